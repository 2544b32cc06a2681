"""The base oscillator with its pendulum TMD as two co-simulated FMUs (the unit's
:class:`~pyfmu_wrapper.cosim.system.CosimSystem` and :class:`~pyfmu_wrapper.cosim.system.CosimEngine`): the
paper's BaseOscillator (``base``, declared by ``base_tmd``) and the model's PendulumTMD (``pendulum``),
coupled by forces exactly as the paper's pair couples BaseOscillator and TMDInerter
(:mod:`pyfmu_wrapper.models.base_tmd.cosim`).

Momentum (impulse) coupling with the interface Jacobian (:func:`impulse_connections`, the default of
:class:`~pyfmu_wrapper.cosim.settings.CosimSettings`)::

    base.x -> pendulum.x, base.xd -> pendulum.xd, base.xdd_free -> pendulum.xdd
    pendulum.yd -> base.f_link   (rate, gain m: the mean of m ydd over the step, first moment from pendulum.y)

with ``pendulum.base_compliance`` = 1/M: within a step the pendulum solves the base's equation with its own
(x'' = xdd_free - f / M, f = m y'' the rod's force on the base, a 2x2 solve for x'' and th''), so the pivot
reacts at once to the rod, and the base gets the exact impulse of the bob over each step. With 1/M and
xdd_free = (F cos(w t) - K x - C xd) / M these are the monolithic model's equations. The force coupling
(:data:`CONNECTIONS`: ``pendulum.force -> base.f_link``, an algebraic loop through ``base.xdd``) is there too.

The steady states, their coupling-error check and the sweeps are the co-simulation engine's
(:mod:`pyfmu_wrapper.cosim.steady`) on :class:`PendulumSystem`; the unit's state z = [x, xd, th, thd] is
given by the outputs ``base.x``, ``base.xd``, ``pendulum.th``, ``pendulum.thd`` (all of it: Newton shooting
moves every state). The start is the unit's (:class:`~pyfmu_wrapper.physics.unit.SmallForcing`: the
monolithic continuation from small forcing, :func:`pyfmu_wrapper.cosim.periods.start_state`).

Time scales (:func:`structure_frequencies`), each with the parameters that set it, of the structure linearised
about rest (the pendulum is then the linear TMD of mass m, stiffness k = m g / L, damping c_p / L^2 on the
bob's horizontal position y = x + L th): the natural frequencies of the coupled structure (mass matrix
diag(M, m), stiffness [[K + k, -k], [-k, k]]), the base alone with the link held, sqrt((K + k) / M), and the
pendulum alone on a pivot held still, sqrt(g / L). (At large swings the pendulum softens: slower, not
faster.) This module imports no unit (the unit's ``cosim`` calls :func:`engine` with it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ...cosim import settings as cosim_settings
from ...cosim import steady as cosim_steady
from ...cosim.settings import CosimSettings
from ...cosim.system import CosimEngine, Scale
from ...cosim.timescales import parameter_text, ratio_sqrt
from ...master.graph import Connection
from ...master.master import Master
from ...physics.params import TMDParams
from ...physics.unit import ModelUnit
from .params import GRAVITY, PendulumTMDParams

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel

#: the force coupling (the ideal-inerter-like loop base.xdd -> pendulum.xdd -> pendulum.force -> base.f_link)
CONNECTIONS = (
    "base.x -> pendulum.x",
    "base.xd -> pendulum.xd",
    "base.xdd -> pendulum.xdd",
    "pendulum.force -> base.f_link",
)
#: the pendulum's outputs the engine reads besides the connected ones (its angle and rate: the shot states)
RECORD = ("pendulum.th", "pendulum.thd", "pendulum.y", "pendulum.yd")
#: smallest absolute tolerance [m] given to the FMUs (with F = 0 the scale FMU_ATOL_SCALE F/K is 0, which they refuse)
ATOL_FLOOR = 1e-14


def cosim_fmus() -> tuple[FmuModel, FmuModel]:
    """The FMUs of the co-simulation: the paper's BaseOscillator (declared by ``base_tmd``: given by that unit
    only) and the model's PendulumTMD."""
    from ..base_tmd.fmus.base_oscillator import FMU as BASE_OSCILLATOR
    from .fmus.pendulum_tmd_fmu import FMU as PENDULUM

    return (BASE_OSCILLATOR, PENDULUM)


