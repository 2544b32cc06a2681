"""What the co-simulation engine asks of a model: a co-simulated system of FMUs (:class:`CosimSystem`),
and what ``run-scenario`` asks of a model's co-simulation (:class:`CosimEngine`).

The engine (:mod:`.periods`, :mod:`.checked`, :mod:`.steady`) computes steady states, their coupling-error
check and sweeps on any :class:`CosimSystem`: a structure and its absorber as FMUs on the generic master,
with the states the FMUs' outputs show. A model's folder implements it (the paper's pair:
:mod:`pyfmu_wrapper.models.base_tmd.cosim`) and gives its unit a :class:`CosimEngine` (its sweep, and
optionally its phase portrait, its up-front refusal and its step count), which ``run-scenario`` calls; the
engine knows no model.

Conventions (those of the model units): the reported displacement is z[0], its rate z[1]; the structure has
``force_amplitude`` and ``stiffness`` (F/K bounds the static deflection: the floors of the relative
errors); the paper's TMD, where the model takes it, sits at z[2:6] = [y, yd, d, dd] (a model with its own
absorber passes a detached TMD: no play, one window, every state shootable).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, NamedTuple, Protocol

import numpy as np
from numpy.typing import NDArray

from ..physics.params import TMDParams
from ..physics.unit import ModelUnit

if TYPE_CHECKING:
    from ..master.master import Master
    from .settings import CosimSettings


class Scale(NamedTuple):
    """A time scale of a co-simulated system that a communication step has to resolve (:mod:`.timescales`)."""

    omega: float  #: angular frequency [rad/s]
    what: str  #: what it is, with the parameters (names, symbols, values) that set it


class CosimSystem(Protocol):
    """A structure and its absorber as co-simulated FMUs (module doc)."""

    @property
    def unit(self) -> ModelUnit: ...  #: the model (its start states, its monolithic companion)
    @property
    def structure(self) -> Any: ...  #: the primary structure's parameters
    @property
    def tmd(self) -> TMDParams: ...  #: the paper's TMD (a detached one for a model with its own absorber)

    @property
    def observed(self) -> tuple[str, str]:
        """The outputs ("instance.variable") of the reported displacement z[0] and its rate z[1]."""
        ...

    @property
    def state_outputs(self) -> tuple[str | None, ...]:
        """The output ("instance.variable") of each entry of the unit's state z[0], z[1], ..., None for an entry
        no FMU output shows: the states shown are those Newton shooting moves (the others, and the entries past
        the end of the tuple, are taken from the start state)."""
        ...

    def with_tmd(self, tmd: TMDParams) -> CosimSystem:
        """The same system with another TMD (the play model's smooth companion)."""
        ...

    def make_master(self, settings: CosimSettings) -> Master:
        """A master with the system's FMUs and connections (the FMUs built if missing or stale)."""
        ...

    def parameters(self, omega: float, z: NDArray[np.float64], fmu_rtol: float) -> dict[str, Any]:
        """The FMU parameters ("instance.variable" -> value) at excitation omega [rad/s] from state z."""
        ...

    def time_scales(self) -> list[Scale]:
        """The angular frequencies [rad/s] a communication step has to resolve, each with the parameters
        that set it (:mod:`.timescales`)."""
        ...

    def reaction_mass(self) -> float:
        """The mass [kg] the absorber hangs on (the play model's rattle error model holds up to an
        inertance of 0.1 of it, :mod:`.checked`)."""
        ...

    def shooting_scale(self, z: NDArray[np.float64], omega: float) -> NDArray[np.float64]:
        """The scale of each shot state (:attr:`state_outputs`) at omega, for Newton's tolerance."""
        ...


@dataclass(frozen=True)
class CosimEngine:
    """A model's co-simulation as ``run-scenario`` calls it (module doc); every function takes the
    structure and the TMD first."""

    #: sweep(structure, tmd, omegas, direction=, settings=, progress=, workers=) -> the sweep table
    sweep: Callable[..., Any]
    #: periodic_time_series(structure, tmd, omega, n_periods, samples_per_period, settings) -> (t, states, ss)
    periodic_time_series: Callable[..., Any] | None = None
    #: refusal(structure, tmd, omegas, cap) -> why some frequency cannot be stepped (an up-front refusal)
    refusal: Callable[..., str | None] | None = None
    #: steps_at(structure, tmd, omega, settings) -> the communication steps per period at omega
    steps_at: Callable[..., int] | None = None
    #: prepare(settings) -> builds, or checks, the FMUs its systems run in the settings' build and FMI version, and
    #: returns their names (``run-scenario`` calls it once, before its workers start:
    #: :func:`pyfmu_wrapper.scenario.engines.prepare_cosim`)
    prepare: Callable[..., list[str]] | None = None
    #: points(structure, tmd, settings) -> a callable giving the co-simulated amplitudes at frequencies asked one
    #: call at a time on one master, with ``close()`` (:class:`~.steady.PointSolver`: a linear curve's peak refinement)
    points: Callable[..., Any] | None = None
