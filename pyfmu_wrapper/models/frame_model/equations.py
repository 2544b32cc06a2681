"""Equations of the shear frame with the TMD-inerter: the storeys' equations here, the TMD's those of
:mod:`pyfmu_wrapper.physics.kernels` (:func:`~pyfmu_wrapper.physics.kernels.tmd_link`,
:func:`~pyfmu_wrapper.physics.kernels.static_link_force`, unchanged).

State (length 2 n + 4), the top storey first so that z[0] is the displacement the curves report
and the TMD's states sit where the paper's do (a 1-storey frame has the paper's layout)::

    z = [x_n, xd_n, y, yd, d, dd, x_{n-1}, xd_{n-1}, ..., x_1, xd_1]

Storey i: M_i xdd_i = -K_i (x_i - x_{i-1}) - C_i (xd_i - xd_{i-1}) + K_{i+1} (x_{i+1} - x_i)
+ C_{i+1} (xd_{i+1} - xd_i) + [i = loaded] F cos(w t) - (the TMD's forces on storey i), x_0 = 0.

The TMD hangs on storey s, its inerter's second terminal is j (a storey, or 0: the ground).
:func:`~pyfmu_wrapper.physics.kernels.tmd_link` gives the TMD side as an affine function of the
inerter terminal's acceleration (its ``xdd`` enters through the inerter only; its x, xd through the
spring, damper and friction Fs): the links' force is f = f0 + a xdd_j, of which Fs acts on storey s
and the inerter's P = f - Fs on storey j (on the ground when j = 0). The feed-through a joins storey
j's mass, M_j + a, so every storey acceleration stays explicit.

Packed parameters: the paper's array (:func:`pyfmu_wrapper.physics.params.pack`: the TMD, F and w
at their ``P_*`` indices) followed by n, the loaded storey, s, j and the n masses, stiffnesses and
dampings (:data:`FRAME_AT` onwards).
"""

from __future__ import annotations

from ..._jit import njit
from ...physics.jacobians import complex_step_jacobian
from ...physics.kernels import Num, Vec, excitation, input_value, static_link_force, switching_functions, tmd_link
from ...physics.params import N_PARAMS, P_df

#: index of the frame's part of the packed array: n, loaded storey, TMD storey, inerter terminal,
#: then masses, stiffnesses, dampings (n each)
FRAME_AT = N_PARAMS
F_N, F_LOAD, F_TMD, F_TO, F_VALUES = FRAME_AT, FRAME_AT + 1, FRAME_AT + 2, FRAME_AT + 3, FRAME_AT + 4


@njit(cache=True, inline="always")
def storey_index(i: int, n: int) -> int:
    """Index of x_i in the state (i = 1..n)."""
    return 0 if i == n else 6 + 2 * (n - 1 - i)


@njit(cache=True)
def storey_rates(t: float, z: Vec, p: Vec, f0: Num, fs: Num, a: Num, out: Vec) -> Num:
    """The storeys' entries of dz/dt under F cos(w t) and the TMD's forces: fs (spring, damper,
    friction) on the TMD's storey s, f0 - fs (the inerter) on the terminal j, the feed-through a
    joining M_j; returns xdd_j (0 for the ground). Each storey's force is summed in the order of the
    paper's base equation (excitation, damper and spring below, those above, the TMD's force), so a
    1-storey frame gives the paper's numbers to the last bit."""
    n = int(p[F_N])
    m0, k0, c0 = F_VALUES, F_VALUES + n, F_VALUES + 2 * n
    load, s, j = int(p[F_LOAD]), int(p[F_TMD]), int(p[F_TO])
    xdd = 0.0 * z[0]  # the inerter terminal's acceleration (0: the ground)
    for i in range(1, n + 1):
        ix = storey_index(i, n)
        f = excitation(t, p) if i == load else 0.0 * z[ix]
        if i == 1:
            f = f - p[c0] * z[ix + 1] - p[k0] * z[ix]
        else:
            ib = storey_index(i - 1, n)
            f = f - p[c0 + i - 1] * (z[ix + 1] - z[ib + 1]) - p[k0 + i - 1] * (z[ix] - z[ib])
        if i < n:
            ia = storey_index(i + 1, n)
            f = f + p[c0 + i] * (z[ia + 1] - z[ix + 1]) + p[k0 + i] * (z[ia] - z[ix])
        if i == s:
            f = f - (f0 if j == s else fs)
        elif i == j:
            f = f - (f0 - fs)
        out[ix] = z[ix + 1]
        out[ix + 1] = f / (p[m0 + i - 1] + a) if i == j else f / p[m0 + i - 1]
        if i == j:
            xdd = out[ix + 1]
    return xdd


@njit(cache=True)
def frame_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt of the frame with its TMD under F cos(w t) (module doc); z real or complex."""
    sx = storey_index(int(p[F_TMD]), int(p[F_N]))
    f0, a, ydd0, ya, ddd0, da, _ = tmd_link(z[sx], z[sx + 1], z[2], z[3], z[4], z[5], p)
    fs = static_link_force(z[sx], z[sx + 1], z[2], z[3], p)
    xdd = storey_rates(t, z, p, f0, fs, a, out)
    out[2] = z[3]
    out[3] = ydd0 + ya * xdd
    out[4] = z[5]
    out[5] = ddd0 + da * xdd


@njit(cache=True)
def storeys_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    """dz/dt of the frame alone (the frame FMU): the TMD's force on the structure f = u[0] (its
    links' total, TMDInerter.force) and its inerter's share P = u[1] (TMDInerter.inerter_force) are
    input polynomials (:func:`~pyfmu_wrapper.physics.kernels.input_value`): f - P acts on the TMD's
    storey, P on the inerter's terminal. The TMD's slots z[2:6] stay at rest."""
    f = input_value(u, 0, t)
    storey_rates(t, z, p, f, f - input_value(u, 1, t), 0.0, out)
    for i in range(2, 6):
        out[i] = 0.0 * z[0]


#: J = d rhs / dz and ft = d rhs / dt of :func:`frame_rhs` by the complex step (exact to rounding)
frame_jacobian = complex_step_jacobian(frame_rhs, "frame")


@njit(cache=True)
def frame_switching(z: Vec, p: Vec, g: Vec) -> None:
    """The paper's switching functions (:func:`~pyfmu_wrapper.physics.kernels.switching_functions`)
    with the friction's relative velocity taken at the TMD's storey."""
    switching_functions(z, p, g)
    if p[P_df] > 0.0:
        sx = storey_index(int(p[F_TMD]), int(p[F_N]))
        g[0] = z[sx + 1] - z[3]
