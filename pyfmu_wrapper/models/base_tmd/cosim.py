"""The paper's pair as two co-simulated FMUs (the unit's :class:`~pyfmu_wrapper.cosim.system.CosimSystem`
and :class:`~pyfmu_wrapper.cosim.system.CosimEngine`): connections, FMU parameters, the master, the
structure's time scales, SSP export.

The two FMUs are BaseOscillator (``base``) and TMDInerter (``tmd``). Force coupling
(:data:`CONNECTIONS`)::

    base.x -> tmd.x, base.xd -> tmd.xd, base.xdd -> tmd.xdd, tmd.force -> base.f_link

(the ideal inerter makes ``base.xdd -> tmd.xdd -> tmd.force -> base.f_link -> base.xdd`` an
algebraic loop), or the momentum (impulse) coupling of :func:`impulse_connections`.
:func:`fmu_parameters` maps :class:`BaseParams` / :class:`TMDParams` and a start state onto the
FMU parameters (through the parameter registry), :func:`make_master` builds the generic
:class:`~pyfmu_wrapper.master.master.Master` for the pair, :func:`structure_frequencies` lists the time
scales a communication step has to resolve and :func:`export_tmd_system` writes the pair as an SSP file
(:func:`pyfmu_wrapper.master.ssp.export_ssp`). The steady states, their check and the sweeps are the
co-simulation engine's (:mod:`pyfmu_wrapper.cosim.steady`) on :class:`PairSystem`: :func:`engine` (what
``run-scenario`` calls) and :func:`steady_state` (on a master of the pair) take the pair's parameters.

Time scales (:func:`structure_frequencies`), each with the parameters that set it:

* the natural frequencies of the coupled linearised structure: mass matrix
  [[M + I, -I], [-I, m + I]], stiffness [[K + k, -k], [-k, k]] (the play chain is taken as the
  ideal inerter: its mesh is resolved inside the TMD FMU; friction and the cubic term, which the
  linearisation at rest does not see, are left to the coupling-error check);
* the base as the master sees it, alone with the link held: sqrt((K + k) / M) (the TMD's
  reaction reaches it only once per step);
* the TMD alone on a base held still: sqrt(k / (m + I));
* the inerter against the base: sqrt(k I / ((m + I) M)), the TMD's spring seen through the
  inerter's share of the base's acceleration (large when I >> M)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...cosim import steady as cosim_steady
from ...cosim.periods import CosimSteadyState
from ...cosim.settings import CosimSettings, fmu_atol
from ...cosim.system import CosimEngine, Scale
from ...cosim.timescales import parameter_text, ratio_sqrt
from ...master.graph import Connection
from ...master.master import Master
from ...master.ssp import export_ssp
from ...physics import registry
from ...physics.params import BaseParams, InerterModel, TMDParams, has_gap, is_detached
from ...physics.unit import ModelUnit
from ...solvers.start import initial_guess, play_atol
from .fmus.base_oscillator import FMU as BASE_OSCILLATOR
from .fmus.tmd_inerter import FMU as TMD_INERTER

CONNECTIONS = ("base.x -> tmd.x", "base.xd -> tmd.xd", "base.xdd -> tmd.xdd", "tmd.force -> base.f_link")
RECORD = ("tmd.y", "tmd.yd")
#: smallest absolute tolerance [m] given to the FMUs: with no forcing (F = 0) the scale FMU_ATOL_SCALE F/K is 0,
#: which the FMUs refuse (atol must be > 0); any forced configuration of the paper is far above it
ATOL_FLOOR = 1e-14

#: how the TMD force reaches the base (CosimSettings.coupling)
COUPLINGS = ("impulse", "force")


def fmu_parameters(base: BaseParams, tmd: TMDParams, omega: float, z0: ArrayLike, fmu_rtol: float = 1e-8) -> dict:
    """The FMU parameter values ("instance.variable" -> value) of a configuration and start state."""
    z = np.asarray(z0, dtype=float)
    out = registry.fmu_start_values(base, tmd, omega)
    out.update(
        {
            "base.x0": z[0],
            "base.xd0": z[1],
            "base.rtol": fmu_rtol,
            "base.atol": fmu_atol(base.force_amplitude, base.stiffness, ATOL_FLOOR),
            "tmd.y0": z[2],
            "tmd.yd0": z[3],
            "tmd.d0": z[4],
            "tmd.dd0": z[5],
            "tmd.rtol": fmu_rtol,
            "tmd.atol": _tmd_atol(base, tmd),
        }
    )
    return out


def _tmd_atol(base: BaseParams, tmd: TMDParams) -> float:
    a = fmu_atol(base.force_amplitude, base.stiffness, ATOL_FLOOR)
    if has_gap(tmd):
        a = min(a, play_atol(base, tmd))
    return a


def impulse_connections(tmd: TMDParams, interface_jacobian: bool = True) -> list:
    """Momentum coupling: the base gets the exact impulse of the links over each step, from the
    TMD's momentum balance m ydd = (force of the links) (the inerter chain is massless): mean
    f_link = m (yd(t + h) - yd(t)) / h over the step, handed to the base as a linear function with
    that mean and the slope between consecutive means; the TMD steps first. The base's change of
    momentum from the links is exact whatever the gear does inside the step, and no algebraic
    loop remains.

    interface_jacobian (default): the TMD gets the base's acceleration without the link force
    (``base.xdd_free -> tmd.xdd``) and, as the parameter ``tmd.base_compliance`` = 1/M set by
    :func:`make_master`, the base's compliance, so that within a step it adds the base's
    instantaneous reaction -force/M to its own force: the gear-mesh rattle meets a base that
    reacts without a step of delay. The base's force then also matches the first moment of the
    impulse (``integral_src="tmd.y"``: exact change of momentum *and* of position over every
    step), which without the interface Jacobian was less accurate because the TMD fed on the
    base's then jumpy end-of-step acceleration (docs/cosimulation.md, "interface Jacobian")."""
    if not interface_jacobian:
        return [*CONNECTIONS[:3], Connection("tmd.yd", "base.f_link", "rate", float(tmd.mass), "tmd.force")]
    return [
        CONNECTIONS[0],
        CONNECTIONS[1],
        "base.xdd_free -> tmd.xdd",
        Connection("tmd.yd", "base.f_link", "rate", float(tmd.mass), "tmd.force", integral_src="tmd.y"),
    ]


