"""Diagnosis of transient records (system level): which effect explains the data **to the noise**.

Steps (docs/diagnose-method.md, "Transient records"):

1. Views (:mod:`.transient_sim`): each record averaged to at most FIT_MAX fit samples; its start
   state estimated under the nominal (two passes); the noise std of every channel of every record
   measured from the raw samples (fourth differences: the white part). A record whose force does not
   determine its impulses (aliased power, or impulses spanning so few samples that their area is
   unknown to the response's noise: FOLD_MAX) is set aside, and the verdict says so.
2. Held out by **time segment**: every record is cut into SEGMENTS equal segments; parameters are
   fitted on the even ones and the odd ones are predicted (the simulation runs through them, their
   samples never enter the fit). The nominal, every single candidate and pairs are scored by the
   held-out chi-square ``z = (chi2 - dof) / sqrt(2 dof)``.
3. A set of effects **explains the data** when its held-out z <= EXPLAINS_Z. The nominal explaining
   it: no structural effect. Else the best single candidate that explains it is named; every other
   single that also does is listed as equally good. No single explains it: the friction single
   refitted from a large start, then pairs of each of the FIRST_TRIES best singles with up to
   PAIR_TRIES + 1 second effects (mass_split beside I or m refitted as inertance + tmd_mass); the
   second effect is needed only if the pair explains the data, closes >= PAIR_SHARE of the excess the
   first leaves, and its size is > 3 std from 0 and physically meaningful. Window fits
   (:mod:`.transient_window`) rule candidates and pairs out first; a linear first ruled out there
   takes every candidate as its second, the screened-out singles are tried on the windows when every
   kept one is ruled out, and a ruled-out single whose fit on everything explains the data is named.
4. The named set is refitted on all samples, and on each record alone: the per-record values must
   agree within their errors (:mod:`.transient_heldout`: chi-square test at AGREE_P; each record's std the sandwich one under the
   force's correlated noise); a disagreement is reported and nothing is
   named (a drift between records, or a pair of effects mimicking the truth). Held out **by record**:
   each record predicted from the others (only its start state fitted on itself).
5. Nothing explains the data sample by sample: the play band test (:mod:`.transient_play`: the
   low band, the rattle's spread in the noise, every other single under play's noise) may name
   play. Else ``unexplained``, with the best candidate as a hint and where the residual lives
   (:func:`where`).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress
from .effects import LABELS, VOCAB
from .transient_effects import BOUNDS, TEFFECTS, apply, meaningless, scales
from .transient_fit import (
    FRICTION_STEEP,
    TFit,
    chi2_of,
    cpu_deadline,
    fit,
    past_deadline,
    residual,
    start_update,
    warm_start,
    z_test,
)
from .transient_heldout import HeldOut
from .transient_screen import NONLINEAR, screen
from .transient_sim import (
    CHANNELS,
    chi2_variance_factor,
    input_noise_series,
    make_view,
    start_responses,
)
from .transient_where import SEGMENTS, where
from .transient_window import PRUNE_Z, WINDOW_SHARE, guarded, window_unusable, window_views

if TYPE_CHECKING:
    from numpy import ndarray

    from ..data import Dataset
    from .transient_effects import Model
    from .transient_sim import TView

EXPLAINS_Z = 5.0  #: held-out chi-square within this many std of its dof: explained to the noise
PAIR_TRIES = 5  #: second effects tried next to the best single
PAIR_SHARE = 0.5  #: a second effect must close at least this share of what the first leaves
ALIASED_MAX = 1e-3  #: a record's force may hold at most this share of its power above 0.8 x Nyquist
FIRST_TRIES = 3  #: first effects of a pair: this many of the best singles
#: CPU seconds of the search (issue 41: a dataset at most 120 s): past it no further candidate fit is
#: started, and the verdict says what was not tried (a fit under way runs to its end)
CPU_BUDGET = 90.0
#: CPU seconds of the whole diagnosis past which every fit under way stops at its next Jacobian with
#: the best point it reached (:func:`.transient_fit.cpu_deadline`), and what is left (the final fit, the
#: records' agreement) is cut short and said so: the reading, the report and the plots stay within 120 s
CPU_LIMIT = 105.0
#: of it, the seconds the restarts and the pair search (many, slow fits) leave to the play band test that
#: follows them (1-22 s measured)
BAND_RESERVE = 25.0
#: the friction single's second start, as a share of the measured force's std (median over records)
FRICTION_RESTART = 0.2
#: the friction force's profile on the windows (:meth:`TransientDiagnosis._window_friction_restart`): this
#: range of shares of the measured force's std, FRICTION_GRID points on a log scale
FRICTION_PROFILE = (0.005, 0.5)
FRICTION_GRID = 13
#: mass_split beside inertance or tmd_mass: the same model as these two (m and I, the nominal's own)
MASS_PAIR = ("inertance", "tmd_mass")
MASS_PAIRS = ({"mass_split", "inertance"}, {"mass_split", "tmd_mass"})
#: a record is set aside when the force's folded share (TView.fold) times a channel's rms exceeds this
#: many noise std of a fit sample. Calibrated on 4 ms hammers, 500 N, 1 % noise: at 2 kHz without a
#: filter on the load cell 0.80 std, chi2/n 3.7 in x at the truth; at 8 and 12.8 kHz 0.13 and 0.22,
#: chi2/n <= 1 (the estimate errs high at 12.8 kHz: 2.5e-4 folded against 1e-4 for a half-sine); field
#: hammer records at 0.31-4.3 std left chi2/n 1.2-2.8 in some channel at the truth
FOLD_MAX = 0.25
START_PASSES = 3  #: start-state passes under a fitted candidate before its held-out chi-square


def _label(e: str) -> str:
    return LABELS.get(e, e)


class TransientDiagnosis:
    def __init__(self, ds: Dataset) -> None:
        from ...physics.params import BaseParams, TMDParams, pack

        self.budget = CPU_BUDGET  #: CPU seconds of the search (:meth:`over`)
        self.t_cpu = time.process_time()
        self.not_tried: list[str] = []
        self.ds = ds
        self.late: dict[str, TFit] = {}  #: singles ruled out on their window, fitted on everything later
        from .transient_sim import fastest_rate

        recs = [r for r in ds.records if r.kind == "transient"]
        self.p_nom = pack(BaseParams(**ds.nominal["base"]), TMDParams(**ds.nominal["tmd"]))
        f_mode = fastest_rate(self.p_nom) / (2 * math.pi)
        views = [make_view(r, ds.acquisition, f_mode) for r in recs]
        # start of the stated rules: a force whose sampling aliased it (power up to Nyquist that no
        # declared anti-alias filter removed: a 4 ms hammer impulse at 256-500 Hz spans 1-2 samples)
        # does not determine its impulse: the record is not used, and the verdict says so
        filt = ds.acquisition.get("force") is not None and ds.acquisition["force"].type is not None
        self.skipped = [
            f"{v.name}: not used, about {100 * v.aliased:.2g} % of the force's power is aliased (its power above "
            f"0.8 x Nyquist, {'through the declared anti-alias filter at the mirror frequencies' if filt else 'no declared anti-alias filter'})"
            ": an impulse spans too few samples to know its area"
            for v in views
            if v.aliased > ALIASED_MAX
        ]
        self.views = [v for v in views if v.aliased <= ALIASED_MAX]
        # an impulse spanning a few samples: its area is known to about v.fold (the phase of the samples
        # against it); where that error of the response stands above its noise, the record is set aside
        kept = []
        for v in self.views:
            snr = _folded_snr(v)
            if snr > FOLD_MAX:
                self.skipped.append(
                    f"{v.name}: not used, the force's impulses span too few samples to know their area to the "
                    f"response's noise (about {100 * v.fold:.2g} % of the force folds onto its low band from the "
                    f"sampling rate, {snr:.2g} noise std of a fit sample)"
                )
            else:
                kept.append(v)
        self.views = kept
        kept = []
        for v in self.views:  # the direct term of an aliased force, shifted by the chains' delay difference
            snr, dd = _direct_snr(v, self.p_nom)
            if snr > FOLD_MAX:
                self.skipped.append(
                    f"{v.name}: not used, about {100 * v.aliased_excess:.2g} % of the force's power is aliased and the "
                    f"load cell's delay differs from the accelerometers' by {1e3 * abs(dd):.3g} ms: the force's "
                    f"direct term in the accelerations is unknown to {snr:.2g} noise std of a fit sample"
                )
            else:
                kept.append(v)
        self.views = kept
        if not self.views:
            self.views = views
            why = "; ".join(r.split(": not used, ", 1)[-1] for r in self.skipped)
            self.skipped = [
                f"every record would be set aside ({why}): all used, but the force does not determine "
                "its impulses; treat the verdict with care"
            ]
        self.log: list[str] = []
        self.warm: dict[tuple[str, ...], dict[str, Any]] = {}  #: effects -> start of the per-record fits
        #: record -> (white share of each recorded channel's whitened noise, whitened input-noise response)
        self.noise_parts: dict[str, tuple[ndarray, ndarray | None]] = {}
        self.nominal_resid: list[ndarray] = []

    # --- masks -----------------------------------------------------------------------------
    def _masks(self, odd: bool | None, views: list[TView] | None = None) -> list[ndarray]:
        """Per view (default: the records'): its held-out samples (odd segments), its training ones
        (even), or all (None); the chain's start-up never."""
        out = []
        for v in self.views if views is None else views:
            seg = np.minimum((np.arange(v.n_out) * SEGMENTS) // v.n_out, SEGMENTS - 1)
            m = np.ones(v.n_out, bool) if odd is None else (seg % 2 == (1 if odd else 0))
            m[: v.skip] = False
            out.append(m)
        return out

    def prepare(self) -> None:
        """Start states under the nominal, and the noise of every channel of every fit sample: the
        sensor's own (raw noise / sqrt(q)) and the response of the nominal to the force channel's
        noise, which drives the simulation (errors in the input: :func:`input_noise_series`; its correlation in time widens the
        chi-square's spread: :func:`chi2_variance_factor`)."""
        allm = self._masks(None)
        nom = apply(self.p_nom, (), np.zeros(0))
        assert not isinstance(nom, str)
        for v, m in zip(self.views, allm):
            v.phi = start_responses(v, self.p_nom)
            for _ in range(2):
                start_update(v, nom, m)
            y_in = input_noise_series(v, self.p_nom)
            s_in = np.zeros(4) if y_in is None else np.std(y_in, axis=0)
            white = np.array([v.raw_noise[c] / math.sqrt(v.q) if v.has[k] else 1.0 for k, c in enumerate(CHANNELS)])
            v.sigma = np.where(v.has, np.hypot(white, s_in), 1.0)
            v.chi2_var = chi2_variance_factor(white[v.has], None if y_in is None else y_in[:, v.has])
            self.noise_parts[v.name] = (
                white[v.has] / v.sigma[v.has],
                None if y_in is None else y_in[:, v.has] / v.sigma[v.has],
            )
        xs = [np.nanstd(v.meas[:, 0]) for v in self.views if v.has[0]]
        self.xscale = float(np.mean(xs)) if xs else 1e-3
        strokes = [np.nanstd(v.meas[:, 0] - v.meas[:, 1]) * 2 for v in self.views if v.has[0] and v.has[1]]
        self.stroke = float(np.mean(strokes)) if strokes else self.xscale
        self.sc = scales(self.p_nom, self.stroke, self.xscale)

    def candidates(self) -> list[str]:
        disp = any(v.has[0] or v.has[1] for v in self.views)
        out = [e for e in TEFFECTS if e != "sensor_offset" or disp]
        if all(v.free_decay for v in self.views):
            out.remove("force_error")  # no force: nothing to scale
        return out

    def _fit(
        self,
        effects: tuple[str, ...],
        train: list[ndarray],
        test: list[ndarray] | None,
        init: ndarray | None = None,
        starts: list[ndarray] | None = None,
        views: list[TView] | None = None,
        z_start: dict[str, ndarray] | None = None,
    ) -> TFit:
        """Fit ``effects``; ``init``: a start (SI, every parameter) to begin from instead of the default
        (a fit with play ignores it: its three gaps); ``starts``: the starts (SI) to begin from, all
        effects alike; ``views``: the records' windows instead of the records (:mod:`.transient_window`);
        ``z_start``: the free decays' start states to begin from (a window fit's). A fit on all
        samples (``test`` None) with no start given begins from the same effects' best held-out fit
        on the records (lowest training chi-square), when there is one."""
        scale = np.array([s for e in effects for s in self.sc[e]], float)
        us = None
        if starts is not None:
            us = [np.asarray(u, float) / scale for u in starts]
        elif init is not None and "play" not in effects:
            us = [init / scale]
        elif "play" in effects:
            k = list(effects).index("play")
            us = []
            for g in (0.1, 1.0, 10.0):  # gap 1e-5, 1e-4, 1e-3 m
                u = np.zeros(sum(len(TEFFECTS[e][0]) for e in effects))
                u[sum(len(TEFFECTS[e][0]) for e in effects[:k])] = g
                us.append(u)
        vs = self.views if views is None else views
        held = getattr(self, "held_fits", {}).get(effects)
        if views is None and test is None and us is None and held is not None:
            # a fit on all samples (the named set's final fit) from its held-out fit: a few steps from
            # near its optimum instead of the whole way from the default start (friction: 14 -> 3)
            us, z_start = [held.theta / scale], held.z0
        f = fit(vs, self.p_nom, effects, train, test, self.sc, starts=us, z_start=z_start)
        progress.candidate("+".join(effects) or "nominal")
        if views is None and test is not None and effects and f.ok:  # the best held-out fit of these effects
            self.held_fits: dict[tuple[str, ...], TFit] = getattr(self, "held_fits", {})
            old = self.held_fits.get(effects)
            if old is None or f.chi2["train"] < old.chi2["train"]:
                self.held_fits[effects] = f
        return self._polish(f, train, test, vs) if effects and test is not None else f

    def _polish(self, f: TFit, train: list[ndarray], test: list[ndarray], views: list[TView] | None = None) -> TFit:
        """The held-out chi-squares of a fitted candidate with each forced record's start state
        converged under the candidate's own model: START_PASSES more passes of :func:`start_update` on
        the training samples (the fit makes one; its projection uses the nominal's start responses, so
        one pass leaves the start transient of a changed model partly unfitted: fresh tr000, base
        stiffness +3 %, kept 82 % of its excess in the first 7.5 s of a random record, z 17). Free
        decays keep the fit's own residual (their start state is a fitted unknown). The parameters are
        not refitted. ``views``: the records' windows instead of the records."""
        if not f.ok:
            return f
        mdl = apply(self.p_nom, f.effects, f.theta)
        if isinstance(mdl, str):
            return f
        vs = self.views if views is None else views
        resid = list(f.resid)
        for i, v in enumerate(vs):
            if v.free_decay or v.phi is None:
                continue
            saved = v.z0.copy()
            try:
                for _ in range(START_PASSES):
                    start_update(v, mdl, train[i])
                e = residual(v, mdl, train[i])
            finally:
                v.z0 = saved
            if e is not None:
                resid[i] = e
        c_tr, n_tr = chi2_of(vs, resid, train)
        c_te, n_te = chi2_of(vs, resid, test)
        if c_tr >= f.chi2["train"]:
            return f  # no better start found: the fit's own
        g = TFit(f.effects, f.theta, f.std, ok=True, reason=f.reason, resid=resid, z0=f.z0)
        g.chi2 = {**f.chi2, "train": c_tr, "dof_train": n_tr, "test": c_te, "dof_test": n_te}
        return g

    # --- the decision ------------------------------------------------------------------------
    def over(self, what: str, reserve: float = 0.0) -> bool:
        """Whether the search is past its CPU budget (:data:`CPU_BUDGET`) less ``reserve`` seconds kept for
        what comes after; ``what`` is then listed as not tried."""
        if time.process_time() - self.t_cpu <= self.budget - reserve:
            return False
        self.not_tried.append(what)
        return True

    def _budget_notes(self) -> list[str]:
        if not self.not_tried:
            return []
        pairs = [w for w in self.not_tried if w.startswith("the pair ")]
        rest = [w for w in self.not_tried if not w.startswith("the pair ")]
        said = rest + ([f"{len(pairs)} pair{'s' if len(pairs) > 1 else ''} (verdict.not_tried)"] if pairs else [])
        return [f"The search stopped at its CPU budget ({self.budget:g} s): not tried: {', '.join(said)}."]

    def run(self) -> dict[str, Any]:
        self.t_cpu = time.process_time()
        self.not_tried = []
        with cpu_deadline(self.t_cpu + self.budget + CPU_LIMIT - CPU_BUDGET):
            return self._run()

    def _run(self) -> dict[str, Any]:
        self.prepare()
        tr, te = self._masks(False), self._masks(True)
        nom = self._fit((), tr, te)
        self.nominal_resid = nom.resid
        z0 = z_test(nom)
        ex0 = nom.chi2["test"] - nom.chi2["dof_test"]
        res: dict[str, Any] = {"nominal": {"z": z0, **nom.chi2}, "candidates": []}
        if z0 <= EXPLAINS_Z:
            return self._result(res, nom, None, [], "none")
        singles = []
        keep, screened = screen(self, self.candidates(), tr)
        for e, red in screened.items():
            res["candidates"].append(
                {"effects": [e], "ok": False, "reason": f"screened out: linearised train chi-square drop {red:.4g}"}
            )
        self._window_setup(res)
        ruled: dict[str, TFit] = {}  #: singles ruled out on their window fit -> that fit

        def single(e: str, note: str | None = None) -> None:
            t0 = time.perf_counter()
            w = self._window_fit((e,))
            if e == "friction" and w is not None and z_test(w) > PRUNE_Z:
                w = self._window_friction_restart(w)
            if w is not None and z_test(w) > PRUNE_Z:
                ruled[e] = w
                res["candidates"].append({**self._ruled_row(w, t0), **({"restart": note} if note else {})})
                return
            f = self._fit((e,), tr, te, **self._warm(w))
            row = self._row(f, ex0)
            if w is not None:
                row["window_z"] = z_test(w)
            if note:
                row["restart"] = note
            row["seconds"] = round(time.perf_counter() - t0, 2)
            res["candidates"].append(row)
            if f.ok:
                singles.append(f)

        for e in keep:
            if not self.over(f"the single {e}"):
                single(e)
        if not singles and ruled and screened:
            # every kept single ruled out on its window: the screen's one linear step from the nominal
            # may not see a cause far from it (a resonance moved past its bandwidth); the screened-out
            # ones are fitted on the windows too (linear: cheap)
            for e in screened:
                if not self.over(f"the single {e}"):
                    single(e, "screened out, fitted on the windows: every kept single was ruled out there")
        singles.sort(key=lambda f: f.chi2["test"])
        passing = [f for f in singles if z_test(f) <= EXPLAINS_Z]
        if not passing:  # before pairs: friction from a large start (its default start's local minimum)
            singles = [
                self._friction_restart(g, tr, te, res, ex0)
                if g.effects == ("friction",) and not self.over("friction from a large start", BAND_RESERVE)
                else g
                for g in singles
            ]
            singles.sort(key=lambda f: f.chi2["test"])
            # the best singles refitted from their own values: the fit's start-state pass then runs under
            # a model near the optimum (fresh tr000, base stiffness: z 9.5 from the default start, its
            # pairs with a null second effect -0.9); kept when the training chi-square drops
            for i, g in enumerate(singles[:FIRST_TRIES]):
                if "play" in g.effects:
                    continue  # its fit has its own three starts
                if self.over(f"{' + '.join(g.effects)} refitted from its own values", BAND_RESERVE):
                    break
                h = self._fit(g.effects, tr, te, init=g.theta)
                if h.ok and h.chi2["train"] < g.chi2["train"]:
                    row = self._row(h, ex0)
                    row["restart"] = "refitted from its own fitted values"
                    res["candidates"].append(row)
                    singles[i] = h
            singles.sort(key=lambda f: f.chi2["test"])
            passing = [f for f in singles if z_test(f) <= EXPLAINS_Z]
        if passing:
            return self._result(res, nom, passing[0], passing[1:], "single")
        self.late.clear()
        pairs = self._pairs(singles, res, ex0, tr, te, ruled)
        best = singles[0] if singles else None
        if best is None and ruled:  # the hint: the single closest on the windows, fitted on everything
            w = min(ruled.values(), key=lambda w: w.chi2["test"])
            hint = self.late.get(w.effects[0])
            if hint is None:  # not fitted on everything by the pair search
                hint = self.late[w.effects[0]] = self._fit(w.effects, tr, te, **self._warm(w))
                if hint.ok:
                    row = self._row(hint, ex0)
                    row["restart"] = "fitted on everything as the hint (the closest single on the windows)"
                    res["candidates"].append(row)
            if hint.ok:
                best = hint
        # a single ruled out on its window (its window fit can stop in a local minimum) whose fit on
        # everything explains the data is named as a single: a second effect is never needed beside it
        late = sorted((f for f in self.late.values() if f.ok and z_test(f) <= EXPLAINS_Z), key=lambda f: f.chi2["test"])
        if late:
            return self._result(res, nom, late[0], late[1:], "single")
        if pairs:
            return self._result(res, nom, pairs[0], pairs[1:], "pair")
        # nothing explains the records sample by sample: play's rattle is not followed so, its low band is
        # (:mod:`.transient_play`: every candidate scored there, the rattle's spread in the noise)
        from .transient_play import play_test

        fitted = {e: self._default_theta(e) for e in self.candidates()}
        fitted.update({f.effects[0]: f.theta for f in [*singles, *self.late.values()] if f.ok and len(f.effects) == 1})
        fitted.update({e: f.theta for (e, *rest), f in getattr(self, "held_fits", {}).items() if not rest})
        if self.over("play on its band"):
            return self._result(res, nom, best, [], "unexplained")
        res["play_band"] = play_test(self, fitted)
        if res["play_band"]["named"]:
            return self._result_play(res, nom, self.held_fits.get(("play",)) if hasattr(self, "held_fits") else None)
        return self._result(res, nom, best, [], "unexplained")

    def _result_play(self, res: dict[str, Any], nom: TFit, held: TFit | None) -> dict[str, Any]:
        """The verdict when play is named by the band test (:mod:`.transient_play`): its gap, the band's
        chi-squares; the held-out sample-by-sample test left it unexplained (the rattle), and the verdict
        says so."""
        pb = res["play_band"]
        gap, std = pb["play"]["gap"], pb["play"]["std"]
        unit = TEFFECTS["play"][1][0]
        params = {"play.play_gap": {"value": float(gap), "std": float(std), "unit": unit}}
        ref = held if held is not None and held.ok else nom  # sample by sample: what the play single leaves
        res["held_out"] = {
            "by_segment": _by_segment(nom, ref),
            "by_record": [],
            "level": (
                f"named on the band below {pb['band_hz']:.3g} Hz (the gear's rattle is not followed sample by "
                "sample: docs/diagnose-method.md, play from its band)"
            ),
        }
        res["agreement"] = {}
        res["where"] = where(self.views, nom.resid)
        o = pb["others"][pb["best_other"]]
        text = (
            f"Gap attributed to {_label('play')} (play.play_gap = {gap:.4g} +- {std:.2g} {unit}), on the band "
            f"below {pb['band_hz']:.3g} Hz where a model of play predicts the motion: its band chi2/dof "
            f"{pb['play']['red']:.3g} with the rattle's spread in the noise, against {o['chi2'] / o['dof']:.3g} for "
            f"the best other candidate ({_label(pb['best_other'])}) and {pb['nominal']['chi2'] / pb['nominal']['dof']:.3g} "
            "for the nominal. The gear's rattle itself (its contact's 60-700 Hz content) is not followed sample by "
            "sample: no candidate explains the records to their noise there."
        )
        ab = pb.get("above_band") or {}
        if ab.get("separates"):
            zs = [z for z in ab["rivals"].values() if z is not None]
            text += (
                f" The band alone does not separate play from {_label(pb['best_other'])} (under play's noise both "
                f"explain it); above the band, where each model is scored under its own noise, every such candidate "
                f"leaves the rattle (z >= {min(zs):.3g}) that play's spread makes (z {ab['play_z']:.3g})."
            )
        notes = [*self.skipped, *self._budget_notes()]
        res["verdict"] = {
            "structural": True,
            "effects": ["play"],
            "labels": [_label("play")],
            "elements": [VOCAB["play"].element],
            "parameters": params,
            "alternatives": [],
            "unexplained": False,
            "unexplained_share": pb["play"]["chi2"] / max(pb["nominal"]["chi2"], 1e-300),
            "hint": None,
            "notes": notes,
            "text": text + (" " + " ".join(notes) if notes else ""),
            "not_tried": list(self.not_tried),
        }
        res.update(self._record_rows())
        return res

    def _record_rows(self) -> dict[str, Any]:
        """``noise`` (each record's noise std per channel) and ``records`` (its fit rate, averaging,
        skipped start, free decay) of the result."""
        return {
            "noise": [
                {"record": v.name, "noise_std": {c: float(s) for c, s, h in zip(CHANNELS, v.sigma, v.has) if h}}
                for v in self.views
            ],
            "records": [
                {
                    "record": v.name,
                    "fit_rate_hz": v.fs,
                    "averaged": v.q,
                    "skipped_start_s": v.skip / v.fs,
                    "free_decay": v.free_decay,
                }
                for v in self.views
            ],
        }

    # --- the window fits (:mod:`.transient_window`) ------------------------------------------------
    def _window_setup(self, res: dict[str, Any]) -> None:
        """The records' windows, when they can rule a candidate out: each long enough, and the nominal
        not explaining them to PRUNE_Z (else a candidate's window z says nothing)."""
        self.win: tuple[list[TView], list[ndarray], list[ndarray]] | None = None
        why = window_unusable(self.views, self.p_nom)
        zw = None
        if why is None:
            wv = window_views(self.views)
            wtr, wte = guarded(self._masks(False, wv)), guarded(self._masks(True, wv))
            wn = self._fit((), wtr, wte, views=wv)
            zw = z_test(wn) if wn.ok else None
            if zw is not None and zw > PRUNE_Z:
                self.win = (wv, wtr, wte)
            else:
                why = f"the nominal explains the records' windows to PRUNE_Z (z {zw})"
        res["window"] = {
            "share": WINDOW_SHARE,
            "prune_z": PRUNE_Z,
            "nominal_z": zw,
            "used": self.win is not None,
            "not_used": why,
        }

    def _window_fit(
        self, effects: tuple[str, ...], init: ndarray | None = None, starts: list[ndarray] | None = None
    ) -> TFit | None:
        """``effects`` fitted on the records' windows (None: no window in use, or the fit failed)."""
        win = getattr(self, "win", None)
        if win is None:
            return None
        wv, wtr, wte = win
        f = self._fit(effects, wtr, wte, init=init, starts=starts, views=wv)
        return f if f.ok else None

    def _window_friction_restart(self, w: TFit) -> TFit:
        """The friction single's window fit again from the best point of a **profile** of the friction
        force (FRICTION_PROFILE: a log grid of FRICTION_GRID forces, shares of the measured force's std,
        median over the forced records; the slope at its default; each record from rest or from its
        start state as held, the better: two simulations of each window a point): the window's
        chi-square in df has several local minima (stick-slip switches at other instants), and the
        default start's fit stops in one (seed 9696 tr019: 1 N ->
        5.99 N, z 389; from 2 x the truth 184 N, z 544; from the truth 4.04 N, z 17). From the profile's
        best force the fit starts twice, as the default's does: at the default slope and at a steep one
        (FRICTION_STEEP: a link that sticks; tr019's fit from the default slope stopped at 800 s/m and
        z 47 on the whole records, the pair with a steep slope reached z 3). The fit of lower training
        chi-square."""
        sf = [float(np.std(v.force)) for v in self.views if not v.free_decay]
        win = getattr(self, "win", None)
        if not sf or win is None:
            return w
        wv, wtr, _ = win
        slope = self._default_theta("friction")[1]
        grid = float(np.median(sf)) * np.geomspace(*FRICTION_PROFILE, FRICTION_GRID)
        best, best_c = None, w.chi2["train"]
        for df in grid:
            mdl = apply(self.p_nom, ("friction",), np.array([df, slope]))
            if isinstance(mdl, str):
                continue
            c = 0.0
            for v, m in zip(wv, wtr):  # each record from rest or its start state as held, the better
                c += min(self._window_chi2(v, mdl, m, z) for z in (None, np.zeros_like(v.z0)))
            if c < best_c:
                best, best_c = df, c
        if best is None:  # no point of the profile below the fit's own training chi-square
            return w
        g = self._window_fit(("friction",), starts=[np.array([best, slope]), np.array([best, FRICTION_STEEP])])
        return g if g is not None and g.chi2["train"] < w.chi2["train"] else w

    @staticmethod
    def _window_chi2(v: TView, mdl: Model, m: ndarray, z0: ndarray | None) -> float:
        """Training chi-square of one window under ``mdl`` from the start state z0 (None: the view's)."""
        e = residual(v, mdl, m, z0)
        return math.inf if e is None else float(np.sum(e[:, v.has][m] ** 2))

    @staticmethod
    def _warm(w: TFit | None) -> dict[str, Any]:
        """A full fit's start from a window fit: its parameters and its free decays' start states."""
        return {} if w is None else {"starts": [w.theta], "z_start": w.z0}

    @staticmethod
    def _ruled_row(w: TFit, t0: float | None = None) -> dict[str, Any]:
        import time

        z = z_test(w)
        row: dict[str, Any] = {
            "effects": list(w.effects),
            "ok": False,
            "reason": f"ruled out on a window fit (z {z:.4g} > {PRUNE_Z:g}): cannot explain the data",
            "window_z": z,
        }
        if t0 is not None:
            row["seconds"] = round(time.perf_counter() - t0, 2)
        return row

    def _pairs(
        self,
        singles: list[TFit],
        res: dict[str, Any],
        ex0: float,
        tr: list[ndarray],
        te: list[ndarray],
        ruled: dict[str, TFit] | None = None,
    ) -> list[TFit]:
        """Pairs that explain the data, best first. First effects: the FIRST_TRIES best singles (by
        held-out chi-square; the best alone missed pairs whose best single is a third effect: field
        base_mass + friction got base_damping first; the friction single was refitted from a large
        start before, :meth:`_friction_restart`), then the singles ruled out on their window fit (by
        their window chi-square; ``ruled``). Second effects: see :meth:`_seconds`. A pair that holds mass_split beside
        inertance or tmd_mass is the model of inertance + tmd_mass: it is refitted in those, the
        nominal's own parameters, and judged there (its size test too). Every pair is first fitted on
        the windows: ruled out there, it is not fitted on everything (nor is a ruled-out first). A first
        ruled out on its window takes every candidate as a second (:meth:`_every_second`) if it is linear."""
        pairs: list[TFit] = []
        seen: set[frozenset[str]] = set()
        ruled = ruled or {}
        order = [*singles, *sorted(ruled.values(), key=lambda w: w.chi2["test"])]
        firsts = order[:FIRST_TRIES]
        alone = {g.effects[0]: g.theta for g in order}
        full = {g.effects[0]: g for g in singles}
        for first0 in firsts:
            e1 = first0.effects[0]
            first = full.get(e1)  # None: ruled out alone; fitted on everything once a pair with it passes its window
            # a first ruled out on its window leaves a gap the second-effect screen, linearised around
            # it, reads poorly: a linear first takes every candidate as its second, each ruled out or
            # kept by its window fit (cheap); a nonlinear one (its pairs' window fits cost far more)
            # keeps the screen's
            ruled_linear = first is None and e1 not in NONLINEAR
            seconds = self._every_second(e1) if ruled_linear else self._seconds(first or first0, order, tr)
            for second in seconds:
                key = frozenset((e1, second))
                if key in seen:
                    continue
                if self.over(f"the pair {e1} + {second}", BAND_RESERVE):
                    continue
                seen.add(key)
                # started from the first's fitted parameters and the second's own fit (else its default
                # start): from the defaults a pair with friction stopped in a local minimum (field tr042,
                # friction + tmd_stiffness left z 12539; from the singles' values z -0.9)
                th2 = alone.get(second)
                if th2 is None:
                    th2 = self._default_theta(second)
                init = np.concatenate([(first or first0).theta, th2])
                w = self._window_fit((e1, second), init=init)
                if w is not None and z_test(w) > PRUNE_Z:
                    res["candidates"].append(self._ruled_row(w))
                    if set(w.effects) in MASS_PAIRS:
                        seen.add(frozenset(MASS_PAIR))  # the same model: ruled out too
                    continue
                if first is None:
                    first = full[e1] = self.late[e1] = self._fit((e1,), tr, te, **self._warm(first0))
                    row = self._row(first, ex0)
                    row["restart"] = "fitted on everything: a pair with it passed the window fit"
                    res["candidates"].append(row)
                if not first.ok:
                    break
                if e1 in self.late and z_test(first) <= EXPLAINS_Z:
                    return []  # it explains the data alone (:meth:`run` names it): no pair is needed
                ex1 = first.chi2["test"] - first.chi2["dof_test"]
                f = self._fit((e1, second), tr, te, **(self._warm(w) if w is not None else {"init": init}))
                if f.ok and set(f.effects) in MASS_PAIRS:
                    f = self._as_mass_pair(f, tr, te)
                    seen.add(frozenset(f.effects))
                row = self._row(f, ex0)
                if w is not None:
                    row["window_z"] = z_test(w)
                res["candidates"].append(row)
                if not f.ok:
                    continue
                if self._second_needed(f, first, ex1, row):
                    pairs.append(f)
        pairs.sort(key=lambda f: f.chi2["test"])
        return pairs

    def _default_theta(self, e: str) -> ndarray:
        """An effect's default start (SI): its scale where it is bounded below, else 0."""
        return np.array(
            [
                self.sc[e][j] if np.isfinite(BOUNDS.get(f"{e}.{n}", (-np.inf,))[0]) else 0.0
                for j, n in enumerate(TEFFECTS[e][0])
            ]
        )

    def _seconds(self, first: TFit, singles: list[TFit], tr: list[ndarray]) -> list[str]:
        """Second effects beside ``first``: the nonlinear singles and the linear candidates whose
        Gauss-Newton step from the first's fitted model lowers the chi-square most (a screened-out
        single may be what the first leaves)."""
        nl = [g.effects[0] for g in singles if g.effects[0] in NONLINEAR and g.effects != first.effects]
        lin, _ = screen(self, [e for e in self.candidates() if e not in NONLINEAR], tr, (first.effects, first.theta))
        return (nl + lin[: max(PAIR_TRIES - len(nl), 2)])[: PAIR_TRIES + 1]

    def _every_second(self, e1: str) -> list[str]:
        """Every candidate beside ``e1`` as its second effect (a first ruled out on its window)."""
        return [e for e in self.candidates() if e != e1]

    def _second_needed(self, f: TFit, first: TFit, ex1: float, row: dict[str, Any]) -> bool:
        """The issue's rule for a second effect: the pair explains the data, its second effect closes
        >= PAIR_SHARE of what the first leaves, and its size is > 3 std from 0 (:func:`_significant`) and
        physically meaningful (:func:`meaningless`; for a pair refitted in the nominal's parameters,
        both effects are judged)."""
        ex2 = f.chi2["test"] - f.chi2["dof_test"]
        signif, i = True, 0
        for k, e in enumerate(f.effects):
            n = len(TEFFECTS[e][0])
            th, sd = f.theta[i : i + n], f.std[i : i + n]
            i += n
            if e == first.effects[0] and k == 0:
                continue  # the first effect's own size was judged as a single
            if not _significant(e, th, sd):
                signif = False
            small = meaningless(e, th, self.p_nom, self.stroke)
            if small:
                row["second_not_meaningful"] = small
                signif = False
        closes = 1 - ex2 / ex1 if ex1 > 0 else 0.0
        row.update(second_closes=closes, second_significant=signif)
        return z_test(f) <= EXPLAINS_Z and closes >= PAIR_SHARE and signif

    def _as_mass_pair(self, f: TFit, tr: list[ndarray], te: list[ndarray]) -> TFit:
        """mass_split (I + s, m - s) beside inertance (I + a) or tmd_mass (m + b) is the model of
        inertance + tmd_mass (I + s + a, m - s + b): refitted in those, from the converted values."""
        v = dict(zip(f.effects, f.theta))
        s = float(v.get("mass_split", 0.0))
        th = np.array([s + float(v.get("inertance", 0.0)), -s + float(v.get("tmd_mass", 0.0))])
        g = self._fit(MASS_PAIR, tr, te, init=th)
        return g if g.ok else f

    def _friction_restart(
        self, first: TFit, tr: list[ndarray], te: list[ndarray], res: dict[str, Any], ex0: float
    ) -> TFit:
        """The friction single refitted from a start at FRICTION_RESTART of the force's std (the
        default start, 1 N, stopped at 1.5 N on a 12.9 N truth whose TMD sticks most of the time):
        the better of the two fits."""
        sf = [float(np.std(v.force)) for v in self.views if not v.free_decay]
        if not sf:
            return first
        th = np.array([FRICTION_RESTART * float(np.median(sf)), first.theta[1]])
        if th[0] <= 2 * first.theta[0]:
            return first
        g = self._fit(("friction",), tr, te, init=th)
        row = self._row(g, ex0)
        row["restart"] = "friction from a large start"
        res["candidates"].append(row)
        return g if g.ok and g.chi2["test"] < first.chi2["test"] else first

    def _row(self, f: TFit, ex0: float) -> dict[str, Any]:
        row: dict[str, Any] = {"effects": list(f.effects), "ok": f.ok, "reason": f.reason}
        if f.ok:
            ex = f.chi2["test"] - f.chi2["dof_test"]
            row.update(
                z=z_test(f),
                gap_closed=1 - ex / ex0 if ex0 > 0 else None,
                params=self._params(f),
            )
        return row

    def _params(self, f: TFit) -> dict[str, dict[str, Any]]:
        out, i = {}, 0
        for e in f.effects:
            names, units = TEFFECTS[e]
            for n, u in zip(names, units):
                out[f"{e}.{n}"] = {"value": float(f.theta[i]), "std": float(f.std[i]), "unit": u}
                i += 1
        return out

    def _result(self, res: dict[str, Any], nom: TFit, best: TFit | None, alts: list[TFit], how: str) -> dict[str, Any]:
        named: tuple[str, ...] = () if how in ("none", "unexplained") or best is None else best.effects
        notes: list[str] = [*self.skipped, *self._budget_notes()]
        final = None
        agree: dict[str, Any] = {}
        held = None
        if named:
            final = None if past_deadline() else self._fit(named, self._masks(None), None)
            if (final is None or final.cut) and best is not None:
                notes.append(
                    "the fit on all samples stopped at the CPU budget: the parameters are the held-out stage's fit "
                    "(on half the samples)"
                )
                final = best
            assert final is not None
            self.warm[named] = warm_start(final, self.sc)
            held = HeldOut(
                self.views, self.p_nom, self.sc, named, self._masks(None), final, self.warm[named], self.noise_parts
            )
            agree = held.agreement()
            if agree.get("not_tested"):
                notes.append(f"the records' agreement on the parameters was {agree['not_tested']}")
            if not agree["agree"]:
                notes.append(
                    f"the records disagree on the parameters of {' + '.join(named)} (p = {agree['p_value']:.2g}): "
                    "a parameter that drifts between records, or effects that only mimic the truth; not named"
                )
                named, how = (), "disagree"
        n_ex = nom.chi2["test"] - nom.chi2["dof_test"]
        ref = best if best is not None else nom
        ex = ref.chi2["test"] - ref.chi2["dof_test"]
        res["held_out"] = {
            "by_segment": _by_segment(nom, ref),
            "by_record": held.by_record() if named and held is not None else [],
            "level": f"explained when the held-out z <= {EXPLAINS_Z:g}",
        }
        res["agreement"] = agree
        res["where"] = where(self.views, (best if how in ("unexplained", "disagree") and best else nom).resid)
        unexplained = how in ("unexplained", "disagree")
        params = self._params(final) if (final is not None and named) else {}
        alternatives = [list(a.effects) for a in alts]
        text = _text(named, params, res, alternatives, unexplained, best, notes)
        if (self.skipped or self.not_tried) and not unexplained:
            text += " " + " ".join([*self.skipped, *self._budget_notes()])
        res["verdict"] = {
            "structural": how != "none",
            "effects": list(named),
            "labels": [_label(e) for e in named],
            "elements": [VOCAB[e].element for e in named],
            "parameters": params,
            "alternatives": alternatives,
            "unexplained": unexplained,
            "unexplained_share": (
                0.0 if how == "none" else (1.0 if not named else max(ex, 0) / n_ex if n_ex > 0 else 0.0)
            ),
            "hint": None if (named or best is None) else {"effects": list(best.effects), **self._row(best, n_ex)},
            "notes": notes,
            "text": text,
            "not_tried": list(self.not_tried),
        }
        res.update(self._record_rows())
        return res


def _by_segment(nom: TFit, ref: TFit) -> dict[str, Any]:
    """The held-out segments' chi-square before (the nominal) and after (``ref``), their z and the share
    of the nominal's excess over the dof that ``ref`` closes."""
    n_ex = nom.chi2["test"] - nom.chi2["dof_test"]
    return {
        "chi2_before": nom.chi2["test"],
        "chi2_after": ref.chi2["test"],
        "dof": nom.chi2["dof_test"],
        "z_before": z_test(nom),
        "z_after": z_test(ref),
        "gap_closed": 1 - (ref.chi2["test"] - ref.chi2["dof_test"]) / n_ex if n_ex > 0 else None,
    }


def _folded_snr(v: TView) -> float:
    """The force's folded share (``v.fold``) times each recorded channel's rms over the noise std of a
    fit sample: the largest, in noise std (how far the impulses' unknown area moves the response)."""
    if v.fold <= 0:
        return 0.0
    out = 0.0
    for k, c in enumerate(CHANNELS):
        if v.has[k] and v.raw_noise.get(c, 0.0) > 0:
            rms = float(np.nanstd(v.meas[:, k]))
            out = max(out, v.fold * rms / (v.raw_noise[c] / math.sqrt(v.q)))
    return out


def _direct_snr(v: TView, p: ndarray) -> tuple[float, float]:
    """(the error of the force's direct term in the accelerations in noise std of a fit sample, the
    delay difference [s]) for a record whose force and accelerometer chains hold the same filter (or
    none) but different delays. The direct term is the measured force shifted by the delay difference
    d (:func:`.transient_sim.direct_force`); an aliased component (true frequency fs - f, seen at f)
    gets the shift of f, so its error is |e^{-i w d} - e^{i (ws - w) d}| = 2 |sin(pi fs d)| of its
    amplitude, whatever f: the error's power is 4 sin^2(pi fs d) x the aliased share of the force's
    transient content (``v.aliased_excess``: impulses; the load cell's stationary noise floor is not
    aliased force, and shifted it is still the noise the chi-square holds) x the direct term's power. Measured on a 256 Hz hammer record behind a 76 Hz Butterworth with a
    0.74 ms load-cell delay: predicted excess chi2/n 0.97 in xdd and 0.14 in ydd at the truth, found
    0.89 and 0.14 (residuals alternating +-40 std around each hit). 0 for a free decay, for no delay
    difference and for different filters."""
    from .transient_sim import direct_force, feedthrough, same_filter

    cf = v.chains.get("force")
    if v.free_decay or v.aliased_excess <= 0:
        return 0.0, 0.0
    out, dd_out = 0.0, 0.0
    direct: ndarray | None = None
    for k, gain in zip((2, 3), feedthrough(p)):
        c = v.chains.get(CHANNELS[k])
        if not v.has[k] or not same_filter(c, cf):
            continue
        dd = (c.delay_s if c is not None else 0.0) - (cf.delay_s if cf is not None else 0.0)
        if dd == 0.0:
            continue
        direct = direct_force(v) if direct is None else direct
        rms = math.sqrt(float(np.mean((gain * direct[:, k - 2]) ** 2)))
        snr = (
            2
            * abs(math.sin(math.pi * dd / v.dt))
            * math.sqrt(v.aliased_excess)
            * rms
            / (v.raw_noise[CHANNELS[k]] / math.sqrt(v.q))
        )
        if snr > out:
            out, dd_out = snr, dd
    return out, dd_out


def _significant(effect: str, theta: ndarray, std: ndarray) -> bool:
    """An effect's size is > 3 std from 0: its first parameter (a friction's force, not the slope of
    its regularisation); a sensor offset's x or y offset (one sensor off is an offset: field tr035,
    cubic + an x offset of -1.18 mm, closed 100 % at z -0.4 and was refused because its y offset was 0)."""
    if effect == "sensor_offset":
        return bool(np.any(np.abs(theta) > 3 * std))
    return bool(abs(theta[0]) > 3 * std[0])


def _text(
    named: tuple[str, ...],
    params: dict[str, Any],
    res: dict[str, Any],
    alts: list[list[str]],
    unexplained: bool,
    best: TFit | None,
    notes: list[str],
) -> str:
    h = res["held_out"]["by_segment"]
    if not named and not unexplained:
        return (
            f"No structural effect: the nominal model explains the transient records to the noise "
            f"(held-out z = {h['z_before']:.1f} <= {EXPLAINS_Z:g})."
        )
    w = res["where"]["text"]
    if unexplained:
        hint = ""
        if best is not None:
            hint = (
                f" The closest candidate, {' + '.join(_label(e) for e in best.effects)}, closes "
                f"{100 * (h['gap_closed'] or 0):.0f} % and leaves z = {h['z_after']:.0f}: a hint, not a cause."
            )
        return f"A structural gap remains that no candidate explains to the noise; it lives in {w}.{hint}" + (
            " " + " ".join(notes) if notes else ""
        )
    ps = "; ".join(f"{k} = {v['value']:.4g} +- {v['std']:.2g} {v['unit']}" for k, v in params.items())
    alt = ""
    if alts:
        alt = " Equally good (also explain the data to the noise): " + "; ".join(" + ".join(a) for a in alts) + "."
    return (
        f"Gap attributed to {' + '.join(_label(e) for e in named)} ({ps}); it explains the held-out "
        f"segments to the noise (z {h['z_before']:.0f} -> {h['z_after']:.1f}, closes "
        f"{100 * (h['gap_closed'] or 0):.1f} %). The nominal's gap lived in {w}.{alt}"
    )
