"""Multi-storey shear frames with a linear TMD-inerter or TMDI: the structure's matrices and its exact
frequency response, written directly from the structure (an independent statement of the linear
physics, not read off the kernels).

A shear frame of n storeys: storey i (1 = lowest) has mass ``masses[i-1]`` [kg] and is joined to
the storey below (storey 0 = the ground) by a spring ``stiffnesses[i-1]`` [N/m] and a viscous damper
``dampings[i-1]`` [N s/m]. A harmonic force F cos(w t) [N] acts on storey ``force_storey``. A TMD
of mass m [kg] hangs on storey ``storey`` by a spring k and a damper c; an ideal inerter of
inertance I [kg] joins the TMD mass to ``inerter_to``: the same storey (the paper's TMD-inerter),
another storey, or the ground (0: the TMDI's inerter to the ground). The inerter's force is
I (d2y/dt2 - d2x_j/dt2) between its two terminals, so it enters the inertance matrix B like a mass
between two nodes; the steady state X of the displacements [storeys 1..n, TMD] solves

    (K - w^2 (M + B) + i w C) X = F.

With n = 1 and the inerter to storey 1 this is the paper's base oscillator with the ideal inerter.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class ShearFrame:
    """A shear frame: per storey (1 = lowest) mass [kg], stiffness and damping to the storey below
    [N/m, N s/m]; a force amplitude [N] on one storey."""

    masses: tuple[float, ...]
    stiffnesses: tuple[float, ...]
    dampings: tuple[float, ...]
    force_amplitude: float = 200.0
    force_storey: int = 0  #: 1..n; 0 means the top storey

    def __post_init__(self) -> None:
        n = len(self.masses)
        if not 1 <= n <= 20:
            raise ValueError(f"a shear frame has 1 to 20 storeys, got {n}")
        if len(self.stiffnesses) != n or len(self.dampings) != n:
            raise ValueError(
                f"masses, stiffnesses and dampings must have one value per storey ({n}), got "
                f"{len(self.stiffnesses)} stiffnesses and {len(self.dampings)} dampings"
            )
        for name, vals, strict in (("masses", self.masses, True), ("stiffnesses", self.stiffnesses, True)):
            if not all(np.isfinite(v) and v > 0 for v in vals) and strict:
                raise ValueError(f"{name} must all be finite and > 0, got {list(vals)}")
        if not all(np.isfinite(v) and v >= 0 for v in self.dampings):
            raise ValueError(f"dampings must all be finite and >= 0, got {list(self.dampings)}")
        if not 0 <= self.force_storey <= n:
            raise ValueError(f"force_storey must be a storey 1..{n} (0: the top), got {self.force_storey}")

    @property
    def n(self) -> int:
        return len(self.masses)

    @classmethod
    def uniform(cls, n: int, mass: float, stiffness: float, damping: float, **kw: float) -> ShearFrame:
        return cls((mass,) * n, (stiffness,) * n, (damping,) * n, **kw)  # type: ignore[arg-type]


@dataclass(frozen=True)
class LinearTMD:
    """A linear TMD on storey ``storey`` (spring k, damper c) with an ideal inerter I from the TMD
    mass to ``inerter_to`` (a storey 1..n, or 0 for the ground: the TMDI)."""

    storey: int
    mass: float
    stiffness: float
    damping: float = 0.0
    inertance: float = 0.0
    inerter_to: int | None = None  #: None: the TMD's own storey

    def terminal(self) -> int:
        return self.storey if self.inerter_to is None else self.inerter_to


def matrices(
    frame: ShearFrame, tmd: LinearTMD | None = None
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(M, B, C, K, F): mass, inertance, damping and stiffness matrices and the force amplitude
    vector of the displacements [storeys 1..n, TMD (if any)]."""
    n = frame.n
    size = n + (tmd is not None)
    M, B, C, K = (np.zeros((size, size)) for _ in range(4))
    F = np.zeros(size)

    def link(mat: NDArray[np.float64], i: int | None, j: int | None, v: float) -> None:
        """An element of value v between nodes i and j (None: the ground)."""
        for a, b in ((i, j), (j, i)):
            if a is not None:
                mat[a, a] += v
                if b is not None:
                    mat[a, b] -= v

    for s in range(n):
        M[s, s] = frame.masses[s]
        below = s - 1 if s > 0 else None
        link(K, s, below, frame.stiffnesses[s])
        link(C, s, below, frame.dampings[s])
    F[(frame.force_storey or n) - 1] = frame.force_amplitude
    if tmd is not None:
        if not 1 <= tmd.storey <= n or not 0 <= tmd.terminal() <= n:
            raise ValueError(f"the TMD's storey and inerter terminal must be storeys of the frame (1..{n}; 0: ground)")
        t, s = n, tmd.storey - 1
        M[t, t] = tmd.mass
        link(K, t, s, tmd.stiffness)
        link(C, t, s, tmd.damping)
        link(B, t, tmd.terminal() - 1 if tmd.terminal() else None, tmd.inertance)
    return M, B, C, K, F


def frequency_response(frame: ShearFrame, tmd: LinearTMD | None, omegas: ArrayLike) -> NDArray[np.complex128]:
    """Complex amplitudes X[k, :] of the displacements [storeys 1..n, TMD] at each omega [rad/s]."""
    M, B, C, K, F = matrices(frame, tmd)
    w = np.atleast_1d(np.asarray(omegas, dtype=float))
    return np.array([np.linalg.solve(K - wk**2 * (M + B) + 1j * wk * C, F) for wk in w])


def top_amplitude(frame: ShearFrame, tmd: LinearTMD | None, omegas: ArrayLike) -> NDArray[np.float64]:
    """max |x| of the top storey [m] in the steady state, at each omega [rad/s]."""
    return np.abs(frequency_response(frame, tmd, omegas)[:, frame.n - 1])