def make_master(
    base: BaseParams | None = None,
    tmd: TMDParams | None = None,
    scheme: str = "loop",
    order: int = 2,
    fmus: dict | None = None,
    coupling: str = "force",
    interface_jacobian: bool = True,
    fmi_version: int = 2,
    fmu_build: str = "native",
) -> Master:
    """A master for the base + TMD pair (the FMUs are built if missing or stale).

    coupling: "force" (tmd.force -> base.f_link, the algebraic loop of the ideal inerter) or
    "impulse" (:func:`impulse_connections`; needs ``tmd``; ``interface_jacobian`` sets
    ``tmd.base_compliance`` = 1/M of ``base``); fmi_version: 2 or 3 (the FMUs of that version);
    fmu_build: "native" (the model compiled into the FMUs' binaries) or "python" (the Python-hosted
    FMUs, the reference)."""
    if fmus is None:
        from ...fmubuild.variants import ensure_variant

        paths = ensure_variant(PAIR_FMUS, fmu_build, fmi_version)
        fmus = {"base": paths["BaseOscillator"], "tmd": paths["TMDInerter"]}
    if coupling == "impulse":
        pars = {"tmd.base_compliance": 1.0 / (base or BaseParams()).mass} if interface_jacobian else {}
        return Master(
            fmus,
            impulse_connections(tmd or TMDParams(), interface_jacobian),
            pars,
            scheme="jacobi",
            order=order,
            record=RECORD,
        )
    return Master(fmus, CONNECTIONS, {}, scheme=scheme, order=order, record=RECORD)


def export_tmd_system(
    unit: ModelUnit,
    path: str | Path,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: ArrayLike | None = None,
    stop_time: float | None = None,
    step_size: float | None = None,
) -> Path:
    """SSP of the base + TMD pair of this project at excitation omega [rad/s] (start state z0,
    default the linear steady state of :func:`~pyfmu_wrapper.solvers.monolithic.initial_guess`;
    step_size: OMSimulator's master step, see :func:`pyfmu_wrapper.master.ssp.ssd_xml`)."""
    from ...fmubuild.build import ensure_fmus

    paths = ensure_fmus(PAIR_FMUS)
    fmus = {"base": paths["BaseOscillator"], "tmd": paths["TMDInerter"]}
    z = initial_guess(unit, base, tmd, omega) if z0 is None else z0
    return export_ssp(
        path,
        fmus,
        CONNECTIONS,
        fmu_parameters(base, tmd, omega, z),
        name="BaseTMD",
        stop_time=stop_time,
        step_size=step_size,
    )


