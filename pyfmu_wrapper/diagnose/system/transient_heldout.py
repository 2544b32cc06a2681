"""Transient records: the named effects' held-out stage, each record fitted alone (the agreement of
their parameters) and each record predicted from the others (held out by record).

Both at the cost of about one Jacobian of each record: at the named set's fit on all records
(``final``, parameters theta) each record's whitened residual r_i and Jacobian J_i are simulated once
(:func:`.transient_fit.fit` with ``linearise``: one simulation per parameter per record, side by side
in the threads). The fit of a set S of records (one record alone; all records but one) is then the
Gauss-Newton step ``theta_S = theta - (sum_S N_j)^-1 sum_S h_j``, with ``N_j = A_j^T P_j A_j`` and
``h_j = A_j^T P_j r_j``: A_j the parameters' columns of J_j, P_j the projection off a free decay's own
four start-state columns (its start state is a nuisance of its own record, fitted with the parameters
as in the full fit). Its std is ``sqrt(diag((sum_S N_j)^-1))``; a record alone's is widened by the
sandwich factor of the same J_i (:func:`.transient_sim.param_variance_factor`). The step is checked:
the residuals of S are simulated at theta_S (one simulation per record of S) and the step from there
with the same Jacobians (a chord Gauss-Newton step) must be below STEP_TOL of the std; else it is
taken and checked again, up to MAX_CHORD times, and a set that still moves (the model nonlinear over
the step: a drift between records, a friction that sticks) gets the full trust-region fit from
``final`` (:func:`.transient_fit.warm_start`), as before. In a linear-in-parameters model the first
step is the exact least-squares answer.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .agreement import LEVEL, records_agree
from .transient_effects import REGULARISATION, TEFFECTS, apply
from .transient_fit import TFit, chi2_of, fit, past_deadline, residual, start_update
from .transient_sim import param_variance_factor

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_sim import TView

AGREE_P = LEVEL  #: per-record parameters disagree when the agreement test's p-value is below this
#: model-error floor of a per-record parameter in the agreement test, as a share of max(|mean|, its
#: scale): the measured force is the simulation's input with its own noise (errors in variables), which
#: the statistical std does not cover (measured: viscous dc = 10 N s/m on four records scatters by 0.3 %)
AGREE_FLOOR = 0.01
STEP_TOL = 0.1  #: a linearised fit of a set of records is converged when its chord step is below this share of its std
MAX_CHORD = 4  #: checked steps of a linearised fit (one simulation per record of the set each) before the full fit
MAX_FRESH = 1  #: of which with the set's Jacobians afresh (one simulation per parameter per record)


def params_of(effects: tuple[str, ...], theta: ndarray, std: ndarray) -> dict[str, dict[str, Any]]:
    """The parameters of a fit of ``effects`` by name: value, std, unit."""
    out, i = {}, 0
    for e in effects:
        names, units = TEFFECTS[e]
        for n, u in zip(names, units):
            out[f"{e}.{n}"] = {"value": float(theta[i]), "std": float(std[i]), "unit": u}
            i += 1
    return out


def closed(c0: float, c1: float, n: int) -> float | None:
    """The share of the excess chi-square over its dof n that c1 closes from c0 (None: no excess)."""
    return 1 - (c1 - n) / (c0 - n) if c0 > n else None


#: what the verdict says when the records' agreement was not tested to its end
CUT_NOTE = "not tested: the CPU budget ran out during the records' own fits"


class HeldOut:
    """The held-out stage of a named set of effects on the records ``views`` (``masks``: their fit
    samples; ``final``: the set's fit on all of them; ``warm``: its :func:`.transient_fit.warm_start`;
    ``noise_parts``: record -> (white share of each channel's whitened noise, whitened input-noise
    response), as :class:`.transient.TransientDiagnosis` measures them)."""

    def __init__(
        self,
        views: list[TView],
        p_nom: ndarray,
        sc: dict[str, tuple[float, ...]],
        effects: tuple[str, ...],
        masks: list[ndarray],
        final: TFit,
        warm: dict[str, Any],
        noise_parts: dict[str, tuple[ndarray, ndarray | None]],
    ) -> None:
        self.views, self.p_nom, self.sc, self.effects = views, p_nom, sc, effects
        self.masks, self.final, self.warm, self.noise_parts = masks, final, warm, noise_parts
        self.scale = np.array([s for e in effects for s in sc[e]], float)
        self.refitted: list[str] = []  #: the sets that needed the full fit (names)
        self.cut = False  #: a fit of this stage stopped at the CPU deadline (:func:`.transient_fit.cpu_deadline`)
        self._lin: _Lin | None = None
        self._lin_tried = False

    def _stop(self) -> bool:
        """Past the CPU deadline (:func:`.transient_fit.cpu_deadline`): no further fit is started (and
        :attr:`cut` says the stage was cut short)."""
        if past_deadline():
            self.cut = True
        return self.cut

    def _linear(self) -> _Lin | None:
        """The records' residuals and Jacobians at ``final`` (computed once; None: not available)."""
        if not self._lin_tried:
            self._lin_tried = True
            if self.final.ok and self.warm and self.scale.size:
                f = fit(self.views, self.p_nom, self.effects, self.masks, None, self.sc, **self.warm, linearise=True)
                self.cut |= f.cut
                if f.ok and f.lin:
                    self._lin = _Lin(self, f)
        return self._lin

    def agreement(self) -> dict[str, Any]:
        """Each record alone: its parameters (``full_fit``: by the full fit, the linearised one not
        converging), and the chi-square of their agreement."""
        if len(self.views) < 2:
            return {"records": [], "p_value": None, "agree": True}
        effects = self.effects
        rows, vals, stds, comb = [], [], [], []
        lin = None if self._stop() else self._linear()
        for i, (v, m) in enumerate(zip(self.views, self.masks)):
            if lin is None and self._stop():
                break
            got = None if lin is None else lin.solve([i])
            if lin is not None and got is not None:
                theta, std = got[0], got[1] * np.sqrt(lin.widening(i, got[2][i]))
            else:
                f = fit([v], self.p_nom, effects, [m], None, self.sc, **self.warm)
                self.cut |= f.cut
                if not f.ok or f.cut:
                    continue
                self.refitted.append(v.name)
                theta, std = f.theta, f.std * np.sqrt(self._std_widening(v, m, f.theta))
            rows.append({"record": v.name, "params": params_of(effects, theta, std), "full_fit": got is None})
            vals.append(theta)
            stds.append(std)
            comb.append(v.free_decay and "friction" in effects)
        if self.cut:
            return {"records": rows, "p_value": None, "agree": True, "not_tested": CUT_NOTE}
        if len(vals) < 2:
            return {"records": rows, "p_value": None, "agree": True}
        scale = [s for e in effects for s in self.sc[e]]
        names = [f"{e}.{n}" for e in effects for n in TEFFECTS[e][0]]
        vote = np.array([n not in REGULARISATION for n in names])
        stds = [np.where(vote, s, np.inf) for s in stds]  # (a non-finite std does not vote)
        # a free decay's friction force is left out of that parameter's test: its chi-square is a comb in
        # the force (the link sticks at an offset its slip history sets), and the record's estimate alone
        # from the pooled fit lands in any tooth (seed 9898 tr004: 0 +- 0.0003 N beside 3.396 and 3.380 N
        # of the forced records; the pooled fit 3.382 N for the truth 3.383 N, z -1.9: not named)
        silent = [[c and n.startswith("friction.") for n in names] for c in comb]
        a = records_agree(vals, stds, names, AGREE_FLOOR, scale, AGREE_P, silent)
        out = {"records": rows, **({"comb": [r["record"] for r, c in zip(rows, comb) if c]} if any(comb) else {})}
        if a is None:
            return {**out, "p_value": None, "agree": True}
        return {**a, **out}

    def _std_widening(self, v: TView, m: ndarray, theta: ndarray) -> ndarray:
        """Per parameter of a fit of record v alone: how much its variance exceeds the one
        ``(J^T J)^-1`` states, which assumes white noise; the force's noise drives the simulation and
        reaches the residual correlated in time and across channels (the sandwich covariance with the
        Welch spectra of the chi-square's spread, :func:`param_variance_factor`; its Jacobian by
        forward differences, one simulation per parameter). At least 1; 1 for a free decay."""
        white, y_w = self.noise_parts.get(v.name, (None, None))
        if white is None or y_w is None:
            return np.ones(theta.size)
        effects = self.effects
        mdl0 = apply(self.p_nom, effects, theta)
        e0 = None if isinstance(mdl0, str) else residual(v, mdl0, m)
        if e0 is None:
            return np.ones(theta.size)
        scale = np.array([s for e in effects for s in self.sc[e]], float)
        J = np.zeros((int(m.sum()), int(v.has.sum()), theta.size))
        for j in range(theta.size):
            for sgn in (1.0, -1.0):
                h = sgn * 1e-3 * max(abs(float(theta[j])), float(scale[j]))
                th = theta.copy()
                th[j] += h
                mdl = apply(self.p_nom, effects, th)
                e1 = None if isinstance(mdl, str) else residual(v, mdl, m)
                if e1 is not None:
                    J[:, :, j] = ((e1 - e0) / h)[m][:, v.has]
                    break
        return np.maximum(param_variance_factor(J, white, y_w), 1.0)

    def _nominal_chi2(self) -> list[float]:
        """Each record's chi-square under the nominal on its fit samples (a decay's start state fitted):
        the decays' start states by one Gauss-Newton step (their residual is linear in it when the
        nominal is linear), checked by simulating there; the nominal's full fit when that does not
        give the linear prediction (a nonlinear nominal) or the step fails."""
        views, allm = self.views, self.masks
        dec = [i for i, v in enumerate(views) if v.free_decay]
        if dec:
            f = fit(views, self.p_nom, (), allm, None, self.sc, linearise=True)
            mdl = apply(self.p_nom, (), np.zeros(0))
            if f.ok and f.lin and not isinstance(mdl, str):
                r, J, offs = f.lin
                out = [float(np.sum(r[int(offs[i]) : int(offs[i + 1])] ** 2)) for i in range(len(views))]
                for k, i in enumerate(dec):
                    v, rows = views[i], slice(int(offs[i]), int(offs[i + 1]))
                    B = J[rows, 4 * k : 4 * k + 4]
                    dz = -np.linalg.lstsq(B, r[rows], rcond=None)[0]
                    pred = float(np.sum((r[rows] + B @ dz) ** 2))
                    z = f.z0[v.name].copy()
                    z[:4] += 1e-3 * dz
                    phi, v.phi = v.phi, None
                    try:
                        e = residual(v, mdl, allm[i], z)
                    finally:
                        v.phi = phi
                    c = None if e is None else float(np.sum(e[:, v.has][allm[i]] ** 2))
                    if c is None or abs(c - pred) > 1e-6 * pred + 1e-3:
                        break
                    out[i] = c
                else:
                    return out
        nom = fit(views, self.p_nom, (), allm, None, self.sc)
        self.cut |= nom.cut
        return [chi2_of([v], [e], [m])[0] for v, e, m in zip(views, nom.resid, allm)]

    def by_record(self) -> list[dict[str, Any]]:
        """Each record predicted from the others (its start state fitted on itself)."""
        if len(self.views) < 2 or self._stop():
            return []
        effects, allm = self.effects, self.masks
        c_nom = self._nominal_chi2()
        out = []
        lin = self._linear()
        for i, v in enumerate(self.views):
            got = None if lin is None else lin.solve([j for j in range(len(self.views)) if j != i])
            if got is None and self._stop():
                break
            if got is not None:
                theta = got[0]
            else:
                others = [u for j, u in enumerate(self.views) if j != i]
                om = [m for j, m in enumerate(allm) if j != i]
                f = fit(others, self.p_nom, effects, om, None, self.sc, **self.warm)
                self.cut |= f.cut
                if not f.ok or f.cut:
                    continue
                self.refitted.append(f"all but {v.name}")
                theta = f.theta
            mdl = apply(self.p_nom, effects, theta)
            if isinstance(mdl, str):
                continue

            z_saved = v.z0.copy()
            for _ in range(2):  # the held-out record's start state under the fitted model (not a parameter)
                start_update(v, mdl, allm[i])
            e = residual(v, mdl, allm[i])
            v.z0 = z_saved
            if e is None:
                continue
            c1, n1 = chi2_of([v], [e], [allm[i]])
            c0 = c_nom[i]
            out.append(
                {
                    "record": v.name,
                    "chi2_before": c0,
                    "chi2_after": c1,
                    "dof": n1,
                    "gap_closed": closed(c0, c1, n1),
                    "full_fit": got is None,  #: the others' parameters by the full fit (not converged linearised)
                }
            )
        return out