def fmu_atol(s: PendulumTMDParams) -> float:
    """The FMUs' absolute tolerance [m]: :data:`~pyfmu_wrapper.cosim.settings.FMU_ATOL_SCALE` of the static
    deflection F/K (the pendulum's angle gets it / L)."""
    return cosim_settings.fmu_atol(s.force_amplitude, s.stiffness, ATOL_FLOOR)


def fmu_parameters(s: PendulumTMDParams, omega: float, z0: ArrayLike, fmu_rtol: float = 1e-8) -> dict[str, Any]:
    """The FMU parameter values ("instance.variable" -> value) of a configuration and a start state z0 of the
    unit's layout [x, xd, th, thd] (the pendulum's pivot starts on the base: its inputs x, xd)."""
    z = np.asarray(z0, dtype=float)
    a = fmu_atol(s)
    out: dict[str, Any] = {
        "base.M": s.mass,
        "base.K": s.stiffness,
        "base.C": s.damping,
        "base.F": s.force_amplitude,
        "base.w": float(omega),
        "base.x0": float(z[0]),
        "base.xd0": float(z[1]),
        "base.rtol": fmu_rtol,
        "base.atol": a,
        "pendulum.m": s.pendulum_mass,
        "pendulum.L": s.length,
        "pendulum.c_p": s.pivot_damping,
        "pendulum.th0": float(z[2]),
        "pendulum.thd0": float(z[3]),
        "pendulum.rtol": fmu_rtol,
        "pendulum.atol": a,
    }
    return out


def impulse_connections(s: PendulumTMDParams, interface_jacobian: bool = True) -> list[Any]:
    """Momentum coupling (module doc): the base gets the exact impulse of the bob over each step, the mean
    of m ydd = m (yd(t + h) - yd(t)) / h with its first moment (``integral_src`` y); with
    ``interface_jacobian`` the pendulum takes the base's acceleration without the rod's force and adds the
    base's reaction itself (``pendulum.base_compliance`` = 1/M, set by :func:`make_master`)."""
    rate = Connection("pendulum.yd", "base.f_link", "rate", float(s.pendulum_mass), "pendulum.force")
    if not interface_jacobian:
        return [*CONNECTIONS[:3], rate]
    return [*CONNECTIONS[:2], "base.xdd_free -> pendulum.xdd", replace(rate, integral_src="pendulum.y")]


def make_master(s: PendulumTMDParams, settings: CosimSettings = CosimSettings()) -> Master:
    """A master for the base and its pendulum (the FMUs built if missing or stale): the coupling, scheme,
    order, FMI version and build (native or Python-hosted) of ``settings``."""
    from ...fmubuild.variants import ensure_variant

    paths = ensure_variant(cosim_fmus(), settings.fmu_build, settings.fmi_version)
    fmus: dict[str, str | Path] = {"base": paths["BaseOscillator"], "pendulum": paths["PendulumTMD"]}
    if settings.coupling == "impulse":
        pars = {"pendulum.base_compliance": 1.0 / s.mass} if settings.interface_jacobian else {}
        conns = impulse_connections(s, settings.interface_jacobian)
        return Master(fmus, conns, pars, scheme="jacobi", order=settings.order, record=RECORD)
    return Master(fmus, CONNECTIONS, {}, scheme=settings.scheme, order=settings.order, record=RECORD)


