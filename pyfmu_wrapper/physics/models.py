"""The models the integrator is built from: each one a right-hand side, a Jacobian and switching
functions, taken from the kernels (no equation is written here).

A model is an :class:`OdeModel`; :func:`pyfmu_wrapper.solvers.rodas.make_integrator` turns it into
a compiled integrator, so a new model (another absorber) is a new :class:`OdeModel` here or in its
own module, and no edit of the solver. The functions a model supplies (all numba-compiled, all
writing into caller-provided arrays):

* ``rhs(t, z, p, u, out)``: out = dz/dt (z real or complex: the Jacobians use the complex step);
* ``jacobian(t, z, p, u, J, ft, zc, oc)``: J = d rhs / dz and ft = d rhs / dt (zc, oc: complex
  work arrays of the state's length);
* ``switching(z, p, g)``: the switching functions, whose sign changes mark the non-smooth points a
  step should land on (g has ``n_switches`` entries; an inactive one is set to 1);
* ``mode(g)``: the index (0 .. ``n_modes`` - 1) of the smooth mode the switching values g lie in;
  the integrator remembers the last step size that worked in each mode.

``switch_tolerance[k]`` says how close to its surface switching function k counts as "on" it: -1
for the caller's band (the friction band 1/s of the velocity difference), or the index of the
state whose absolute tolerance (times the integrator's surface_tol) is the tolerance (an index
past the state's end: no tolerance).

The three systems of this package: the coupled base + TMD (the monolithic solver) and the base and
TMD subsystems of the two FMUs, driven by input polynomials u (see :mod:`.kernels`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .._jit import njit
from .jacobians import coupled_jacobian, system_dfdt_work, system_jacobian_work, tmd_jacobian
from .kernels import SYS_BASE, SYS_COUPLED, SYS_TMD, Vec, system_rhs, system_switching


@dataclass(frozen=True, kw_only=True)
class OdeModel:
    """A first-order system z' = rhs(t, z) with switching functions (see the module doc)."""

    name: str  #: a Python identifier, unique per model (names the compiled integrator and its cache)
    rhs: Any
    jacobian: Any
    switching: Any
    mode: Any
    n_switches: int
    n_modes: int
    switch_tolerance: tuple[int, ...]
    state_names: tuple[str, ...]
    #: describe(z, p, atol, band) -> the mode of state z in words (for error messages)
    describe: Callable[..., str]


# -- the contact mode shared by the three systems: g[1] = d - eps, g[2] = d + eps -----------------


@njit(cache=True)
def contact_mode_index(g: Vec) -> int:
    """0: engaged in extension (d < -eps), 1: free, 2: engaged in compression (d > eps)."""
    return (1 if g[1] > 0.0 else 0) - (1 if g[2] < 0.0 else 0) + 1


_SURFACE_TOL = 1e-3  # the integrator's surface tolerance (solvers.rodas.SURFACE_TOL), for messages


def mode_describer(friction: bool, contact_index: int) -> Callable[..., str]:
    def describe(z: ArrayLike, p: Vec, atol: ArrayLike, band: float, _switching: Any = None) -> str:
        g = np.empty(3)
        _switching(np.asarray(z, dtype=float), p, g)
        parts = []
        if friction and g[0] != 1.0:
            parts.append("friction stuck" if abs(g[0]) <= band else "friction sliding")
        if g[1] != 1.0 or g[2] != 1.0:
            tol = _SURFACE_TOL * float(np.asarray(atol)[contact_index])
            if abs(g[1]) <= tol or abs(g[2]) <= tol:
                parts.append("gear chain on its contact surface")
            elif g[1] > 0.0:
                parts.append("gear engaged in compression (d > eps)")
            elif g[2] < 0.0:
                parts.append("gear engaged in extension (d < -eps)")
            else:
                parts.append("gear free (|d| < eps)")
        return ", ".join(parts) if parts else "smooth"

    return describe


def bind_describe(describe: Callable[..., str], switching: Any) -> Callable[[ArrayLike, Vec, ArrayLike, float], str]:
    return lambda z, p, atol, band: describe(z, p, atol, band, _switching=switching)


# -- coupled base + TMD: z = [x, xd, y, yd, d, dd] ----------------------------------------------------