@dataclass
class _Rec:
    """One record linearised at a point: its stacked whitened residual, the parameters' columns of its
    Jacobian (scaled), a decay's own four start-state columns (None: a forced record, its start state
    projected out) and its start state."""

    r: ndarray
    A: ndarray
    B: ndarray | None
    z: ndarray

    def reduce(self, x: ndarray) -> ndarray:
        """A^T P x: P projects off the record's own start-state columns (a decay's)."""
        if self.B is None:
            return np.asarray(self.A.T @ x)
        w = np.linalg.lstsq(self.B, x, rcond=None)[0]
        return np.asarray(self.A.T @ (x - self.B @ w))


class _Lin:
    """The linearised fits of sets of records at ``final`` (:class:`HeldOut`)."""

    def __init__(self, h: HeldOut, f: TFit) -> None:
        from .transient_effects import BOUNDS

        self.h = h
        self.u0 = h.final.theta / h.scale
        eff = h.effects
        bounds = [BOUNDS.get(f"{e}.{n}", (-np.inf, np.inf)) for e in eff for n in TEFFECTS[e][0]]
        self.lb = np.array([b[0] for b in bounds]) / h.scale
        self.ub = np.array([b[1] for b in bounds]) / h.scale
        self.recs = self._records(list(range(len(h.views))), f)

    def _records(self, S: list[int], f: TFit) -> dict[int, _Rec]:
        """The records S (in the order of f's views) from a linearised fit f."""
        h = self.h
        r, J, offs = f.lin
        npar = h.scale.size
        dec = [i for i in S if h.views[i].free_decay]
        out = {}
        for k, i in enumerate(S):
            rows = slice(int(offs[k]), int(offs[k + 1]))
            B = None
            if i in dec:
                c = npar + 4 * dec.index(i)
                B = np.ascontiguousarray(J[rows, c : c + 4])
            out[i] = _Rec(r[rows], np.ascontiguousarray(J[rows, :npar]), B, f.z0[h.views[i].name].copy())
        return out

    def _fresh(self, S: list[int], u: ndarray, recs: dict[int, _Rec]) -> dict[int, _Rec] | None:
        """The records S linearised afresh at u (their decays' start states as in recs)."""
        h = self.h
        f = fit(
            [h.views[j] for j in S],
            h.p_nom,
            h.effects,
            [h.masks[j] for j in S],
            None,
            h.sc,
            starts=[u],
            z_start={h.views[j].name: recs[j].z for j in S if recs[j].B is not None},
            linearise=True,
        )
        return self._records(S, f) if f.ok and f.lin else None

    def widening(self, i: int, A: ndarray) -> ndarray:
        """Record i's sandwich factor per parameter (:meth:`HeldOut._std_widening`) from its Jacobian A."""
        h = self.h
        v, m = h.views[i], h.masks[i]
        white, y_w = h.noise_parts.get(v.name, (None, None))
        if white is None or y_w is None:
            return np.ones(h.scale.size)
        J = A.reshape(int(m.sum()), int(v.has.sum()), h.scale.size)
        return np.maximum(param_variance_factor(J, white, y_w), 1.0)

    def _resid(self, t: tuple[int, ndarray, ndarray]) -> ndarray | None:
        """Record i's stacked whitened residual at the scaled parameters u from start state z (a decay's
        fitted, not projected, as in the fit); t = (i, u, z)."""
        i, u, z = t
        h = self.h
        v, m = h.views[i], h.masks[i]
        mdl = apply(h.p_nom, h.effects, u * h.scale)
        if isinstance(mdl, str):
            return None
        phi = v.phi
        if v.free_decay:
            v.phi = None
        try:
            e = residual(v, mdl, m, z)
        finally:
            v.phi = phi
        return None if e is None else e[:, v.has][m].ravel()

    def solve(self, S: list[int]) -> tuple[ndarray, ndarray, dict[int, ndarray]] | None:
        """The fit of the records S: (parameters, std, SI; each record's parameter columns at the
        end), by Gauss-Newton steps from ``final`` (chord steps: the Jacobians kept; once a check
        does not converge, the Jacobians of S afresh); None when it does not converge (then the
        full fit)."""
        from .transient_fit import pmap

        h = self.h
        u = self.u0.copy()
        recs = {j: self.recs[j] for j in S}
        fresh = 0
        for k in range(MAX_CHORD + 1):
            try:
                Ni = np.linalg.inv(sum(recs[j].reduce(recs[j].A) for j in S))
            except np.linalg.LinAlgError:
                return None
            sd = np.sqrt(np.clip(np.diag(Ni), 0, None))
            if not np.all(sd > 0):
                return None
            new = np.clip(u - Ni @ sum(recs[j].reduce(recs[j].r) for j in S), self.lb, self.ub)
            if k > 0 and np.all(np.abs(new - u) <= STEP_TOL * sd):
                return new * h.scale, sd * h.scale, {j: recs[j].A for j in S}
            if k == MAX_CHORD:
                return None
            for j in S:  # a decay's start state follows: its least-squares move given the parameters' step
                rec = recs[j]
                if rec.B is not None:
                    w = np.linalg.lstsq(rec.B, rec.r + rec.A @ (new - u), rcond=None)[0]
                    rec = recs[j] = _Rec(rec.r, rec.A, rec.B, rec.z.copy())
                    rec.z[:4] -= 1e-3 * w
            u = new
            if k > 0 and fresh < MAX_FRESH:  # the kept Jacobians did not converge: afresh at u
                got = self._fresh(S, u, recs)
                if got is None:
                    return None
                recs, fresh = got, fresh + 1
                continue
            rs = pmap(self._resid, [(j, u, recs[j].z) for j in S], [h.views[j].n_out for j in S])
            for j, x in zip(S, rs):
                if x is None:
                    return None
                recs[j] = _Rec(x, recs[j].A, recs[j].B, recs[j].z)
        return None
