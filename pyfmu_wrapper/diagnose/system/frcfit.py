"""The FRC records as evidence for the system diagnosis: one effect's parameter refitted on the
stepped-sine points with the other effects held at their time-record values, its held-out
chi-square by 3 folds (every third frequency), and the chi-square drop of a model fitted elsewhere
(methods of :class:`.frc.FRCDiagnosis`, kept apart by job: the stand-alone FRC diagnosis is
:meth:`.frc.FRCDiagnosis.run`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.optimize import minimize_scalar

from ...physics.params import ParameterError
from ...solvers.monolithic import SolverError

if TYPE_CHECKING:
    from numpy import ndarray

    from ...physics.params import BaseParams, TMDParams


class FRCEffectFit:
    # what the mixin reads of the FRC diagnosis it is mixed into (FRCDiagnosis)
    base: BaseParams
    tmd: TMDParams
    F: ndarray
    x: ndarray
    stroke: float
    pred0: ndarray
    _fold: ndarray

    if TYPE_CHECKING:

        @property
        def sigma(self) -> ndarray: ...

        def predict(self, params: dict[str, Any]) -> ndarray | None: ...

        def chi2(self, pred: ndarray, mask: ndarray | None = None) -> float: ...

    def bounds(self, key: str, stroke: float) -> tuple[float, float] | None:
        """Plausible range of an effect parameter for the FRC search (SI)."""
        b, t = self.base, self.tmd
        Fm = float(np.max(np.abs(self.F)))
        d = max(stroke, self.stroke, 1e-9)
        return {
            "viscous.delta_damping": (-t.damping, max(10 * t.damping, 100.0)),
            "mass_split.delta_inertance": (-t.inertance + 1e-6, t.mass - 1e-6),
            "cubic.cubic_stiffness": (-t.stiffness / (3 * d * d), 3 * t.stiffness / (d * d)),
            "force_error.force_gain_error": (-0.5, 0.5),
            "friction.friction_force": (0.0, 0.5 * Fm),
            "base_mass.delta_mass": (-0.3 * b.mass, 0.3 * b.mass),
            "base_stiffness.delta_stiffness": (-0.3 * b.stiffness, 0.3 * b.stiffness),
            "base_damping.delta_damping": (-b.damping, 2.0 * b.damping),
            "tmd_stiffness.delta_stiffness": (-0.3 * t.stiffness, 0.3 * t.stiffness),
        }.get(key)

    def fit_effect(
        self, key: str, fixed: dict, guess: float | None = None, std: float | None = None, stroke: float = 0.0
    ) -> dict[str, float] | None:
        """Fit parameter ``key`` on the FRC points with the parameters ``fixed`` (from the time
        records) held; search within guess +- 6 std (the time-record fit) clipped to the plausible
        range, or the whole range. Returns {value, std, chi2_all, chi2_cv} (chi2_cv: each third of
        the frequencies predicted with the value fitted on the other two thirds; the per-point
        prediction is quadratic in the parameter around the fit), or None."""
        rng = self.bounds(key, stroke)
        if rng is None:
            return None
        lo, hi = rng
        if guess is not None and std is not None and np.isfinite(std) and std > 0:
            lo, hi = max(lo, guess - 6 * std), min(hi, guess + 6 * std)
            if not lo < hi:
                return None
        cache = {}

        def pred(v: float) -> Any:
            if v not in cache:
                cache[v] = self.predict({**fixed, key: float(v)})
            return cache[v]

        def obj(v: float) -> float:
            try:
                p = pred(v)
            except (SolverError, ParameterError, ValueError, FloatingPointError):
                return 1e20
            return self.chi2(p) if p is not None and np.all(np.isfinite(p)) else 1e20

        nonlinear = key.startswith(("cubic.", "friction.")) or not self.tmd.is_linear
        grid = np.linspace(lo, hi, 9 if nonlinear else 17)
        if key.startswith("cubic.") and lo < 0 < hi:  # the cubic's range spans decades: a log grid
            grid = np.unique(np.concatenate([[0.0], -np.geomspace(1e-2 * -lo, -lo, 2), np.geomspace(1e-3 * hi, hi, 6)]))
        vals = [obj(v) for v in grid]
        j = int(np.argmin(vals))
        a, c = grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]
        res = minimize_scalar(
            obj,
            bounds=(a, c),
            method="bounded",
            options=dict(maxiter=10 if nonlinear else 30, xatol=1e-6 * max(abs(hi - lo), 1e-300)),
        )
        v0 = float(res.x) if res.fun <= vals[j] else float(grid[j])
        if obj(v0) >= 1e20:
            return None
        h = max(0.02 * abs(v0), 1e-4 * (hi - lo))
        try:
            P = np.array([pred(v0 - h), pred(v0), pred(v0 + h)])
        except (SolverError, ParameterError, ValueError, FloatingPointError):
            return None
        if P.ndim != 2 or not np.all(np.isfinite(P)):
            return None
        # per point: pred(v0 + u h) = P1 + u (P2 - P0)/2 + u^2 (P2 - 2 P1 + P0)/2
        d1, d2 = 0.5 * (P[2] - P[0]), 0.5 * (P[2] - 2 * P[1] + P[0])
        sig = self.sigma
        u = np.linspace(-3.0, 3.0, 241)
        Q = (self.x[None, :] - (P[1][None, :] + u[:, None] * d1 + u[:, None] ** 2 * d2)) / sig
        Q = Q * Q  # (u, point)
        cv = 0.0
        for k in range(3):
            tr = self._fold != k
            iu = int(np.argmin(Q[:, tr].sum(axis=1)))
            cv += float(Q[iu, ~tr].sum())
        g = d1 / sig
        sd = h / math.sqrt(max(float(g @ g), 1e-300))
        return {"value": v0, "std": sd, "chi2_all": self.chi2(P[1]), "chi2_cv": cv}

    def chi2_of(self, params: dict[str, Any]) -> float | None:
        """FRC chi-square of the nominal changed by ``params`` (None when not evaluable)."""
        try:
            pred = self.predict(params)
        except (SolverError, ParameterError, ValueError, FloatingPointError):
            return None
        if pred is None or not np.all(np.isfinite(pred)):
            return None
        return self.chi2(pred)
