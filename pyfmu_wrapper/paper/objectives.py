"""What a TMD optimisation minimises: the named objectives of a frequency-response curve and the exact
linear responses they are computed from (the vectorised complex amplitudes, the H2 norm from the
controllability Gramian). The search itself is :mod:`.optimise`.

Objectives (registry :data:`OBJECTIVES`; each is minimised):

- ``peak``: max over the band of the base amplitude (min-max design);
- ``mean``: mean base amplitude over the band (area under the FRC / band width);
- ``mean_square``: mean of the squared base amplitude over the band;
- ``h2``: int |X|^2 dw. Linear configurations: exact, over all frequencies 0..inf (closed form
  from the controllability Gramian; the band is ignored). Nonlinear ones: over the band, from a
  frequency sweep (the band must hold the resonance; 15..25 rad/s does);
- ``peak_relative``: max over the band of the TMD stroke |X - Y| (linear configurations only).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..physics.params import BaseParams, InerterModel, TMDParams


class OptimisationError(InputError):
    """Bad optimisation request (unknown objective or parameter, bad bounds or band)."""


# --- frequency responses ------------------------------------------------------------------------


def _active(tmd: TMDParams) -> list[int]:
    """States that carry dynamics: [x, xd, y, yd] (+ [d, dd] for the play chain)."""
    return [0, 1, 2, 3, 4, 5] if tmd.inerter == InerterModel.PLAY else [0, 1, 2, 3]


def _reduced_system(base: BaseParams, tmd: TMDParams) -> tuple[np.ndarray, np.ndarray, list[int]]:
    from ..models.solve import linear_system  # imported at first use: the objectives' names cost nothing

    A, b = linear_system(base, tmd)
    act = _active(tmd)
    return A[np.ix_(act, act)], b[act], act


def linear_response(
    base: BaseParams, tmd: TMDParams, omegas: Sequence[float] | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Exact complex amplitudes (X, X - Y) of the base and of the TMD stroke at each omega [rad/s].

    Vectorised counterpart of :func:`pyfmu_wrapper.solvers.frequency_response.exact_response`
    (same A, b, read off the kernels), for the many evaluations of an optimisation.
    """
    A, b, _ = _reduced_system(base, tmd)
    w = np.atleast_1d(np.asarray(omegas, dtype=float))
    n = A.shape[0]
    mats = 1j * w[:, None, None] * np.eye(n) - A
    rhs = np.broadcast_to((b * base.force_amplitude)[:, None], (w.size, n, 1))
    Z = np.linalg.solve(mats, rhs)[..., 0]
    return Z[:, 0], Z[:, 0] - Z[:, 2]


def h2_exact(base: BaseParams, tmd: TMDParams) -> float:
    """int_0^inf |X(w)|^2 dw [m^2 rad/s] for a linear configuration (inf if not asymptotically stable).

    With dz/dt = A z + b f: int_{-inf}^{inf} |c (iw - A)^-1 b|^2 dw = 2 pi c P c^T where
    A P + P A^T + b b^T = 0 (controllability Gramian), so int_0^inf = pi F^2 P[0, 0].
    """
    A, b, _ = _reduced_system(base, tmd)
    if not np.all(np.linalg.eigvals(A).real < 0.0):
        return math.inf
    from scipy.linalg import solve_continuous_lyapunov

    P = solve_continuous_lyapunov(A, -np.outer(b, b))
    return float(math.pi * base.force_amplitude**2 * P[0, 0])


# --- objectives ---------------------------------------------------------------------------------


def _trapz(y: np.ndarray, w: np.ndarray) -> float:
    return float(np.trapezoid(y, w)) if len(w) > 1 else float(y[0])


def _width(w: np.ndarray) -> float:
    return float(w[-1] - w[0]) if len(w) > 1 else 1.0


@dataclass(frozen=True)
class Objective:
    """A named scalar measure of a frequency-response curve, to be minimised.

    reduce(omegas, amplitude) -> float works on a sampled base-amplitude curve (any configuration);
    exact(base, tmd) -> float, if given, replaces it for linear configurations (no band);
    relative: the measure needs the TMD stroke |X - Y| (linear configurations only).
    """

    name: str
    summary: str
    reduce: Callable[[np.ndarray, np.ndarray], float]
    exact: Callable[[BaseParams, TMDParams], float] | None = None
    relative: bool = False


OBJECTIVES: dict[str, Objective] = {}


def register(obj: Objective) -> Objective:
    OBJECTIVES[obj.name] = obj
    return obj


register(Objective("peak", "max over the band of the base amplitude (min-max)", lambda w, a: float(np.max(a))))
register(
    Objective(
        "mean", "mean base amplitude over the band (area under the FRC / width)", lambda w, a: _trapz(a, w) / _width(w)
    )
)
register(
    Objective("mean_square", "mean squared base amplitude over the band", lambda w, a: _trapz(a * a, w) / _width(w))
)
register(
    Objective(
        "h2",
        "int |X|^2 dw: exact over all frequencies when linear, over the band otherwise",
        lambda w, a: _trapz(a * a, w),
        exact=h2_exact,
    )
)
register(
    Objective(
        "peak_relative",
        "max over the band of the TMD stroke |X - Y| (linear only)",
        lambda w, a: float(np.max(a)),
        relative=True,
    )
)


def get_objective(name: str | Objective) -> Objective:
    if isinstance(name, Objective):
        return name
    try:
        return OBJECTIVES[name]
    except KeyError:
        raise OptimisationError(f"unknown objective {name!r}; known: {sorted(OBJECTIVES)}") from None