@njit(cache=True)
def coupled_rhs(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    system_rhs(SYS_COUPLED, t, z, p, u, out)


@njit(cache=True)
def coupled_jac(t: float, z: Vec, p: Vec, u: Vec, J: Vec, ft: Vec, zc: Vec, oc: Vec) -> None:
    coupled_jacobian(t, z, p, J, ft)


@njit(cache=True)
def coupled_switching(z: Vec, p: Vec, g: Vec) -> None:
    system_switching(SYS_COUPLED, z, p, g)


# -- base subsystem: z = [x, xd], input u = the link force polynomial --------------------------------


@njit(cache=True)
def base_rhs_u(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    system_rhs(SYS_BASE, t, z, p, u, out)


@njit(cache=True)
def base_jac(t: float, z: Vec, p: Vec, u: Vec, J: Vec, ft: Vec, zc: Vec, oc: Vec) -> None:
    system_jacobian_work(SYS_BASE, t, z, p, u, J, zc, oc)
    system_dfdt_work(SYS_BASE, t, z, p, u, ft, zc, oc)


@njit(cache=True)
def base_switching(z: Vec, p: Vec, g: Vec) -> None:
    system_switching(SYS_BASE, z, p, g)


# -- TMD subsystem: z = [y, yd, d, dd], inputs u = base motion polynomials (+ kappa) ---------------


@njit(cache=True)
def tmd_rhs_u(t: float, z: Vec, p: Vec, u: Vec, out: Vec) -> None:
    system_rhs(SYS_TMD, t, z, p, u, out)


@njit(cache=True)
def tmd_jac(t: float, z: Vec, p: Vec, u: Vec, J: Vec, ft: Vec, zc: Vec, oc: Vec) -> None:
    tmd_jacobian(t, z, p, u, J)
    system_dfdt_work(SYS_TMD, t, z, p, u, ft, zc, oc)


@njit(cache=True)
def tmd_switching(z: Vec, p: Vec, g: Vec) -> None:
    system_switching(SYS_TMD, z, p, g)


COUPLED = OdeModel(
    name="coupled",
    rhs=coupled_rhs,
    jacobian=coupled_jac,
    switching=coupled_switching,
    mode=contact_mode_index,
    n_switches=3,
    n_modes=3,
    switch_tolerance=(-1, 4, 4),
    state_names=("x", "xd", "y", "yd", "d", "dd"),
    describe=bind_describe(mode_describer(True, 4), coupled_switching),
)
BASE = OdeModel(
    name="base",
    rhs=base_rhs_u,
    jacobian=base_jac,
    switching=base_switching,
    mode=contact_mode_index,
    n_switches=3,
    n_modes=3,
    switch_tolerance=(-1, 2, 2),
    state_names=("x", "xd"),
    describe=bind_describe(mode_describer(False, 2), base_switching),
)
TMD = OdeModel(
    name="tmd",
    rhs=tmd_rhs_u,
    jacobian=tmd_jac,
    switching=tmd_switching,
    mode=contact_mode_index,
    n_switches=3,
    n_modes=3,
    switch_tolerance=(-1, 2, 2),
    state_names=("y", "yd", "d", "dd"),
    describe=bind_describe(mode_describer(False, 2), tmd_switching),
)


# -- a smooth model of its own (no switching, one mode): what every such model shares -------------------


@njit(cache=True)
def no_switching(z: Vec, p: Vec, g: Vec) -> None:
    """A smooth model: its one switching function is inactive (1)."""
    g[0] = 1.0


@njit(cache=True)
def one_mode(g: Vec) -> int:
    """A smooth model's one mode."""
    return 0


def describe_smooth(z: ArrayLike, p: Vec, atol: ArrayLike, band: float) -> str:
    """A smooth model's mode in words (for the integrator's error messages)."""
    return "smooth"


def smooth_model(name: str, rhs: Any, jacobian: Any, state_names: tuple[str, ...]) -> OdeModel:
    """The :class:`OdeModel` of a smooth model with equations of its own (the linear TMD, the pendulum):
    one inactive switching function, one mode, no switching tolerance (an index past the state)."""
    return OdeModel(
        name=name,
        rhs=rhs,
        jacobian=jacobian,
        switching=no_switching,
        mode=one_mode,
        n_switches=1,
        n_modes=1,
        switch_tolerance=(1000,),
        state_names=state_names,
        describe=describe_smooth,
    )
