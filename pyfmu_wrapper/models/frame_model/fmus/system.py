"""FrameSystem: the shear frame with its TMD-inerter as one FMU. Its state map, outputs and step, as compiled
functions both step paths call (the native step of :mod:`.system_native` and the slave of :mod:`.system_slave`),
so the two are bit-identical.

The model is the frame unit's: its equations (:func:`~pyfmu_wrapper.models.frame_model.equations.frame_rhs`,
state of 2 n + 4 entries for n storeys), integrated over a communication step by the unit's own compiled
RODAS4 integrator (the monolithic engine's) with the unit's tolerances (:func:`..tolerances.frame_atol`). The
FMU's state vector is the layout for 20 storeys (:func:`.system_variables.state_names`): :func:`to_model` and
:func:`to_fmu` map it onto the model's for the frame's n (the states of the storeys above the top untouched).
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
from ....physics.params import P_W, P_s
from ....solvers.rodas import STAT_STEPS, make_integrator
from ..equations import F_N, F_TMD, F_TO, frame_rhs, frame_switching, storey_index
from ..ode import FRAME
from ..params import MAX_STOREYS
from ..tolerances import frame_atol
from .step import NS_MAX
from .system_variables import FRAME_SYSTEM, VR_XDS, VR_XS

#: the frame model and its compiled integrator (the monolithic engine's: one per model)
FRAME_MODEL = FRAME
integrate_frame = make_integrator(FRAME_MODEL)
N_SWITCH = FRAME_MODEL.n_switches
FRAME_SYSTEM_OUTPUTS = ("x_top", "xd_top", "x", "xd", "xdd", "force", "y", "yd", "inerter_force", "contact")
FS_OUT_VR, FS_OUT_INT = output_layout(FRAME_SYSTEM, FRAME_SYSTEM_OUTPUTS)
FS_D_VR = np.array([FRAME_SYSTEM.vr(n) for n in ("d", "dd")], dtype=np.int64)
FS_DER_VR = np.array([v.vr for v in FRAME_SYSTEM.derivatives()], dtype=np.int64)
FS_EI_VR = np.array([v.vr for v in FRAME_SYSTEM.event_indicators()], dtype=np.int64)
FS_RTOL, FS_ATOL = FRAME_SYSTEM.vr("rtol"), FRAME_SYSTEM.vr("atol")
FS_XS, FS_XDS = VR_XS, VR_XDS


@njit(cache=True)
def to_model(zf: NDArray[Any], n: int, zm: NDArray[Any]) -> None:
    """The model's state (2 n + 4 entries) from the FMU's (the layout for 20 storeys)."""
    for k in range(2, 6):
        zm[k] = zf[k]
    for i in range(1, n + 1):
        a, b = storey_index(i, n), storey_index(i, MAX_STOREYS)
        zm[a] = zf[b]
        zm[a + 1] = zf[b + 1]


@njit(cache=True)
def to_fmu(zm: NDArray[Any], n: int, zf: NDArray[Any]) -> None:
    """The FMU's state from the model's (the storeys above the top left as they are)."""
    for k in range(2, 6):
        zf[k] = zm[k]
    for i in range(1, n + 1):
        a, b = storey_index(i, n), storey_index(i, MAX_STOREYS)
        zf[b] = zm[a]
        zf[b + 1] = zm[a + 1]


@njit(cache=True)
def model_index(n: int, idx: NDArray[np.int64]) -> None:
    """idx[k] = the FMU state index of the model's state k (k < 2 n + 4)."""
    for k in range(2, 6):
        idx[k] = k
    for i in range(1, n + 1):
        a, b = storey_index(i, n), storey_index(i, MAX_STOREYS)
        idx[a] = b
        idx[a + 1] = b + 1


@njit(cache=True)
def frame_system_outputs(zm: NDArray[Any], t: float, p: NDArray[np.float64], out: NDArray[Any]) -> None:
    """x_top, xd_top, the TMD storey's x and xd, the inerter terminal's acceleration (0: the ground), the TMD's
    force on the structure, y, yd, the inerter's force and the gear contact, at the model's state zm (real or
    complex: the outputs' Jacobian by complex step) and time t."""
    n, s, j = int(p[F_N]), int(p[F_TMD]), int(p[F_TO])
    dz = np.empty_like(zm)
    frame_rhs(t, zm, p, np.zeros(1), dz)
    sx = storey_index(s, n)
    xdd = dz[storey_index(j, n) + 1] if j > 0 else 0.0 * zm[0]
    f0, a, _, _, _, _, _ = kn.tmd_link(zm[sx], zm[sx + 1], zm[2], zm[3], zm[4], zm[5], p)
    zt = np.empty_like(zm[:6])
    zt[0], zt[1] = zm[sx], zm[sx + 1]
    for k in range(2, 6):
        zt[k] = zm[k]
    out[0] = zm[0]
    out[1] = zm[1]
    out[2] = zm[sx]
    out[3] = zm[sx + 1]
    out[4] = xdd
    out[5] = f0 + a * xdd
    out[6] = zm[2]
    out[7] = zm[3]
    out[8] = kn.inerter_force(zt, xdd, p)
    out[9] = kn.contact_state(zm[4].real, p)


