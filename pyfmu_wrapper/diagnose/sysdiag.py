"""One verdict for a system-level dataset from all its evidence: time records and FRC records.

Decision (every gate is a separate function, tested on its own):

1. ``noise_gate``: the nominal model's held-out chi-square (whitened by the noise measured in every
   record and channel) exceeds its degrees of freedom by more than Z_NOISE standard deviations;
   otherwise the gap is noise. The play candidate has its own gate (the rattle statistic,
   :mod:`play`).
2. ``evidence_gate``: an effect is added (greedy, at most two) when it lowers the held-out
   chi-square by more than EVIDENCE + p ln(n) (a held-out BIC), with the FRC records' chi-square
   change (the FRC predicted with the parameters fitted on the time records) added to the evidence;
   a second effect must also close PAIR_SHARE of the excess the first one leaves (``pair_gate``),
   and the residual the first leaves must still be above the noise.
3. ``plausibility``: a fit with an unphysical parameter (I < 0, m < 0, negative total damping or
   friction beyond 2 std, a softening spring that goes negative over the measured stroke, a gain
   1 + a <= 0, an offset or gap larger than the motion) is rejected with its reason.
"""
from __future__ import annotations

import math

import numpy as np

from ..solvers.monolithic import SolverError
from .play import PlayFit
from dataclasses import replace

from .acquisition import unobservable
from .system import EFFECT_PARAMS, SystemModel, fit_eq, folds_for, record_views, steady_signature

Z_NOISE = 5.0
EVIDENCE = 10.0
PAIR_SHARE = 0.25
MAX_EFFECTS = 2
RELEVANCE = 1e-3  #: a second effect must change the link force by more than this share of its rms
LABELS = {
    "friction": "dry friction in the TMD link", "play": "play in the inerter gear",
    "viscous": "extra viscous damping", "mass_split": "different split of m and I (m + I fixed)",
    "cubic": "cubic term in the TMD spring", "force_error": "forcing-amplitude error",
    "sensor_offset": "displacement-sensor offset",
}
UNITS = {"friction_force": "N", "friction_slope": "s/m", "play_gap": "m", "delta_inertance_eff": "kg", "signature_scale": "1",
         "delta_damping": "N s/m", "delta_inertance": "kg", "cubic_stiffness": "N/m^3",
         "force_gain_error": "1", "x_offset": "m", "y_offset": "m"}
EQ_EFFECTS = ("friction", "viscous", "mass_split", "cubic", "force_error", "sensor_offset")


def noise_gate(chi2, dof, z=Z_NOISE):
    """True when chi2 exceeds what noise alone gives (dof) by more than z standard deviations."""
    return (chi2 - dof) / math.sqrt(2.0 * max(dof, 1)) > z


def evidence_gate(chi2_before, chi2_after, n_new_params, n, threshold=None):
    """True when the held-out chi-square drops by more than threshold (EVIDENCE) + p ln(n)."""
    threshold = EVIDENCE if threshold is None else threshold
    return chi2_before - chi2_after - n_new_params * math.log(max(n, 2)) > threshold


def pair_gate(excess_single, excess_pair, share=PAIR_SHARE):
    """True when the second effect closes at least ``share`` of the excess the first one leaves."""
    return excess_single > 0 and (excess_single - excess_pair) >= share * excess_single


def relevance_gate(effect_rms, link_rms, share=RELEVANCE):
    """True when a second effect changes the link force by more than ``share`` of its rms (an
    effect far below what any rig could act on is not proposed, however significant)."""
    return effect_rms > share * link_rms


