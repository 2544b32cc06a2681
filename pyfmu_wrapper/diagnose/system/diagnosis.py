"""One verdict for a system-level dataset from all its evidence: time records and FRC records.

Evidence. Every chi-square is in units of the measured noise: the whitened equation errors of the
time records, held out record by record (each predicted with the parameters fitted on the others,
summed over all folds), plus the FRC points (all held out when predicted with the time-record
parameters; or, for an effect the time records do not pin down, the effect's parameter fitted on
two thirds of the FRC frequencies and predicted on the third, in three folds -- so one informative
record cannot veto an effect the FRC supports, and an effect visible only in the FRC can be named).

Decision (the gates are in :mod:`gates`, each tested on its own):

1. ``noise_gate`` on the nominal's held-out chi-square (time records + FRC).
2. Greedy, at most two effects: ``evidence_gate`` (held-out BIC), ``plausibility``, and for a
   second effect ``relevance_gate`` and ``pair_gate``.
3. ``share_gate``: the named effects must close at least MIN_SHARE of the held-out gap; otherwise
   none is named as a cause and the best is offered as a hint.
4. ``remaining_gate``: a gap left after the named effects (or with none named) that is still
   structural makes the verdict ``unexplained``, with where it lives (:mod:`verdict`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from ...solvers.monolithic import SolverError
from .. import gates, progress
from ..acquisition import unobservable
from ..gates import (
    evidence_gate,
    noise_gate,
    pair_gate,
    plausibility,
    relevance_gate,
    remaining_gate,
    share_gate,
)
from . import outcome
from .agreement import record_agreement
from .effects import EQ_EFFECTS, FRC_PRIOR, LABELS, MAX_EFFECTS, TMD_EFFECTS, UNITS
from .eqfit import fit_eq, folds_for
from .model import EFFECT_PARAMS, SIGN, SystemModel, record_views, steady_signature
from .play import EPS_LADDER, PlayFit
from .playfit import PlayMixin

if TYPE_CHECKING:
    from typing import Any

    from ..data import Dataset
    from .eqfit import EqFit
    from .frc import FRCDiagnosis


@dataclass
class Cand:
    """An effect set with its time-record fit and its FRC chi-square."""

    effects: tuple
    fit: Any
    chi_t: float  #: held-out chi-square of the time records
    chi_f: float  #: FRC chi-square (0 without FRC records)
    params: dict
    std: dict
    frc_source: str = ""  #: "" (no FRC), "time" (time-record parameters), "frc" (fitted on the FRC, 3 folds), "none"
    why: list = field(default_factory=list)

    @property
    def chi(self) -> float:
        return self.chi_t + self.chi_f


class SystemDiagnosis(PlayMixin):
    def __init__(self, ds: Dataset, frc: FRCDiagnosis | None = None) -> None:
        self.ds, self.frc = ds, frc
        self.views, self.flagged = record_views(ds)
        self.log: list[tuple[Any, ...]] = []

    def run(self) -> SystemDiagnosis:
        v = self.views
        self.model = m = SystemModel(self.ds, v)
        self.folds = folds_for(v)
        self.train_ids = sorted({i for tr, _ in self.folds for i in tr})
        self.test_ids = sorted({i for _, te in self.folds for i in te})
        self.dof_t = sum(v[i].r.size for i in self.test_ids)
        self.chi0_t = sum(float(v[i].r @ v[i].r) for i in self.test_ids)
        self.nf = int(self.frc.x.size) if self.frc is not None else 0
        self.chi0_f = self.frc.chi2(self.frc.pred0) if self.frc is not None else 0.0
        self.dof = self.dof_t + self.nf
        self.chi0 = self.chi0_t + self.chi0_f
        self.n = self.dof
        self.motion = {
            "x": max(float(np.abs(w.grid["x"] - w.X[0].real).max()) for w in v),
            "y": max(float(np.abs(w.grid["y"] - w.Y[0].real).max()) for w in v),
            "d": max(float(np.abs(w.grid["x"] - w.grid["y"] - (w.X[0] - w.Y[0]).real).max()) for w in v),
        }
        # play: the rattle gate, then the gap through the solver
        self.play = PlayFit(m.base, m.tmd, v)
        self.play_ok = False
        base: tuple[str, ...] = ()
        self.play_nominal = False  #: the nominal's own play gap confirmed by the rattle (then part of the model)
        if self.play.indicated:
            try:
                self.play.fit(self.train_ids, self.folds)
                if self.play.eps <= EPS_LADDER[0] * (1 + 1e-9):  # the nominal's chain rattles as much
                    self.log.append(
                        (
                            "rejected",
                            ("play",),
                            [f"the records rattle no more than the nominal's link with a gap of {EPS_LADDER[0]:g} m"],
                        )
                    )
                    self.play_fail = True
                else:
                    self._refine_play()
                    self._play_of_nominal()
            except (SolverError, ValueError, FloatingPointError) as err:
                self.log.append(("rejected", ("play",), [f"the play model could not be simulated: {err}"]))
                self.play_fail = True
        if self.play.indicated and not getattr(self, "play_fail", False) and not self.play_nominal:
            eqp = fit_eq(m, ("play",), self.folds)
            params = dict(eqp.params, **{"play.play_gap": self.play.eps})
            std = dict(eqp.std, **{"play.play_gap": self.play.std})
            why = plausibility(params, std, m.tmd, self.motion, m.base)
            if why:
                self.log.append(("rejected", ("play",), why))
            else:
                self.play_ok = True
                base = ("play",)
        self.noise_ok = noise_gate(self.chi0, self.dof)
        self.unobservable = unobservable(v)  # acceleration-only records: no DC, no sensor offset
        self.effects = tuple(e for e in EQ_EFFECTS if e not in self.unobservable)
        self.frc_ev: dict[tuple[str, ...], Any] = {}
        self.cands: dict[tuple[str, ...], Any] = {}
        start = self._cand(base) if base else Cand((), None, self.chi0_t, self.chi0_f, {}, {})
        self.singles = {}
        for e in self.effects:
            f = fit_eq(m, base + (e,), self.folds)
            pr = self._frc_prior(base, e, f)
            self.singles[e] = fit_eq(m, base + (e,), self.folds, prior=pr) if pr else f
        self._refine_friction(base)
        chosen: list[str] = list(base)
        cur = start
        while len(chosen) < MAX_EFFECTS and noise_gate(cur.chi, self.dof):
            cands = []
            for e in self.effects:
                if e in chosen:
                    continue
                c = self._cand(tuple(chosen) + (e,), cur)
                cands.append((cur.chi - c.chi - len(EFFECT_PARAMS[e]) * math.log(self.n), e, c))
            cands.sort(key=lambda c: -c[0])
            pick = None
            for ev, e, c in cands:
                if not evidence_gate(cur.chi, c.chi, len(EFFECT_PARAMS[e]), self.n):
                    break
                if c.why:
                    self.log.append(("rejected", c.effects, c.why))
                    continue
                if chosen and not gates.significance_gate(c.params, c.std, e):
                    self.log.append(
                        ("not added", c.effects, [f"{e}'s parameter is within {gates.Z_SIGNIF:.0f} std of 0"])
                    )
                    continue
                small = (
                    gates.meaningful_gate(
                        e, c.params.get(f"{e}.{EFFECT_PARAMS[e][0]}", 1e300), m.base, m.tmd, self.motion["d"]
                    )
                    if chosen
                    else ""
                )
                if small:
                    self.log.append(("not added", c.effects, [f"{e}: {small}"]))
                    continue
                if chosen and not relevance_gate(*self._effect_rms(c.fit, e)):
                    er, lr = self._effect_rms(c.fit, e)
                    self.log.append(
                        (
                            "not added",
                            c.effects,
                            [
                                f"{e} changes the link force by {100 * er / lr:.2g} % of "
                                f"its rms (< {100 * gates.RELEVANCE:.2g} %)"
                            ],
                        )
                    )
                    continue
                if chosen and not pair_gate(cur.chi - self.dof, c.chi - self.dof):
                    self.log.append(
                        (
                            "not added",
                            c.effects,
                            [
                                f"{e} closes less than {100 * gates.PAIR_SHARE:.0f} % "
                                "of the held-out excess left by " + " + ".join(chosen)
                            ],
                        )
                    )
                    break
                pick = (ev, e, c)
                break
            if pick is None:
                break
            chosen.append(pick[1])
            cur = pick[2]
            src = {"frc": "; parameter from the FRC (3-fold held out)", "time": "", "": "", "none": ""}[cur.frc_source]
            self.log.append(("added", tuple(chosen), [f"held-out evidence {pick[0]:.1f}{src}"]))
        self.chosen, self.cur = chosen, cur
        if len(chosen) == 2 and chosen[0] == "play" and chosen[1] in TMD_EFFECTS:
            self._refit_play(cur)
            if self._rattle_is_the_seconds(cur):  # e.g. the spikes of dry friction's stick-slip
                base, start, chosen = (), Cand((), None, self.chi0_t, self.chi0_f, {}, {}), chosen[1:]
                cur = self._cand(tuple(chosen))
                self.chosen, self.cur = chosen, cur
        self.final = cur.fit
        # the honest part: do the named effects explain the gap, and is anything structural left?
        self.hint = None
        g0, g1 = self.gaps()
        if self.chosen and not share_gate(g0, g1):
            self.log.append(
                (
                    "not named",
                    tuple(self.chosen),
                    [
                        f"{' + '.join(self.chosen)} closes {100 * (1 - g1 / g0) if g0 > 0 else 0:.0f} % of the held-out gap "
                        f"(< {100 * gates.MIN_SHARE:.0f} %): offered as a hint, not a cause"
                    ],
                )
            )
            self.hint = (tuple(self.chosen), 1 - g1 / g0 if g0 > 0 else None)
            self.chosen, self.cur, self.final = [], start if not base else start, None
            if base:  # play passed its own rattle gate; it stays only if it alone meets the share
                self.chosen, self.final = list(base), start.fit
                g0, g1 = self.gaps()
                if not share_gate(g0, g1):
                    self.chosen, self.final, self.cur = [], None, Cand((), None, self.chi0_t, self.chi0_f, {}, {})
        if self.hint is None and not self.chosen and self.noise_ok:
            best = min(
                (self._cand((e,)) for e in self.effects if not self._cand((e,)).why), key=lambda c: c.chi, default=None
            )
            if best is not None:
                self.hint = (best.effects, 1 - max(best.chi - self.dof, 0) / g0 if g0 > 0 else None)
        g0, g1 = self.gaps()
        self.unexplained = bool(self.noise_ok and (not self.chosen or remaining_gate(self.dof + g1, self.dof, g0)))
        self.unexplained_share = (max(g1, 0.0) / g0 if g0 > 0 else 0.0) if self.noise_ok else 0.0
        # one value of the named effects' parameters for every record, or no confident cause
        self.agreement = None
        self.gap_left = self.unexplained  # a structural gap the named effects leave (before the agreement)
        if self.chosen and self.final is not None:
            self.agreement = record_agreement(m, tuple(self.chosen), self.final.theta)
            if self.agreement is not None and not self.agreement["agree"]:
                self.unexplained = True
                self.log.append(("records disagree", tuple(self.chosen), [self.agreement["worst"]["param"]]))
        from ..verdict import localise

        self.localisation = localise(self)
        return self

    def _frc_prior(self, base: tuple[str, ...], e: str, f_time: EqFit) -> dict[int, Any] | None:
        """The FRC's own fit of effect ``e`` (fitted on two thirds of its frequencies) as a prior on
        its time-record parameter, so one informative record held out is predicted from the other
        records **and** the FRC (alone, a single informative record could veto a cubic). Used only
        when it agrees with the fit on all time records (within 3 combined std)."""
        if self.frc is None or e not in FRC_PRIOR or not hasattr(self.frc, "fits"):
            return None
        f = next((f for f in self.frc.fits if f["effects"] == [e]), None)
        key = f"{e}.{EFFECT_PARAMS[e][0]}"
        if f is None or key not in f["params"]:
            return None
        v, sd = f["params"][key], f["std"].get(key, 0.0)
        if not (np.isfinite(v) and np.isfinite(sd) and sd > 0):
            return None
        vt, st = f_time.params.get(key), f_time.std.get(key, math.inf)
        if vt is None or not np.isfinite(st) or abs(vt - v) > 3 * math.hypot(st, sd):
            return None
        k = sum(len(EFFECT_PARAMS[b]) for b in base)
        return {k: (SIGN.get(e, 1.0) * v, sd)}

    def _cand(self, effects: tuple[str, ...], parent: Cand | None = None) -> Cand:
        """Fit ``effects`` on the time records; its FRC chi-square from the time-record parameters
        or, when that leaves a structural FRC gap, from the last effect's parameter fitted on the FRC."""
        effects = tuple(effects)
        if effects in self.cands:
            return self.cands[effects]
        m = self.model
        base = ("play",) if self.play_ok else ()
        if len(effects) == len(base) + 1 and effects[:-1] == base and effects[-1] in self.singles:
            f = self.singles[effects[-1]]
        else:
            f = fit_eq(m, effects, self.folds)
        progress.candidate("+".join(effects) or "nominal")
        params, std = dict(f.params), dict(f.std)
        if "play" in effects and hasattr(self.play, "eps"):
            params["play.play_gap"], std["play.play_gap"] = self.play.eps, self.play.std
        c = Cand(effects, f, f.chi2_ho, 0.0, params, std)
        c.why = plausibility(params, std, m.tmd, self.motion, m.base)
        fr = self.frc
        if fr is not None:
            parent_f = parent.chi_f if parent is not None else self.chi0_f
            chi_f = None if c.why else fr.chi2_of(params)
            c.frc_source = "time" if chi_f is not None else "none"
            e = effects[-1]
            key = f"{e}.{EFFECT_PARAMS[e][0]}"
            if not c.why and key in params and (chi_f is None or noise_gate(chi_f, self.nf)):
                fixed = {
                    k: v for k, v in params.items() if not (k.startswith(e + ".") and k != "friction.friction_slope")
                }
                try:
                    fe = fr.fit_effect(key, fixed, params[key], std.get(key), self.motion["d"])
                except (SolverError, ValueError, FloatingPointError):
                    fe = None
                st0 = std.get(key, math.inf)
                if (
                    fe is not None
                    and np.isfinite(st0)
                    and abs(fe["value"] - params[key]) > 3 * math.hypot(st0, fe["std"])
                ):
                    fe = None  # the FRC's value contradicts the time records': no FRC fit for this candidate
                if fe is not None and (chi_f is None or fe["chi2_cv"] < chi_f):
                    st, sf = std.get(key, math.inf), fe["std"]
                    wt = 1 / st**2 if np.isfinite(st) and st > 0 else 0.0
                    wf = 1 / sf**2 if sf > 0 else 0.0
                    if wt + wf > 0:
                        params[key] = (wt * params[key] + wf * fe["value"]) / (wt + wf)
                        std[key] = 1 / math.sqrt(wt + wf)
                    chi_f, c.frc_source = fe["chi2_cv"], "frc"
                    c.why = plausibility(params, std, m.tmd, self.motion, m.base)
            c.chi_f = parent_f if chi_f is None else chi_f
            self.frc_ev[effects] = None if chi_f is None else self.chi0_f - chi_f
        c.params, c.std = params, std
        self.cands[effects] = c
        return c

    def gaps(self) -> tuple[float, float]:
        """(held-out gap before, after the named effects) in chi-square units: time records + FRC +
        (with play) the rattle statistic."""
        ho = self.held_out()
        return ho["excess_before"], ho["excess_after"]

    def _effect_rms(self, f: EqFit, effect: str) -> tuple[float, float]:
        """(rms of the force the effect adds in the base equation, rms of the nominal link force) [N]."""
        m = self.model
        k = 0
        for e in f.effects:
            if e == effect:
                break
            k += len(EFFECT_PARAMS[e])
        beta = f.beta[k : k + len(EFFECT_PARAMS[effect])]
        num = den = 0.0
        for v in self.views:
            A = sum(b * col[0] for b, col in zip(beta, m.columns(effect, v, f.theta.get(effect, ()))))
            num += float(np.sum(np.abs(A[1:]) ** 2) / 2 + abs(A[0]) ** 2)
            hw = np.arange(v.X.size) * v.omega
            L = (m.tmd.stiffness + 1j * m.tmd.damping * hw - m.tmd.inertance * hw**2) * (v.X - v.Y)
            den += float(np.sum(np.abs(L[1:]) ** 2) / 2)
        return math.sqrt(num), math.sqrt(den)

    def _refine_friction(self, base: tuple[str, ...], iterations: int = 2) -> None:
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

    # --- results -------------------------------------------------------------------------------
    def params(self) -> Any:
        if not self.chosen:
            return {}, {}
        c = self._cand(tuple(self.chosen))
        return dict(c.params), dict(c.std)

    def held_out(self) -> dict[str, Any]:
        """Held-out chi-squares and gaps before and after the named effects (:func:`.outcome.held_out`)."""
        return outcome.held_out(self)

    def candidates(self) -> list[dict[str, Any]]:
        """The candidate effects with their evidence, best first (:func:`.outcome.candidates`)."""
        return outcome.candidates(self)

    def verdict_text(self) -> str:
        from ..verdict import verdict_text

        return verdict_text(self, LABELS, UNITS)