_away_from_zero = njit(away_from_zero)


@njit(cache=True)
def frame_indicators(zm: NDArray[np.float64], p: NDArray[np.float64], g: NDArray[np.float64]) -> None:
    """The event indicators at the model's state: the unit's switching functions
    (:func:`~pyfmu_wrapper.fmi.native_model.away_from_zero`)."""
    frame_switching(zm, p, g)
    _away_from_zero(g)


@njit(cache=True)
def frame_derivatives(zf: NDArray[np.float64], t: float, p: NDArray[np.float64], dzf: NDArray[np.float64]) -> None:
    """The FMU's state derivatives: the model's right-hand side, 0 for the storeys above the top."""
    n = int(p[F_N])
    m = 2 * n + 4
    zm, dm = np.empty(m), np.empty(m)
    to_model(zf, n, zm)
    frame_rhs(t, zm, p, np.zeros(1), dm)
    for k in range(dzf.shape[0]):
        dzf[k] = 0.0
    to_fmu(dm, n, dzf)


@njit(cache=True)
def write_frame_system(
    zf: NDArray[np.float64], t: float, p: NDArray[np.float64], reals: NDArray[np.float64], ints: NDArray[np.int32]
) -> None:
    """Everything FrameSystem reports at (t, z) into the value buffers: outputs, the states, their derivatives,
    the event indicators."""
    n = int(p[F_N])
    zm = np.empty(2 * n + 4)
    to_model(zf, n, zm)
    out = np.empty(FS_OUT_VR.shape[0])
    frame_system_outputs(zm, t, p, out)
    for j in range(out.shape[0]):
        if FS_OUT_INT[j]:
            ints[FS_OUT_VR[j]] = np.int32(out[j])
        else:
            reals[FS_OUT_VR[j]] = out[j]
    reals[FS_D_VR[0]] = zf[4]
    reals[FS_D_VR[1]] = zf[5]
    for i in range(1, MAX_STOREYS + 1):
        b = storey_index(i, MAX_STOREYS)
        reals[FS_XS + i - 1] = zf[b]
        reals[FS_XDS + i - 1] = zf[b + 1]
    dzf = np.empty(NS_MAX)
    frame_derivatives(zf, t, p, dzf)
    for k in range(NS_MAX):
        reals[FS_DER_VR[k]] = dzf[k]
    g = np.empty(N_SWITCH)
    frame_indicators(zm, p, g)
    for k in range(N_SWITCH):
        reals[FS_EI_VR[k]] = g[k]


@njit(cache=True)
def advance_frame_system(
    zf: NDArray[np.float64],
    t: float,
    h: float,
    p: NDArray[np.float64],
    u: NDArray[np.float64],
    rtol: float,
    atol_scale: float,
    hn: float,
    stats: NDArray[np.int64],
) -> tuple[float, int, float]:
    """The FMU's state at t -> at t + h by the frame's integrator (steps longer than NATIVE_MAX_STEP in equal
    pieces, its longest step a twentieth of the forcing period as in the monolithic engine, at most
    MAX_INTEGRATOR_STEPS steps). Returns (the next step size, 0 or the integrator's status or FAIL_BUDGET - 1,
    the time reached); on failure zf holds the state where it stopped."""
    n = int(p[F_N])
    m = 2 * n + 4
    zm, atol = np.empty(m), np.empty(m)
    to_model(zf, n, zm)
    frame_atol(p, atol_scale, atol)
    band = 1.0 / p[P_s] if p[P_s] > 0 else 1e-6
    period_max = 2.0 * math.pi / p[P_W] / 20.0 if p[P_W] > 0 else h
    pieces = 1 if h <= NATIVE_MAX_STEP else int(math.ceil(h / NATIVE_MAX_STEP))
    start = stats[STAT_STEPS]
    no_t, no_s = np.zeros(0), np.zeros((0, m))
    status, tf = 0, t + h
    for k in range(pieces):
        a = t if pieces == 1 else t + h * k / pieces
        b = t + h if (pieces == 1 or k == pieces - 1) else t + h * (k + 1) / pieces
        hn, _, status, tf = integrate_frame(
            zm, a, b, p, u, rtol, atol, hn, min(b - a, period_max), no_t, no_s, band, stats, MAX_INTEGRATOR_STEPS
        )
        if status != 0:
            break
        if stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
            status, tf = FAIL_BUDGET - 1, b
            break
    to_fmu(zm, n, zf)
    return hn, status, tf
