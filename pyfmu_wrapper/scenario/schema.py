"""Typed objects of a validated scenario (schema version 2; see docs/scenarios.md).

The loader (:mod:`.loader`) turns a YAML file into these objects; everything downstream (the
runner, the plots) works with them only, never with raw YAML.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..inputs.reader import ScenarioError
from ..physics import registry
from ..physics.params import TMDParams
from ..solvers.monolithic import SolverSettings

if TYPE_CHECKING:
    from ..cosim.settings import CosimSettings

__all__ = ["ScenarioError"]  # (defined with the reader that raises it; imported from here by the scenario code)

SCHEMA_VERSION = 2
#: older versions still read: 1 only when the file has no ``solver:`` block (docs/scenarios.md)
READ_VERSIONS = (1, 2)

DIRECTIONS = ("up", "down", "both")
LINEAR_METHODS = ("exact", "simulate")
STUDY_KINDS = ("frc", "map", "phase_portrait")
#: TMD parameters a map may sweep: the numeric TMDParams fields and the derived inertance_ratio.
MAP_PARAMETERS = tuple(p.name for p in registry.fields("tmd") if p.mappable) + ("inertance_ratio",)


@dataclass(frozen=True)
class SweepConfig:
    """``sweep:`` block of a scenario: how the frequencies are visited, for every engine.

    direction: 'up', 'down' or 'both' (stepped-sine sweep with continuation);
    continuation: True (each frequency starts from the previous steady state) or False (each starts
    from the engine's initial guess, independently: the map executors then run every frequency as
    its own sweep of one point; much faster for the rattling play model).
    """

    direction: str = "up"
    continuation: bool = True

    def as_dict(self) -> dict:
        return dict(direction=self.direction, continuation=self.continuation)


@dataclass(frozen=True)
class SolverConfig:
    """``solver:`` block of a scenario: the settings of the monolithic engine only.

    rtol ... max_periods: :class:`~pyfmu_wrapper.solvers.monolithic.SolverSettings`;
    linear: 'exact' (linear configurations use the exact frequency response) or 'simulate'
    (integrate them like the nonlinear ones, e.g. to cross-check). The co-simulation engine reads
    none of these (its block is :class:`CosimConfig`).
    """

    rtol: float = SolverSettings.rtol
    atol_scale: float = SolverSettings.atol_scale
    tol: float = SolverSettings.tol
    tol_window: float = SolverSettings.tol_window
    window: int | None = SolverSettings.window
    min_periods: int = SolverSettings.min_periods
    max_periods: int = SolverSettings.max_periods
    linear: str = "exact"

    def settings(self) -> SolverSettings:
        return SolverSettings(
            rtol=self.rtol,
            atol_scale=self.atol_scale,
            tol=self.tol,
            tol_window=self.tol_window,
            window=self.window,
            min_periods=self.min_periods,
            max_periods=self.max_periods,
        )

    def as_dict(self) -> dict:
        return dict(
            rtol=self.rtol,
            atol_scale=self.atol_scale,
            tol=self.tol,
            tol_window=self.tol_window,
            window=self.window,
            min_periods=self.min_periods,
            max_periods=self.max_periods,
            linear=self.linear,
        )


#: keys of the ``cosim:`` block (fields of pyfmu_wrapper.cosim.settings.CosimSettings a scenario may set)
COSIM_KEYS = (
    "accuracy",
    "steps_per_period",
    "coupling_tol",
    "max_steps_per_period",
    "coupling",
    "order",
    "scheme",
    "tol",
    "tol_window",
    "window",
    "min_periods",
    "max_periods",
    "fmu_rtol",
    "shooting",
    "interface_jacobian",
    "fmi_version",
    "fmu_build",
)


@dataclass(frozen=True)
class CosimConfig:
    """``cosim:`` block of a scenario: the settings of the co-simulation engine only.

    ``overrides`` holds the keys the file sets (names of
    :class:`~pyfmu_wrapper.cosim.settings.CosimSettings` fields, :data:`COSIM_KEYS`); every other
    field keeps its default. The monolithic engine reads none of these.
    """

    overrides: tuple = ()  #: ((key, value), ...) in file order

    def settings(self) -> CosimSettings:
        """The :class:`~pyfmu_wrapper.cosim.settings.CosimSettings` of the block."""
        from ..cosim.settings import CosimSettings  # lazy: the co-simulation engine imports fmpy

        return CosimSettings(**dict(self.overrides))

    def as_dict(self) -> dict:
        return dict(self.overrides)


@dataclass(frozen=True)
class Curve:
    """One configuration of the TMD in a study: a label and its parameters."""

    label: str
    tmd: TMDParams
    without_tmd: bool = False  #: the base alone (the TMD detached), the paper's black reference lines
    #: the primary structure of this curve when it differs from the scenario's (a frame with its
    #: TMD attached elsewhere); None: the scenario's
    structure: Any = None


@dataclass(frozen=True)
class FRCStudy:
    """Frequency-response curves: base amplitude against omega [rad/s], one line per curve."""

    name: str
    title: str
    omegas: np.ndarray = field(repr=False)
    curves: tuple[Curve, ...]
    kind: str = "frc"
    yscale: str = "linear"  #: the amplitude axis, linear or log (the scenario's or the study's plot: block)


@dataclass(frozen=True)
class MapStudy:
    """Two-parameter diagram: base amplitude over (parameter value, omega), drawn as a colour map."""

    name: str
    title: str
    parameter: str
    values: np.ndarray = field(repr=False)
    omegas: np.ndarray = field(repr=False)
    tmds: tuple[TMDParams, ...] = field(repr=False)  #: one per value
    kind: str = "map"


@dataclass(frozen=True)
class PhasePortraitStudy:
    """Steady-state phase portraits (x, xd) of the base at a few omegas, one line per curve."""

    name: str
    title: str
    omegas: tuple[float, ...]
    curves: tuple[Curve, ...]
    n_periods: int = 1
    samples_per_period: int = 400
    kind: str = "phase_portrait"


Study = FRCStudy | MapStudy | PhasePortraitStudy


@dataclass(frozen=True)
class Scenario:
    """A validated scenario file."""

    path: str
    name: str
    description: str
    schema_version: int
    base: Any  #: the primary structure: BaseParams (base:) or FrameParams (frame:), its model's class
    tmd: TMDParams
    frequencies: np.ndarray = field(repr=False)
    solver: SolverConfig  #: the monolithic engine's block
    studies: tuple
    sweep: SweepConfig = SweepConfig()  #: shared by every engine
    cosim: CosimConfig = CosimConfig()  #: the co-simulation engine's block
    raw: dict = field(repr=False, compare=False, default_factory=dict)  #: the YAML data as read
