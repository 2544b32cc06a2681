"""System-level stepped-sine FRC records (omega, force_amplitude, x_max): residual against omega and
the candidates that the steady-state solvers can refit frugally.

A nominal with play: the play chain's x_max by the steady-state solver once, at every point; each
candidate's x_max is its change computed with an ideal inerter (I, no gap, no mesh spring) plus that
offset (the play's change of x_max is a fraction of a percent, docs/diagnose.md; a candidate's on it
is second order), so the candidates cost what they cost on a nominal without play.

Linear candidates (viscous damping, inertance/mass split with m + I fixed, forcing-amplitude error,
sensor bias on x_max, the nominal's own M, K, C and k) use the exact frequency response; dry
friction and the cubic spring use the monolithic steady state (one scalar parameter, a bounded
scalar search). Play (about 1 s per frequency, its effect on x_max below the steady-state scatter)
is not fitted here.

Noise of x_max: ``x_max_noise`` of dataset.yaml when given (an absolute std [m]); otherwise
estimated per FRC record from the relative residual the best candidate leaves (:meth:`FRCDiagnosis.run`),
its fitted parameter counted: s^2 = sum r^2 / (n - 1) (on 21 points of white noise its relative
scatter is 1/sqrt(2 (n - 1)) = 16 %). The guard: an estimate that neither a smooth structural
residual nor a few jumps can inflate, the MAD of the second differences (in frequency order) of the
same residual; where the residual's own estimate exceeds GUARD = 3 x the guard, structure is left in
it and the guard is the noise. The cost: a smooth structure no candidate fits, under ~6-9 x the noise
in the FRC residual, is partly taken for noise (a Gaussian bump of 9 x the noise: caught in 60 % of
draws). Before :meth:`FRCDiagnosis.run` the noise is the robust estimate of the
nominal's residual.

With time records, :meth:`FRCDiagnosis.fit_effect` (:mod:`.frcfit`) fits one effect's parameter on
the FRC with the other effects fixed at their time-record values, and its held-out chi-square by 3
folds (every third frequency), so an effect visible only in the FRC can be named.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from ...models.solve import exact_amplitude, steady_state
from ...physics.params import BaseParams, InerterModel, ParameterError, TMDParams
from ...solvers.monolithic import SolverError
from .. import progress
from . import frc_report
from .effects import VOCAB
from .frcfit import FRCEffectFit

if TYPE_CHECKING:
    from collections.abc import Iterator
    from typing import Any

    from numpy import float64, ndarray

    from ...physics.params import BaseParams, TMDParams
    from ..data import Dataset

BIC_THRESHOLD = 6.0
EXCESS_THRESHOLD = 0.15
#: a fitted model's residual estimates the noise unless its rms exceeds GUARD x the robust estimate
#: (white noise on 21 points: the ratio stays below 3 in 99.8 % of draws, tests/test_diagnose_corrected.py)
GUARD = 3.0


class FRCDiagnosis(FRCEffectFit):
    def __init__(self, ds: Dataset) -> None:
        recs = [r for r in ds.records if r.kind == "frc"]
        self.names = [r.name for r in recs]
        self.w = np.concatenate([r["omega"] for r in recs])
        self.F = np.concatenate([r["force_amplitude"] for r in recs])
        self.x = np.concatenate([r["x_max"] for r in recs])
        role = np.concatenate([np.full(r["omega"].size, r.role or "") for r in recs])
        self.rec = np.concatenate([np.full(r["omega"].size, i) for i, r in enumerate(recs)])  #: record of each point
        self.base = BaseParams(**ds.nominal["base"])
        self.tmd = TMDParams(**ds.nominal["tmd"])
        if (role == "test").any():
            self.test = role == "test"
        else:
            order = np.argsort(self.w, kind="stable")
            self.test = np.zeros(self.w.size, bool)
            self.test[order[1::3]] = True
        self.train = ~self.test
        self._play_offset: ndarray | None = None
        if self.tmd.inerter == InerterModel.PLAY and self.tmd.play_gap > 0.0:
            # a nominal with play: its x_max by the solver once (~1 s a point); a candidate's change is
            # computed on the same chain without the gap, plus this offset (module doc)
            self._play_offset = self._amplitude(self.base, self.tmd) - self._amplitude(self.base, _ideal(self.tmd))
        self.noise_given = float(ds.raw.get("x_max_noise", 0.0) or 0.0)
        self.noise = self.noise_given or self._noise()
        self.pred0 = self.amplitude(self.base, self.tmd)
        self.noise_rel = _d2_noise(self.x / self.pred0 - 1.0, self.w) or self.noise / max(
            float(np.abs(self.x).mean()), 1e-300
        )
        #: relative noise of every point, estimated per FRC record (two sweeps may have other noise)
        self.noise_rel_pt = self._per_record(self.x / self.pred0 - 1.0, self.noise_rel)
        try:  # the TMD's relative stroke |x - y| the nominal predicts (sets the cubic's plausible range)
            from ...models.solve import exact_response

            Z = exact_response(replace(self.base, force_amplitude=1.0), replace(self.tmd, friction_force=0.0), self.w)
            self.stroke = float(np.max(np.abs(Z[:, 0] - Z[:, 2]) * np.abs(self.F)))
        except Exception:  # noqa: BLE001 -- a nominal without a linear response (e.g. play): x_max instead
            self.stroke = float(np.max(np.abs(self.x)))
        self._fold = np.zeros(self.w.size, int)
        self._fold[np.argsort(self.w, kind="stable")] = np.arange(self.w.size) % 3

    def amplitude(
        self,
        base: BaseParams,
        tmd: TMDParams,
        gain: float | float64 = 1.0,
        bias: float | float64 = 0.0,
        only: ndarray | None = None,
    ) -> ndarray:
        """x_max at every FRC point (``only``: a mask of the points to compute; others are nan). With a
        play nominal, a model with the nominal's gap is the same model with an ideal inerter plus the
        play's offset of the nominal (:attr:`_play_offset`)."""
        off = self._play_offset
        if off is not None and tmd.inerter == InerterModel.PLAY and tmd.play_gap == self.tmd.play_gap:
            a = self._amplitude(base, _ideal(tmd), gain, only=only) + off * gain
            return a + bias
        return self._amplitude(base, tmd, gain, bias, only)

    def _amplitude(
        self,
        base: BaseParams,
        tmd: TMDParams,
        gain: float | float64 = 1.0,
        bias: float | float64 = 0.0,
        only: ndarray | None = None,
    ) -> ndarray:
        if tmd.is_linear:
            a = exact_amplitude(replace(base, force_amplitude=1.0), tmd, self.w) * np.abs(self.F) * gain
        else:
            # a sweep in frequency order reusing the shooting Jacobian of the previous point
            a = np.full(self.w.size, np.nan)
            hint: dict[str, Any] = {}
            for i in np.argsort(self.w, kind="stable"):
                if only is not None and not only[i]:
                    continue
                a[i] = steady_state(
                    replace(base, force_amplitude=self.F[i] * gain), tmd, float(self.w[i]), hint=hint
                ).amplitude
        return a + bias

    def changed(self, params: dict[str, Any]) -> tuple[BaseParams, TMDParams]:
        """The nominal changed by effect parameters (``effect.parameter``: the vocabulary's
        :meth:`~pyfmu_wrapper.physics.effects.Vocabulary.changed`, within the registry's bounds); a
        different split of m and I keeps I within 1e-6 of 0 and of m + I, and m + I fixed."""
        b, t = self.base, self.tmd
        split = params.get("mass_split.delta_inertance")
        new = VOCAB.changed(
            {"base": b, "tmd": t}, {k: v for k, v in params.items() if k != "mass_split.delta_inertance"}
        )
        if split is not None:
            I = min(max(t.inertance + float(split), 1e-6), t.inertia - 1e-6)
            new["tmd"] = replace(new["tmd"], inertance=I, mass=t.inertia - I)
        return new["base"], new["tmd"]

    def predict(self, params: dict[str, Any]) -> ndarray | None:
        """x_max predicted by the nominal model changed by fitted effect parameters (names as in
        the diagnosis: ``effect.parameter``, :meth:`changed`); None when an effect cannot be evaluated on
        FRC records (play: its effect on x_max is below the solver's steady-state scatter)."""
        if any(k.split(".", 1)[0] == "play" for k in params):
            return None
        model = {k: v for k, v in params.items() if k.split(".", 1)[0] not in ("force_error", "sensor_offset")}
        gain = 1.0 + params["force_error.force_gain_error"] if "force_error.force_gain_error" in params else 1.0
        pred = self.amplitude(*self.changed(model), gain=gain)
        if "sensor_offset.x_offset" in params:  # x_max may be a peak (+b) or half a peak-to-peak (0): fitted
            wgt = 1.0 / np.abs(self.x) ** 2
            pred = pred + float(np.sum(wgt * (self.x - pred)) / np.sum(wgt))
        return pred

    @property
    def sigma(self) -> ndarray:
        """Noise std of every x_max [m]: x_max_noise when given, else the relative estimate."""
        if self.noise_given:
            return np.full(self.x.size, self.noise_given)
        return np.abs(self.x) * np.maximum(self.noise_rel_pt, 1e-12)

    def _per_record(self, rel: ndarray, pooled: float) -> np.ndarray:
        """Robust relative noise per FRC record (:func:`_d2_noise` on each record's own points; the
        pooled value for a record of fewer than 5 points), one value per point."""
        out = np.full(self.x.size, float(pooled))
        if len(self.names) > 1:
            for i in range(len(self.names)):
                m = self.rec == i
                if m.sum() >= 5:
                    out[m] = _d2_noise(rel[m], self.w[m]) or pooled
        return out

    def set_noise(self, pred: ndarray, p: int) -> None:
        """The x_max noise from the relative residual of a model fitted with ``p`` parameters on these
        points (its degrees of freedom counted, per FRC record), guarded by this residual's
        second-difference estimates (:func:`_d2_guard`): where the rms exceeds GUARD x the guard, the
        guard (module doc)."""
        rel = self.x / pred - 1.0
        guard = _d2_guard(rel, self.w) or self.noise_rel
        guard_pt = np.full(self.x.size, guard)
        if len(self.names) > 1:
            for i in range(len(self.names)):
                m = self.rec == i
                if m.sum() >= 5:
                    guard_pt[m] = _d2_guard(rel[m], self.w[m]) or guard
        own = fit_noise(rel, p)
        self.noise_rel = own if 0.0 < own <= GUARD * guard else guard
        own_pt = np.full(self.x.size, own)
        if len(self.names) > 1:
            for i in range(len(self.names)):
                m = self.rec == i
                if m.sum() >= 5:
                    own_pt[m] = fit_noise(rel[m], p)
        self.noise_rel_pt = np.where((own_pt > 0) & (own_pt <= GUARD * guard_pt), own_pt, guard_pt)

    def chi2(self, pred: ndarray, mask: ndarray | None = None) -> float:
        r = (self.x - pred) / self.sigma
        if mask is not None:
            r = r[mask]
        return float(r @ r)

    def _noise(self) -> float:
        o = np.argsort(self.w)
        r = (self.x - self.amplitude(self.base, self.tmd))[o]
        d2 = np.diff(r, 2)
        return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0)) if d2.size else 0.0

    def _candidates(self) -> Iterator[Any]:
        """(effect, [its parameter], start or search range, x_max of the changed model): the FRC's
        candidates, each a change of the nominal from the unit's vocabulary (:meth:`changed`)."""
        b, t = self.base, self.tmd

        def changed_by(key: str) -> Any:
            return lambda p, only=None: self.amplitude(*self.changed({key: p[0]}), only=only)

        yield "viscous", ["delta_damping"], [0.0], changed_by("viscous.delta_damping")
        if t.inerter.name != "NONE":
            yield "mass_split", ["delta_inertance"], [0.0], changed_by("mass_split.delta_inertance")
        yield "force_error", ["force_gain_error"], [0.0], lambda p: self.amplitude(b, t, gain=1.0 + p[0])
        yield "sensor_offset", ["x_offset"], [0.0], lambda p: self.amplitude(b, t, bias=p[0])
        yield "friction", ["friction_force"], None, changed_by("friction.friction_force")
        yield (
            "cubic",
            ["cubic_stiffness"],
            self.bounds("cubic.cubic_stiffness", 0.0),
            changed_by("cubic.cubic_stiffness"),
        )
        for e in ("base_mass", "base_stiffness", "base_damping", "tmd_stiffness"):
            name = VOCAB[e].params[0].name
            yield e, [name], [0.0], changed_by(f"{e}.{name}")

    def run(self) -> FRCDiagnosis:
        """Fit each candidate on the training frequencies; everything in relative residuals
        (x - model) / x_max, the form of the measurement noise (a % of x_max)."""
        sc = np.maximum(np.abs(self.x), 1e-300)
        r0 = self.x - self.amplitude(self.base, self.tmd)
        nt = int(self.test.sum())
        q0 = r0 / sc
        self.rss0 = float(q0[self.test] @ q0[self.test])
        self.fits = []
        for name, pnames, p0, model in self._candidates():
            if p0 is None or isinstance(p0, tuple):  # friction, cubic: bounded scalar search on the training points

                def obj(v: float, model: Any = model) -> float:
                    try:
                        c = float(np.sum(((self.x - model([v], only=self.train)) / sc)[self.train] ** 2))
                    except (SolverError, ParameterError, ValueError, FloatingPointError):
                        return 1e20
                    # a point the solver does not converge on is nan: as a model that cannot be evaluated
                    # (np.argmin of the grid would otherwise pick the first nan)
                    return c if math.isfinite(c) else 1e20

                lo, upper = p0 if isinstance(p0, tuple) else (0.0, 0.5 * float(np.max(np.abs(self.F))))
                if isinstance(p0, tuple):  # decades: the best of a log grid, then Brent next to it
                    grid = np.unique(
                        np.concatenate([[0.0], -np.geomspace(1e-3 * -lo, -lo, 3), np.geomspace(1e-3 * upper, upper, 6)])
                    )
                    vals = [obj(v) for v in grid]
                    j = int(np.argmin(vals))
                    lo, upper = grid[max(j - 1, 0)], grid[min(j + 1, grid.size - 1)]
                res = minimize_scalar(
                    obj, bounds=(lo, upper), method="bounded", options=dict(maxiter=7, xatol=1e-3 * (upper - lo))
                )
                p = np.array([res.x])
            else:
                try:  # a nonlinear nominal's point the solver does not converge on is nan: the candidate is skipped
                    p = least_squares(
                        lambda q, model=model: ((self.x - model(q)) / sc)[self.train], p0, diff_step=1e-4
                    ).x
                except (SolverError, ParameterError, ValueError, FloatingPointError):
                    continue
            progress.candidate(name)
            try:
                pred = model(p)
            except (SolverError, ParameterError, ValueError, FloatingPointError):
                continue
            r = (self.x - pred) / sc
            rss_te = float(r[self.test] @ r[self.test])
            h = 1e-4 * max(abs(p[0]), 1e-3)
            try:
                J = ((model(p + h) - pred) / h / sc)[self.train]
            except (SolverError, ParameterError, ValueError, FloatingPointError):
                J = np.zeros(int(self.train.sum()))
            s2 = float(r[self.train] @ r[self.train]) / max(int(self.train.sum()) - 1, 1)
            sd = math.sqrt(s2 / max(float(J @ J), 1e-300))
            bic = nt * math.log(max(rss_te, 1e-300) / nt) + math.log(nt)
            self.fits.append(
                {
                    "effects": [name],
                    "params": {f"{name}.{pnames[0]}": float(p[0])},
                    "std": {f"{name}.{pnames[0]}": sd},
                    "pred": pred,
                    "rss_test": rss_te,
                    "bic": bic,
                }
            )
        self.bic0 = nt * math.log(max(self.rss0, 1e-300) / nt)
        self.fits.sort(key=lambda f: f["bic"])
        best = self.fits[0]
        self.set_noise(best["pred"], 1)
        if self.noise_given:
            self.noise_rel = self.noise_given / max(float(np.abs(self.x).mean()), 1e-300)
        nr = max(self.noise_rel, 1e-300)
        excess = math.sqrt(self.rss0 / nt) / nr - 1.0
        self.structural = excess > EXCESS_THRESHOLD and best["bic"] < self.bic0 - BIC_THRESHOLD
        g0 = max(self.rss0 / nt - nr**2, 0.0)
        for f in self.fits:
            g1 = max(f["rss_test"] / nt - nr**2, 0.0)
            f["gap_closed"] = None if g0 <= 0 else 1.0 - g1 / g0
            f["delta_bic"] = f["bic"] - self.bic0
        self.chosen = best if self.structural else None
        self.excess = excess
        # the honest part (gates.py): in noise units over every point, does the best candidate
        # explain at least MIN_SHARE of the gap, and is what it leaves still structural?
        from ..gates import noise_gate, remaining_gate, share_gate

        n = self.x.size
        c0, c1 = self.chi2(self.pred0), self.chi2(best["pred"])
        G0, G1 = max(c0 - n, 0.0), max(c1 - n, 0.0)
        self.hint: Any = None
        if self.chosen is not None and not share_gate(G0, G1):
            self.hint, self.chosen = best, None
        gap = noise_gate(c0, n)
        self.unexplained = bool(gap and (self.chosen is None or remaining_gate(c1, n, G0)))
        self.unexplained_share = (G1 / G0 if self.chosen is not None else 1.0) if (gap and G0 > 0) else 0.0
        if gap and self.chosen is None and self.hint is None:
            self.hint = best
        return self

    def result(self) -> dict[str, Any]:
        """Verdict, candidates and held-out gap (:func:`.frc_report.result`)."""
        return frc_report.result(self)

    def markdown(self) -> list[str]:
        """The FRC section of a report (:func:`.frc_report.markdown`)."""
        return frc_report.markdown(self)

    def write(self, out: Path, res: dict[str, Any] | None = None) -> None:
        """diagnosis.json, report.md and frc.png of a stand-alone FRC diagnosis (:func:`.frc_report.write`)."""
        frc_report.write(self, out, res)