def structure_frequencies(base: BaseParams, tmd: TMDParams) -> list[Scale]:
    """The angular frequencies [rad/s] of the coupled structure and of its two parts (module doc)."""
    M, K = float(base.mass), float(base.stiffness)
    m, k = float(tmd.mass), float(tmd.stiffness)
    inert = 0.0 if tmd.inerter == InerterModel.NONE else float(tmd.inertance)
    pars = {
        "M": parameter_text("base.mass (M)", M, "kg"),
        "K": parameter_text("base.stiffness (K)", K, "N/m"),
        "m": parameter_text("tmd.mass (m)", m, "kg"),
        "k": parameter_text("tmd.stiffness (k)", k, "N/m"),
        "I": parameter_text("tmd.inertance (I)", inert, "kg"),
    }
    out: list[Scale] = []
    with np.errstate(all="ignore"):
        mass = np.array([[M + inert, -inert], [-inert, m + inert]])
        stiff = np.array([[K + k, -k], [-k, k]])
        try:
            lam = np.linalg.eigvals(np.linalg.solve(mass, stiff))
            w2 = float(np.max(np.abs(lam)))
        except np.linalg.LinAlgError:
            w2 = math.inf
        if not math.isfinite(w2):
            w2 = math.inf
    out.append(Scale(math.sqrt(w2), f"the coupled structure's highest natural frequency ({', '.join(pars.values())})"))
    out.append(
        Scale(
            ratio_sqrt(K + k, M),
            f"the base alone, sqrt((K + k)/M) ({pars['M']}, {pars['K']}, {pars['k']})",
        )
    )
    out.append(
        Scale(ratio_sqrt(k, m + inert), f"the TMD alone, sqrt(k/(m + I)) ({pars['k']}, {pars['m']}, {pars['I']})")
    )
    if inert > 0.0:
        out.append(
            Scale(
                ratio_sqrt(k * inert, (m + inert) * M),
                f"the inerter against the base, sqrt(k I/((m + I) M)) ({pars['k']}, {pars['I']}, {pars['m']}, {pars['M']})",
            )
        )
    return out


def fastest(base: BaseParams, tmd: TMDParams) -> Scale:
    """The fastest of :func:`structure_frequencies`."""
    return max(structure_frequencies(base, tmd), key=lambda s: s.omega)


@dataclass(frozen=True)
class PairSystem:
    """The base + TMD pair as a :class:`~pyfmu_wrapper.cosim.system.CosimSystem` (module doc)."""

    unit: ModelUnit  #: the base_tmd unit (the package gives it: :func:`engine`)
    structure: BaseParams
    tmd: TMDParams

    observed: tuple[str, str] = ("base.x", "base.xd")

    @property
    def state_outputs(self) -> tuple[str | None, ...]:
        """x, xd of the base and y, yd of the TMD; a detached TMD's (no link: a free mass) are no part of the
        response and not shot (their drift would make the period map's Jacobian singular)."""
        if is_detached(self.tmd):
            return ("base.x", "base.xd")
        return ("base.x", "base.xd", "tmd.y", "tmd.yd")

    def with_tmd(self, tmd: TMDParams) -> PairSystem:
        return replace(self, tmd=tmd)

    def make_master(self, settings: CosimSettings) -> Master:
        return make_master(
            self.structure,
            self.tmd,
            settings.scheme,
            settings.order,
            coupling=settings.coupling,
            interface_jacobian=settings.interface_jacobian,
            fmi_version=settings.fmi_version,
            fmu_build=settings.fmu_build,
        )

    def parameters(self, omega: float, z: NDArray[np.float64], fmu_rtol: float) -> dict[str, Any]:
        return fmu_parameters(self.structure, self.tmd, omega, z, fmu_rtol)

    def time_scales(self) -> list[Scale]:
        return structure_frequencies(self.structure, self.tmd)

    def reaction_mass(self) -> float:
        return float(self.structure.mass)

    def shooting_scale(self, z: NDArray[np.float64], omega: float) -> NDArray[np.float64]:
        """One scale for the base's and the TMD's (x, xd/w): the larger orbit's, at least 1e-6 F/K."""
        base = self.structure
        pairs = np.asarray(z, dtype=float).reshape(-1, 2)
        amp = max(
            float(np.max(np.hypot(pairs[:, 0], pairs[:, 1] / omega))), 1e-6 * abs(base.force_amplitude) / base.stiffness
        )
        return np.tile([amp, amp * omega], pairs.shape[0])


def steady_state(
    unit: ModelUnit,
    master: Master,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: ArrayLike | None = None,
    settings: CosimSettings = CosimSettings(),
    hint: dict | None = None,
    restart: bool = True,
) -> CosimSteadyState:
    """The co-simulated steady state of the pair at omega [rad/s], checked
    (:func:`pyfmu_wrapper.cosim.steady.steady_state` on :class:`PairSystem`)."""
    return cosim_steady.steady_state(master, PairSystem(unit, base, tmd), omega, z0, settings, hint, restart)


#: the pair's FMUs, BaseOscillator and TMDInerter (its unit gives the same declarations)
PAIR_FMUS = (BASE_OSCILLATOR, TMD_INERTER)


def engine(unit: ModelUnit) -> CosimEngine:
    """The pair's co-simulation as ``run-scenario`` calls it, for its unit (the unit holds it: the unit's
    ``cosim`` returns ``engine(UNIT)``; this module imports no unit): the engine's on :class:`PairSystem`."""
    return cosim_steady.engine_of(partial(PairSystem, unit), prepare=prepare)


def prepare(settings: CosimSettings) -> list[str]:
    """Builds, or checks, the pair's FMUs in the settings' build and FMI version: their names."""
    from ...fmubuild.variants import ensure_variant

    return list(ensure_variant(PAIR_FMUS, settings.fmu_build, settings.fmi_version))