def plausibility(params: dict, std: dict, tmd, motion: dict) -> list:
    """Reasons why a fitted parameter set is unphysical (empty list: plausible)."""
    out = []
    g = lambda k: params.get(k)
    s = lambda k: 2.0 * std.get(k, 0.0) if np.isfinite(std.get(k, 0.0)) else 0.0
    if g("friction.friction_force") is not None and g("friction.friction_force") < -s("friction.friction_force"):
        out.append(f"negative friction force df = {g('friction.friction_force'):.3g} N")
    if g("viscous.delta_damping") is not None and tmd.damping + g("viscous.delta_damping") < -s("viscous.delta_damping"):
        out.append(f"negative total damping c = {tmd.damping + g('viscous.delta_damping'):.3g} N s/m")
    dI = g("mass_split.delta_inertance")
    if dI is not None:
        if tmd.inertance + dI < -s("mass_split.delta_inertance"):
            out.append(f"I < 0 (I = {tmd.inertance + dI:.3g} kg)")
        if tmd.mass - dI < -s("mass_split.delta_inertance"):
            out.append(f"m < 0 (m = {tmd.mass - dI:.3g} kg)")
    k3 = g("cubic.cubic_stiffness")
    if k3 is not None and tmd.stiffness + 3 * (k3 + s("cubic.cubic_stiffness")) * motion["d"] ** 2 < 0:
        out.append(f"spring stiffness k + 3 k3 d^2 < 0 over the measured stroke |x - y| <= {motion['d']:.3g} m")
    a = g("force_error.force_gain_error")
    if a is not None and 1 + a <= 0:
        out.append(f"force gain 1 + a = {1 + a:.3g} <= 0")
    for k, m in (("sensor_offset.x_offset", "x"), ("sensor_offset.y_offset", "y")):
        if g(k) is not None and abs(g(k)) - s(k) > motion[m]:
            out.append(f"{k.split('.')[1]} = {g(k):.3g} m larger than the motion ({motion[m]:.3g} m)")
    eps = g("play.play_gap")
    if eps is not None and eps > motion["d"]:
        out.append(f"gap {eps:.3g} m larger than the relative motion ({motion['d']:.3g} m)")
    sc = g("play.signature_scale")
    if sc is not None and sc <= 0:
        out.append(f"the simulated rattle signature enters with scale {sc:.3g} <= 0")
    dIe = g("play.delta_inertance_eff")
    if dIe is not None and tmd.inertance + dIe < -s("play.delta_inertance_eff"):
        out.append(f"effective inertance < 0 ({tmd.inertance + dIe:.3g} kg)")
    return out


