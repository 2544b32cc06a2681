"""Exact steady-state frequency response of the linear configurations.

With no friction and no gap the coupled equations are linear, dz/dt = A z + b F cos(w t), and the
steady state is z(t) = Re(Z e^{i w t}) with Z = (i w - A)^{-1} b F. A and b are read off the
physics kernels themselves (the right-hand side is affine in z and in the applied force, so two
evaluations per column are exact to rounding): there is no second statement of the equations.
This covers the ideal inerter, no inerter, and the inerter in series with the ki-ci mesh spring
(play model with eps = 0).

``linearise=True`` gives the frequency response of the linearisation about rest instead, for
smooth nonlinear configurations (the cubic spring term k3): A is the complex-step Jacobian of the
kernels at z = 0 (exact to rounding), the small-amplitude limit of the nonlinear response.
Friction and a gap have no linearisation about rest (a kink or a 1e6 slope) and are refused.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..physics.params import InerterModel, ParameterError, TMDParams
from ..physics.unit import ModelUnit


def linear_system(unit: ModelUnit, base: Any, tmd: TMDParams, linearise: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(A, b): dz/dt = A z + b f for the applied force f [N] (module doc for linearise); unit: the
    structure's model, base: the primary structure's parameters."""
    gap = tmd.play_gap if tmd.inerter == InerterModel.PLAY else 0.0
    if linearise:
        if unit.takes_tmd and (tmd.friction_force != 0.0 or gap != 0.0):
            raise ParameterError(
                "a linearisation about rest needs a smooth configuration: "
                f"friction_force = {tmd.friction_force} and play_gap = {gap} must be 0"
            )
    elif not unit.is_linear(base, tmd):
        raise ParameterError(
            "the exact frequency response needs a linear configuration: "
            + (
                f"friction_force = {tmd.friction_force}, play_gap = {gap} and "
                f"cubic_stiffness = {tmd.cubic_stiffness} must be 0 (linearise=True gives the "
                "small-amplitude limit of a smooth configuration)"
                if unit.takes_tmd
                else f"model {unit.name!r} is not linear at these parameters"
            )
        )
    return unit.linear_system(base, tmd, linearise)


def exact_response(
    unit: ModelUnit, base: Any, tmd: TMDParams, omegas: ArrayLike, linearise: bool = False
) -> np.ndarray:
    """Complex amplitudes Z[k, :] of the state (the paper's [x, xd, y, yd, d, dd]; a model's own
    layout) at each omega [rad/s]."""
    A, b = linear_system(unit, base, tmd, linearise)
    n = A.shape[0]
    omegas = np.atleast_1d(np.asarray(omegas, dtype=float))
    out = np.empty((omegas.size, n), dtype=complex)
    eye = np.eye(n)
    for k, w in enumerate(omegas):
        try:
            out[k] = np.linalg.solve(1j * w * eye - A, b * base.force_amplitude)
        except np.linalg.LinAlgError:
            # an undamped internal mode exactly at w (e.g. m = 0: the TMD node is massless and
            # carries no force); the base response is still defined: take the least-norm solution
            out[k] = np.linalg.lstsq(1j * w * eye - A, b * base.force_amplitude, rcond=None)[0]
    return out


def exact_amplitude(
    unit: ModelUnit, base: Any, tmd: TMDParams, omegas: ArrayLike, linearise: bool = False
) -> np.ndarray:
    """Steady-state amplitude |z[0]| [m] (the base; a frame's top storey) at each omega [rad/s]."""
    return np.abs(exact_response(unit, base, tmd, omegas, linearise)[:, 0])


def exact_state(
    unit: ModelUnit, base: Any, tmd: TMDParams, omega: float, t: float = 0.0, linearise: bool = False
) -> np.ndarray:
    """The steady-state state vector at time t (phase w t) of a linear configuration (``linearise``: of
    the linearisation about rest)."""
    Z = exact_response(unit, base, tmd, [omega], linearise)[0]
    return np.real(Z * np.exp(1j * omega * t))
