"""The co-simulation engine's settings (:class:`CosimSettings`: the steady-state definition shared with
the monolithic solver plus the communication step, coupling, scheme and FMU tolerance, each declared
in :mod:`pyfmu_wrapper.solvers.settings_table`) and the calibrated error model that turns a requested
amplitude accuracy into communication steps per forcing period (:func:`steps_for_accuracy`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..physics.params import TMDParams, has_gap
from ..solvers import settings_table as _table
from ..solvers.settings_table import COSIM, MONO
from ..solvers.steady import SteadySettings

#: the absolute tolerance of the integrators inside the FMUs (parameter ``atol``), as a fraction of the structure's
#: static deflection |F|/K: the monolithic engine's (its ``atol_scale`` default), so that both engines integrate the
#: absorber to the same tolerance (a tighter one only costs the FMU integrator steps the coupling error swamps).
FMU_ATOL_SCALE: float = _table.default("atol_scale", MONO)


def fmu_atol(force_amplitude: float, stiffness: float, floor: float) -> float:
    """The FMUs' ``atol`` [m] for a structure of force amplitude F [N] and stiffness K [N/m]:
    :data:`FMU_ATOL_SCALE` |F|/K, at least ``floor`` (an unforced structure has no scale)."""
    return max(FMU_ATOL_SCALE * abs(force_amplitude) / stiffness, floor)


@dataclass(frozen=True)
class CosimSettings(SteadySettings):
    """Co-simulation steady-state settings.

    The steady-state fields (tol, tol_window, window, min_periods, max_periods,
    scatter_tol, play_start, shooting, max_newton) are those of
    :class:`~pyfmu_wrapper.solvers.steady.SteadySettings` (the definition shared with the
    monolithic solver, validated there), with max_periods 240, max_newton 12 and tol_window 1e-3 here
    (below the amplitude accuracy with a gear gap, 2.5e-3; the coupling error makes the rattle's window
    maxima scatter by about 1e-3, so a tighter agreement only runs every point to the stop rule of
    the windows' running maximum). Own fields:
    steps_per_period: communication steps per forcing period (None: chosen from ``accuracy``
    with the calibrated error model of :func:`steps_for_accuracy`); accuracy: the relative
    amplitude error asked for (None: :data:`DEFAULT_ACCURACY`, 1e-3 without a gear gap and 2.5e-3
    with one, where the error is set by the rattle, not by a smooth discretisation); coupling: "impulse"
    (:func:`impulse_connections`) or "force" (:data:`CONNECTIONS`); scheme / order: see
    :mod:`pyfmu_wrapper.master.master`; fmu_rtol: tolerance of the integrators inside the FMUs;
    interface_jacobian: with the impulse coupling, hand the TMD the base's compliance 1/M and its
    acceleration without the link force (:func:`impulse_connections`); fmi_version: run the FMI
    2.0 or the FMI 3.0 variants of the FMUs (the same core: the same numbers); fmu_build: the native
    FMUs (model code compiled into the binary) or the Python-hosted ones (bit-identical); coupling_tol: the
    tolerance of the coupling-error estimate checked at every point (:mod:`.checked`; 5e-3, the
    agreement with the monolithic solver the co-simulation promises: the estimate bounds the error
    from above, so a point that passes is within it); max_steps_per_period: the most steps per period a point may need (the structure's
    time scales, :mod:`.timescales`, and the refinements of the check) before it is reported not
    converged.
    """

    tol_window: float = _table.default("tol_window", COSIM)
    max_periods: int = _table.default("max_periods", COSIM)
    max_newton: int = _table.default("max_newton", COSIM)
    steps_per_period: int | None = _table.default("steps_per_period", COSIM)
    accuracy: float | None = _table.default("accuracy", COSIM)
    coupling_tol: float = _table.default("coupling_tol", COSIM)
    max_steps_per_period: int = _table.default("max_steps_per_period", COSIM)
    coupling: str = _table.default("coupling", COSIM)
    scheme: str = _table.default("scheme", COSIM)
    order: int = _table.default("order", COSIM)
    fmu_rtol: float = _table.default("fmu_rtol", COSIM)
    interface_jacobian: bool = _table.default("interface_jacobian", COSIM)
    fmi_version: int = _table.default("fmi_version", COSIM)
    fmu_build: str = _table.default("fmu_build", COSIM)
    # (validated by SteadySettings.validate against solvers/settings_table.py)

    def steps_for(self, tmd: TMDParams) -> int:
        if self.steps_per_period is not None:
            return int(self.steps_per_period)
        return steps_for_accuracy(self.accuracy_for(tmd), self.order, self.coupling, has_gap(tmd))

    def accuracy_for(self, tmd: TMDParams) -> float:
        """The relative amplitude accuracy asked for (:data:`DEFAULT_ACCURACY` when not set)."""
        return DEFAULT_ACCURACY[has_gap(tmd)] if self.accuracy is None else float(self.accuracy)

    def coupling_tolerance(self, tmd: TMDParams) -> float:
        """The tolerance of the coupling-error estimate (``coupling_tol``, the same for every model)."""
        return float(self.coupling_tol)

    @property
    def method(self) -> str:
        """Short name of the co-simulation method (the 'method' column of sweep tables)."""
        if self.coupling == "impulse":
            return f"cosim_impulse_o{self.order}"
        return f"cosim_force_{self.scheme}_o{self.order}"


#: error model: relative FRC error ~ C (2 pi / N)^q with N steps per period, (C, q) per coupling and
#: extrapolation order, fitted to the largest error against the monolithic solver over the
#: configuration types (docs/cosimulation.md), C rounded up by a safety factor of about 3
_ERR_MODEL = {
    ("impulse", 2): (3.0, 3),
    ("impulse", 1): (10.0, 2),
    ("impulse", 0): (10.0, 1),
    ("force", 2): (20.0, 3),
    ("force", 1): (20.0, 2),
    ("force", 0): (10.0, 1),
}
#: with a gear gap (play) the error is set by the rattling chain (contact times are sensitive to
#: any perturbation), not by a smooth discretisation: fitted to the largest error over the 41-point
#: sweeps of the six play and full-model configurations of the paper (regular points), impulse
#: coupling with the interface Jacobian, order 2: 7.3e-3 at N = 96 and 2.3e-3 at N = 192
#: (docs/cosimulation.md), no safety factor
_ERR_MODEL_PLAY = {("impulse", 2): (0.69, 1.67)}
#: accuracy used when none is asked for: without a gap 1e-3 (N = 96), with a gap 2.5e-3 (N = 184)
DEFAULT_ACCURACY = {False: 1e-3, True: 2.5e-3}


def steps_for_accuracy(accuracy: float, order: int = 2, coupling: str = "impulse", play: bool = False) -> int:
    """Communication steps per forcing period for a requested relative amplitude accuracy
    (a multiple of 8, at least 32); ``play``: the error model of the rattling configurations
    (calibrated for the impulse coupling of order 2; the smooth model otherwise)."""
    model = _ERR_MODEL_PLAY if play and (coupling, order) in _ERR_MODEL_PLAY else _ERR_MODEL
    c, q = model[(coupling, order)]
    n = 2 * math.pi / (accuracy / c) ** (1.0 / q)
    return max(32, int(math.ceil(n / 8.0) * 8))