class SystemDiagnosis:
    def __init__(self, ds, frc=None):
        self.ds, self.frc = ds, frc
        self.views, self.flagged = record_views(ds)
        self.log = []

    def run(self):
        v = self.views
        self.model = m = SystemModel(self.ds, v)
        self.folds = folds_for(v)
        self.train_ids = sorted({i for tr, _ in self.folds for i in tr})
        self.test_ids = sorted({i for _, te in self.folds for i in te})
        self.dof = sum(v[i].r.size for i in self.test_ids)
        self.n = self.dof
        self.chi0 = sum(float(v[i].r @ v[i].r) for i in self.test_ids)
        self.motion = {"x": max(float(np.abs(w.grid["x"] - w.X[0].real).max()) for w in v),
                       "y": max(float(np.abs(w.grid["y"] - w.Y[0].real).max()) for w in v),
                       "d": max(float(np.abs(w.grid["x"] - w.grid["y"] - (w.X[0] - w.Y[0]).real).max()) for w in v)}
        # play: the rattle gate, then the gap through the solver
        self.play = PlayFit(m.base, m.tmd, v)
        self.play_ok = False
        base = ()
        if self.play.indicated:
            try:
                self.play.fit(self.train_ids, self.folds)
                self._refine_play()
            except (SolverError, ValueError, FloatingPointError) as err:
                self.log.append(("rejected", ("play",), [f"the play model could not be simulated: {err}"]))
                self.play_fail = True
        if self.play.indicated and not getattr(self, "play_fail", False):
            eqp = fit_eq(m, ("play",), self.folds)
            params = dict(eqp.params, **{"play.play_gap": self.play.eps})
            std = dict(eqp.std, **{"play.play_gap": self.play.std})
            why = plausibility(params, std, m.tmd, self.motion)
            if why:
                self.log.append(("rejected", ("play",), why))
            else:
                self.play_ok = True
                base = ("play",)
        self.noise_ok = noise_gate(self.chi0, self.dof)
        cur = fit_eq(m, base, self.folds) if base else None
        chi_cur = cur.chi2_ho if cur else self.chi0
        self.unobservable = unobservable(v)  # acceleration-only records: no DC, no sensor offset
        self.effects = tuple(e for e in EQ_EFFECTS if e not in self.unobservable)
        self.singles = {e: fit_eq(m, base + (e,), self.folds) for e in self.effects}
        self._refine_friction(base)
        self.frc_ev = {}
        chosen = list(base)
        while len(chosen) < MAX_EFFECTS and noise_gate(chi_cur, self.dof):
            cands = []
            for e in self.effects:
                if e in chosen:
                    continue
                f = self.singles[e] if len(chosen) == len(base) else fit_eq(m, tuple(chosen) + (e,), self.folds)
                ev = chi_cur - f.chi2_ho - len(EFFECT_PARAMS[e]) * math.log(self.n)
                cands.append((ev, e, f))
            cands.sort(key=lambda c: -c[0])
            if self.frc is not None:  # FRC evidence for the leading time-record candidates
                top = []
                for ev, e, f in cands[:3]:
                    fe = None
                    if not plausibility(f.params, f.std, m.tmd, self.motion):
                        fe = self._frc_evidence(f)
                    top.append((ev + (fe or 0.0), e, f))
                cands = sorted(top + cands[3:], key=lambda c: -c[0])
            pick = None
            for ev, e, f in cands:
                extra = ev - (chi_cur - f.chi2_ho - len(EFFECT_PARAMS[e]) * math.log(self.n))  # FRC evidence
                if not evidence_gate(chi_cur + extra, f.chi2_ho, len(EFFECT_PARAMS[e]), self.n):
                    break
                why = plausibility(f.params, f.std, m.tmd, self.motion)
                if why:
                    self.log.append(("rejected", f.effects, why))
                    continue
                if chosen and not relevance_gate(*self._effect_rms(f, e)):
                    er, lr = self._effect_rms(f, e)
                    self.log.append(("not added", f.effects, [f"{e} changes the link force by {100 * er / lr:.2g} % of "
                                                              f"its rms (< {100 * RELEVANCE:.2g} %)"]))
                    continue
                if chosen and not pair_gate(chi_cur - self.dof, f.chi2_ho - self.dof):
                    self.log.append(("not added", f.effects, [f"{e} closes less than {100 * PAIR_SHARE:.0f} % "
                                                              "of the held-out excess left by " + ' + '.join(chosen)]))
                    break
                pick = (ev, e, f)
                break
            if pick is None:
                break
            chosen.append(pick[1])
            cur, chi_cur = pick[2], pick[2].chi2_ho
            self.log.append(("added", tuple(chosen), [f"held-out evidence {pick[0]:.1f}"]))
        self.chosen, self.final = chosen, cur
        return self

    def _refine_play(self, factor=1.25):
        """The rattle statistic fixes the gap to ~10-25 %; the periodic part of the chain force is
        more sensitive to it: compare the equation error of the simulated signature at eps / factor,
        eps, eps * factor (training chi-square) and keep the vertex of the parabola in log eps."""
        m, pf = self.model, self.play
        e0 = pf.eps
        grid = [e0 / factor, e0, e0 * factor]
        sigs, chi = {}, []
        for e in grid:
            m.play_signature = sigs[e] = pf.signature(m, e)
            chi.append(fit_eq(m, ("play",), self.folds).chi2_fit)
        x = np.log(grid)
        c = np.polyfit(x, chi, 2)
        best = grid[int(np.argmin(chi))]
        if c[0] > 0:
            xv = -c[1] / (2 * c[0])
            if x[0] <= xv <= x[-1]:
                best = float(np.exp(xv))
        if best not in sigs:
            sigs[best] = pf.signature(m, best)
        pf.eps = best
        m.play_signature = sigs[best]

    def _effect_rms(self, f, effect):
        """(rms of the force the effect adds in the base equation, rms of the nominal link force) [N]."""
        m = self.model
        k = 0
        for e in f.effects:
            if e == effect:
                break
            k += len(EFFECT_PARAMS[e])
        beta = f.beta[k:k + len(EFFECT_PARAMS[effect])]
        num = den = 0.0
        for v in self.views:
            A = sum(b * col[0] for b, col in zip(beta, m.columns(effect, v, f.theta.get(effect, ()))))
            num += float(np.sum(np.abs(A[1:]) ** 2) / 2 + abs(A[0]) ** 2)
            hw = np.arange(v.X.size) * v.omega
            L = (m.tmd.stiffness + 1j * m.tmd.damping * hw - m.tmd.inertance * hw ** 2) * (v.X - v.Y)
            den += float(np.sum(np.abs(L[1:]) ** 2) / 2)
        return math.sqrt(num), math.sqrt(den)

    def _refine_friction(self, base, iterations=2):
        """When dry friction is a leading candidate, replace its regressor (the kernels' friction law
        along the measured, smoothed relative velocity) by the friction force along the steady state
        simulated with the fitted df (the solver resolves the stick phases), per newton; refit."""
        m = self.model
        ranked = sorted(self.singles, key=lambda e: self.singles[e].chi2_ho)
        f = self.singles["friction"]
        df = f.params.get("friction.friction_force", 0.0)
        if "friction" not in ranked[:2] or not df > 0:
            return
        slope = m.tmd.friction_slope
        for _ in range(iterations):
            tmd = replace(m.tmd, friction_force=df)
            m.friction_signature = {}
            try:
                for v in self.views:
                    A, B = steady_signature(m, v, tmd)
                    m.friction_signature[v.name] = (A / df, B / df)
            except (SolverError, ValueError, FloatingPointError) as err:
                m.friction_signature = {}
                self.log.append(("note", ("friction",), [f"no refinement through the solver: {err}"]))
                return
            g = fit_eq(m, base + ("friction",), self.folds, {"friction": (slope,)})
            new = g.params["friction.friction_force"]
            if not new > 0:
                m.friction_signature = {}
                return
            converged = abs(new - df) <= 0.01 * df
            df = new
            if converged:
                break
        self.singles["friction"] = g

    def _frc_evidence(self, f):
        key = f.effects
        if key not in self.frc_ev:
            self.frc_ev[key] = self.frc.evidence(f.params)
        return self.frc_ev[key]

    # --- results -------------------------------------------------------------------------------
    def params(self):
        if not self.chosen:
            return {}, {}
        p, s = dict(self.final.params), dict(self.final.std)
        if "play" in self.chosen:
            p["play.play_gap"], s["play.play_gap"] = self.play.eps, self.play.std
        return p, s

    def held_out(self):
        dof = self.dof
        chi1 = self.final.chi2_ho if self.final else self.chi0
        g0, g1 = max(self.chi0 - dof, 0.0), max(chi1 - dof, 0.0)
        sp0 = sp1 = 0.0
        if self.play_ok:
            sd = [max(s, 1e-300) for s in self._spike_sd()]
            for h in self.play.ho:
                i = [w.name for w in self.views].index(h["record"])
                sp0 += (h["S_measured"] / sd[i]) ** 2
                sp1 += ((h["S_measured"] - h["S_predicted"]) / sd[i]) ** 2
        G0, G1 = g0 + sp0, g1 + sp1
        per = []
        for i in self.test_ids:
            c0 = float(self.views[i].r @ self.views[i].r)
            c1 = self.final.chi2_ho_rec[i] if self.final else c0
            n = self.views[i].r.size
            per.append({"record": self.views[i].name, "omega": self.views[i].omega, "dof": n,
                        "chi2_before": c0, "chi2_after": c1,
                        "gap_closed": (1 - max(c1 - n, 0) / (c0 - n)) if c0 > n else None})
        return {"chi2_before": self.chi0, "chi2_after": chi1, "dof": dof,
                "rattle_chi2_before": sp0, "rattle_chi2_after": sp1,
                "excess_before": G0, "excess_after": G1,
                "gap_closed": (1 - G1 / G0) if (self.chosen and G0 > 0) else None,
                "rms_before_noise_units": math.sqrt(self.chi0 / dof), "rms_after_noise_units": math.sqrt(chi1 / dof),
                "per_record": per}

    def _spike_sd(self):
        out = []
        for w in self.views:
            ex, ey = w.series.resid.get("xdd"), w.series.resid.get("ydd")
            out.append(self.model.base.mass * self.model.tmd.mass * float(np.std(ex) * np.std(ey)) / math.sqrt(ex.size))
        return out

    def candidates(self):
        rows = []
        base = ("play",) if self.play_ok else ()
        chi_b = fit_eq(self.model, base, self.folds).chi2_ho if base else self.chi0
        for e, f in self.singles.items():
            why = plausibility(f.params, f.std, self.model.tmd, self.motion)
            rows.append({"effects": list(f.effects), "params": f.params, "std": f.std, "chi2_held_out": f.chi2_ho,
                         "evidence": chi_b - f.chi2_ho - len(EFFECT_PARAMS[e]) * math.log(self.n),
                         "frc_evidence": self.frc_ev.get(f.effects),
                         "gap_closed": (1 - max(f.chi2_ho - self.dof, 0) / (self.chi0 - self.dof)) if self.chi0 > self.dof else None,
                         "rejected": why})
        rows.sort(key=lambda r: -r["evidence"])
        return rows

    def verdict_text(self):
        p, s = self.params()
        if not self.chosen:
            why = ("the held-out gap is within the measured noise (chi2 {:.0f} for {} dof)".format(self.chi0, self.dof)
                   if not self.noise_ok else "no candidate passes the evidence and plausibility gates")
            return f"No structural effect: {why}."
        parts = []
        for e in self.chosen:
            ps = ", ".join(f"{k.split('.', 1)[1]} = {v:.4g} +- {s.get(k, float('nan')):.2g} {UNITS.get(k.split('.', 1)[1], '')}"
                           for k, v in p.items() if k.startswith(e + ".") and not k.endswith("friction_slope")
                           and not k.endswith("delta_inertance_eff") and not k.endswith("signature_scale") and not (k.endswith("y_offset") and abs(v) < 2 * s.get(k, 0)))
            parts.append(f"{LABELS[e]} ({ps})")
        gc = self.held_out()["gap_closed"]
        return ("Gap attributed to " + " + ".join(parts)
                + (f"; closes {100 * gc:.0f} % of the held-out gap." if gc is not None else "."))
