"""TMDSystem: the paper's base with its TMD-inerter as one FMU. Its outputs and its step, as compiled functions
both step paths call (the native step of :mod:`.system_native` and the slave of :mod:`.system_slave`), so the two
are bit-identical.

The model is the unit's: the coupled equations :data:`~pyfmu_wrapper.physics.models.COUPLED` (state
z = [x, xd, y, yd, d, dd], every configuration of the paper), integrated over a communication step by the
unit's own compiled RODAS4 integrator (the monolithic engine's, :func:`~pyfmu_wrapper.solvers.rodas.make_integrator`
of that model) with the unit's absolute tolerances (:func:`..tolerances.coupled_atol`). In Model Exchange the
host integrates the same right-hand side (:mod:`.system_native`).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ...._jit import njit
from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS, NATIVE_MAX_STEP
from ....fmi.native_model import away_from_zero
from ....fmi.outputs import output_layout
from ....physics import kernels as kn
from ....physics import models
from ....physics.models import coupled_rhs, coupled_switching
from ....physics.params import P_W, P_s
from ....solvers.rodas import STAT_STEPS, make_integrator
from ..tolerances import coupled_atol
from .variables import TMD_SYSTEM

#: the coupled model and its compiled integrator (the monolithic engine's: one per model)
SYSTEM_MODEL = models.COUPLED
integrate_system = make_integrator(SYSTEM_MODEL)
NSTATE = kn.NSTATE
N_SWITCH = SYSTEM_MODEL.n_switches
SYSTEM_OUTPUTS = ("x", "xd", "xdd", "f_exc", "xdd_free", "force", "y", "yd", "inerter_force", "contact")
SYS_OUT_VR, SYS_OUT_INT = output_layout(TMD_SYSTEM, SYSTEM_OUTPUTS)
#: the locals TMDSystem reports besides its outputs: the chain's states, the derivatives, the event indicators
SYS_D_VR = np.array([TMD_SYSTEM.vr(n) for n in ("d", "dd")], dtype=np.int64)
SYS_DER_VR = np.array([v.vr for v in TMD_SYSTEM.derivatives()], dtype=np.int64)
SYS_EI_VR = np.array([v.vr for v in TMD_SYSTEM.event_indicators()], dtype=np.int64)
S_RTOL, S_ATOL = TMD_SYSTEM.vr("rtol"), TMD_SYSTEM.vr("atol")
if [v.name for v in TMD_SYSTEM.states()] != list(SYSTEM_MODEL.state_names):  # pragma: no cover - a declaration error
    raise RuntimeError("TMDSystem: its states are not the coupled model's z")


@njit(cache=True)
def system_outputs(z: NDArray[Any], t: float, p: NDArray[np.float64], out: NDArray[Any]) -> None:
    """x, xd, xdd, F cos(w t), the base's acceleration without the link force, the links' force on the base,
    y, yd, the inerter chain's force and the gear contact at state z and time t (z real or complex: the
    outputs' Jacobian by complex step)."""
    x, xd, y, yd, d, dd = z[0], z[1], z[2], z[3], z[4], z[5]
    fexc = kn.excitation(t, p)
    f0, a, _, _, _, _, _ = kn.tmd_link(x, xd, y, yd, d, dd, p)
    xdd = kn.base_acceleration(x, xd, f0, a, fexc, p)
    out[0] = x
    out[1] = xd
    out[2] = xdd
    out[3] = fexc
    out[4] = kn.base_acceleration(x, xd, 0.0, 0.0, fexc, p)
    out[5] = f0 + a * xdd
    out[6] = y
    out[7] = yd
    out[8] = kn.inerter_force(z, xdd, p)
    out[9] = kn.contact_state(d.real, p)


_away_from_zero = njit(away_from_zero)


@njit(cache=True)
def system_indicators(z: NDArray[np.float64], p: NDArray[np.float64], g: NDArray[np.float64]) -> None:
    """The event indicators: the unit's switching functions (:func:`~pyfmu_wrapper.fmi.native_model.away_from_zero`)."""
    coupled_switching(z, p, g)
    _away_from_zero(g)


@njit(cache=True)
def system_locals(z: NDArray[np.float64], t: float, p: NDArray[np.float64], reals: NDArray[np.float64]) -> None:
    """The chain's states, the states' derivatives (the coupled right-hand side) and the event indicators (its
    switching functions) into the value buffer."""
    dz = np.empty(NSTATE)
    coupled_rhs(t, z, p, np.zeros(1), dz)
    g = np.empty(N_SWITCH)
    system_indicators(z, p, g)
    reals[SYS_D_VR[0]] = z[4]
    reals[SYS_D_VR[1]] = z[5]
    for i in range(NSTATE):
        reals[SYS_DER_VR[i]] = dz[i]
    for k in range(g.shape[0]):
        reals[SYS_EI_VR[k]] = g[k]


@njit(cache=True)
def write_system(
    z: NDArray[np.float64], t: float, p: NDArray[np.float64], reals: NDArray[np.float64], ints: NDArray[np.int32]
) -> None:
    """Everything TMDSystem reports at (t, z) into the value buffers: outputs and locals."""
    out = np.empty(SYS_OUT_VR.shape[0])
    system_outputs(z, t, p, out)
    for j in range(out.shape[0]):
        if SYS_OUT_INT[j]:
            ints[SYS_OUT_VR[j]] = np.int32(out[j])
        else:
            reals[SYS_OUT_VR[j]] = out[j]
    system_locals(z, t, p, reals)


@njit(cache=True)
def advance_system(
    z: NDArray[np.float64],
    t: float,
    h: float,
    p: NDArray[np.float64],
    u: NDArray[np.float64],
    rtol: float,
    atol_scale: float,
    atol: NDArray[np.float64],
    hn: float,
    stats: NDArray[np.int64],
) -> tuple[float, int, float]:
    """z at t -> at t + h by the coupled integrator (steps longer than NATIVE_MAX_STEP in equal pieces, its
    longest step a twentieth of the forcing period as in the monolithic engine, at most MAX_INTEGRATOR_STEPS
    steps). Returns (the next step size, 0 or the failure code of :mod:`~pyfmu_wrapper.fmi.contract` less 1
    (the integrator's status), or FAIL_BUDGET; the time reached). On failure z is where it stopped."""
    coupled_atol(p, atol_scale, atol)
    band = 1.0 / p[P_s] if p[P_s] > 0 else 1e-6
    period_max = 2.0 * math.pi / p[P_W] / 20.0 if p[P_W] > 0 else h
    n = 1 if h <= NATIVE_MAX_STEP else int(math.ceil(h / NATIVE_MAX_STEP))
    start = stats[STAT_STEPS]
    no_t, no_s = np.zeros(0), np.zeros((0, NSTATE))
    for k in range(n):
        a, b = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
        hn, _, status, tf = integrate_system(
            z, a, b, p, u, rtol, atol, hn, min(b - a, period_max), no_t, no_s, band, stats, MAX_INTEGRATOR_STEPS
        )
        if status != 0:
            return hn, status, tf
        if stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
            return hn, FAIL_BUDGET - 1, b
    return hn, 0, t + h