def _d2_noise(rel: ndarray, w: ndarray) -> float:
    """Robust std of white noise on a smooth curve: 1.4826 MAD of the second differences in
    frequency order / sqrt(6)."""
    d2 = np.diff(np.asarray(rel)[np.argsort(w, kind="stable")], 2)
    return float(1.4826 * np.median(np.abs(d2 - np.median(d2))) / math.sqrt(6.0)) if d2.size else 0.0


def _d2_guard(rel: ndarray, w: ndarray) -> float:
    """The noise neither a smooth structural residual nor a few jumps (a hysteretic FRC) can inflate,
    for :meth:`FRCDiagnosis.set_noise`: the robust second-difference estimate (:func:`_d2_noise`; 32 %
    scatter on 21 points, so the guard factor GUARD is 3)."""
    return _d2_noise(rel, w)


def _ideal(tmd: TMDParams) -> TMDParams:
    """The TMD with an ideal inerter in place of the play chain (same I; no gap, no mesh spring)."""
    return replace(tmd, inerter=InerterModel.IDEAL, play_gap=0.0)


def fit_noise(rel: ndarray, p: int) -> float:
    """Std of the relative residual of a model with ``p`` parameters fitted on these points:
    sqrt(sum r^2 / (n - p))."""
    r = np.asarray(rel, float)
    return float(math.sqrt(float(r @ r) / (r.size - p))) if r.size > p else 0.0


def diagnose_frc(ds: Dataset) -> FRCDiagnosis:
    return FRCDiagnosis(ds).run()