def structure_frequencies(s: PendulumTMDParams) -> list[Scale]:
    """The angular frequencies [rad/s] of the linearised structure and of its two parts (module doc)."""
    M, K, m, L = float(s.mass), float(s.stiffness), float(s.pendulum_mass), float(s.length)
    k = m * GRAVITY / L
    pars = {
        "M": parameter_text("pendulum_tmd.mass (M)", M, "kg"),
        "K": parameter_text("pendulum_tmd.stiffness (K)", K, "N/m"),
        "m": parameter_text("pendulum_tmd.pendulum_mass (m)", m, "kg"),
        "L": parameter_text("pendulum_tmd.length (L)", L, "m"),
    }
    with np.errstate(all="ignore"):
        try:
            lam = np.linalg.eigvals(np.linalg.solve(np.diag([M, m]), np.array([[K + k, -k], [-k, k]])))
            w2 = float(np.max(np.abs(lam)))
        except np.linalg.LinAlgError:
            w2 = math.inf
    w2 = w2 if math.isfinite(w2) else math.inf
    return [
        Scale(math.sqrt(w2), f"the linearised structure's highest natural frequency ({', '.join(pars.values())})"),
        Scale(
            ratio_sqrt(K + k, M),
            f"the base alone, sqrt((K + m g/L)/M) ({pars['M']}, {pars['K']}, {pars['m']}, {pars['L']})",
        ),
        Scale(ratio_sqrt(GRAVITY, L), f"the pendulum alone, sqrt(g/L) ({pars['L']})"),
    ]


@dataclass(frozen=True)
class PendulumSystem:
    """The base and its pendulum as a :class:`~pyfmu_wrapper.cosim.system.CosimSystem` (module doc)."""

    unit: ModelUnit  #: the pendulum_tmd unit (the package gives it: :func:`engine`)
    structure: PendulumTMDParams
    tmd: TMDParams  #: the detached TMD the engines pass (the model carries its own absorber)

    observed: tuple[str, str] = ("base.x", "base.xd")
    state_outputs: tuple[str, ...] = ("base.x", "base.xd", "pendulum.th", "pendulum.thd")

    def with_tmd(self, tmd: TMDParams) -> PendulumSystem:
        return replace(self, tmd=tmd)

    def make_master(self, settings: CosimSettings) -> Master:
        return make_master(self.structure, settings)

    def parameters(self, omega: float, z: NDArray[np.float64], fmu_rtol: float) -> dict[str, Any]:
        return fmu_parameters(self.structure, omega, z, fmu_rtol)

    def time_scales(self) -> list[Scale]:
        return structure_frequencies(self.structure)

    def reaction_mass(self) -> float:
        return float(self.structure.mass)

    def shooting_scale(self, z: NDArray[np.float64], omega: float) -> NDArray[np.float64]:
        """A scale per coordinate: the base's (x, xd/w) orbit in metres, the pendulum's (th, thd/w) in radians,
        each at least 1e-6 of the static deflection F/K (for the angle, F/(K L))."""
        s = self.structure
        xs = abs(s.force_amplitude) / s.stiffness
        xs = xs if xs > 0 else 1e-3
        ax = max(math.hypot(z[0], z[1] / omega), 1e-6 * xs)
        at = max(math.hypot(z[2], z[3] / omega), 1e-6 * xs / s.length)
        return np.array([ax, ax * omega, at, at * omega])


def engine(unit: ModelUnit) -> CosimEngine:
    """The co-simulation as ``run-scenario`` calls it, for the unit (the unit's ``cosim`` returns
    ``engine(UNIT)``; this module imports no unit): the engine's on :class:`PendulumSystem`."""
    return cosim_steady.engine_of(partial(PendulumSystem, unit), prepare=prepare)


def prepare(settings: CosimSettings) -> list[str]:
    """Builds, or checks, the base's and the pendulum's FMUs in the settings' build and FMI version: their names."""
    from ...fmubuild.variants import ensure_variant

    return list(ensure_variant(cosim_fmus(), settings.fmu_build, settings.fmi_version))
