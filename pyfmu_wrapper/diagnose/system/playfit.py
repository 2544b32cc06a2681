"""Play in a system diagnosis: the gap refined on the periodic evidence and refitted next to a
second effect (methods of :class:`sysdiag.SystemDiagnosis`, kept apart by job)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...solvers.monolithic import SolverError
from .effects import VOCAB
from .eqfit import fit_eq
from .play import PlayFit

REFINE = 1.25  #: the periodic evidence refines the rattle's gap within / and x this factor


class PlayMixin:
    # what the mixin reads of the diagnosis it is mixed into (SystemDiagnosis)
    model: Any
    play: Any
    folds: Any
    views: Any
    train_ids: Any
    test_ids: Any
    log: Any
    chi0_t: Any
    chi0_f: Any
    chi0: Any
    play_nominal: Any
    _play_chi: Any
    _play_raw: Any
    play_ok: Any
    cands: Any
    singles: Any
    _refine_friction: Any

    def _refit_play(self, c: Any) -> None:
        """Play + a second effect in the TMD link: the rattle curves S(eps) were simulated with the
        nominal link; extra damping (or stiffness, friction, ...) changes the rattle, so the gap is
        fitted again on curves simulated with the second effect's fitted parameters."""
        second = c.effects[1]
        try:
            new = VOCAB.changed(
                {"base": self.model.base, "tmd": self.model.tmd},
                {k: v for k, v in c.params.items() if k.split(".", 1)[0] == second},
            )
            pf = PlayFit(new["base"], new["tmd"], self.views)
            pf.fit(self.train_ids, self.folds)
        except (SolverError, ValueError, FloatingPointError, KeyError) as err:
            self.log.append(("note", c.effects, [f"play not refitted with {second}: {err}"]))
            return
        self._take_play(c, pf)

    def _rattle_is_the_seconds(self, c: Any) -> bool:
        """After :meth:`_refit_play`: a gap at the bottom of the ladder (EPS_LADDER[0]) means the rattle
        curves simulated with the second effect alone (and a gap too small to rattle) already carry the
        records' rattle statistic -- the spikes are the second effect's (dry friction's stick-slip is
        anti-correlated in xdd and ydd as contact is). Then play is dropped: not a candidate, its rattle
        terms not part of the gap, the second effect refitted without it. Returns whether it was."""
        from .play import EPS_LADDER

        if not c.params.get("play.play_gap", 1.0) <= EPS_LADDER[0] * (1 + 1e-9):
            return False
        second = c.effects[1]
        self.log.append(
            (
                "note",
                c.effects,
                [
                    f"the rattle is {second}'s: its simulation with a gap of {EPS_LADDER[0]:g} m carries it; play dropped"
                ],
            )
        )
        self.play_ok = False
        self.model.play_signature = {}
        self.cands.pop((second,), None)
        self.singles[second] = fit_eq(self.model, (second,), self.folds)  # friction: on its solver signature
        if second == "friction":
            self._refine_friction(())
        return True

    def _take_play(self, c: Any, pf: Any) -> None:
        self.log.append(
            (
                "note",
                c.effects,
                [
                    f"play gap refitted on rattle curves simulated with {c.effects[1]}: "
                    f"{self.play.eps:.4g} -> {pf.eps:.4g} m"
                ],
            )
        )
        self.play.eps, self.play.std, self.play.ho = pf.eps, pf.std, pf.ho
        self.play.n_sim += pf.n_sim
        c.params["play.play_gap"], c.std["play.play_gap"] = pf.eps, pf.std

    def _refine_play(self, factor: float = REFINE) -> None:
        """The rattle statistic fixes the gap to ~10-25 %; the periodic part of the chain force is
        more sensitive to it: compare the equation error of the simulated signature at eps / factor,
        eps, eps * factor (training chi-square) and keep the vertex of the parabola in log eps."""
        m, pf = self.model, self.play
        e0 = self._play_raw = pf.eps
        grid = [e0 / factor, e0, e0 * factor]
        sigs, chi = {}, []
        for e in grid:
            m.play_signature = sigs[e] = pf.signature(m, e)
            chi.append(fit_eq(m, ("play",), self.folds).chi2_fit)
        self._play_chi = dict(zip(grid, chi, strict=True))  #: gap -> training chi-square (:meth:`_play_of_nominal`)
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

    def _play_of_nominal(self) -> bool:
        """A nominal with play (inerter = play, gap g > 0): the gap the records give (:meth:`_refine_play`:
        the rattle statistic, then the periodic equation error) is compared with g by the equation error's
        training chi-square: if chi2(g) - chi2(fitted gap) <= Z_SIGNIF^2 and g is within the refinement's
        range (REFINE) plus Z_SIGNIF std of the rattle's gap (the equation error alone does not separate
        gaps well: its nuisance inertance absorbs part), the gap is the nominal's: the nominal's residuals become those of its play chain (the
        equation error the ideal link leaves on the chain's simulated records, the signature at g, taken
        out of every record's whitened residual, with the play model's nuisance inertance column at its
        fitted value), play is part of the model, not a candidate; returns
        True. A gap that differs is a candidate as without play in the nominal; returns False."""
        from ...physics.params import InerterModel
        from ..gates import Z_SIGNIF

        m, pf = self.model, self.play
        g = float(m.tmd.play_gap) if m.tmd.inerter == InerterModel.PLAY else 0.0
        if not g > 0.0:
            return False
        best, sig_best = pf.eps, m.play_signature
        chi_best = self._play_chi.get(best)
        if chi_best is None:
            chi_best = self._play_chi[best] = fit_eq(m, ("play",), self.folds).chi2_fit
        sig = pf.signature(m, g)
        m.play_signature = sig
        fg = fit_eq(m, ("play",), self.folds)
        chi_g = fg.chi2_fit
        # the rattle's gap (before the refinement, which moves it by up to REFINE x) and its std
        far = abs(math.log(g / self._play_raw)) > math.log(REFINE) + Z_SIGNIF * float(pf.std) / self._play_raw
        if far or chi_g - chi_best > Z_SIGNIF**2:
            m.play_signature = sig_best
            self.log.append(
                (
                    "note",
                    ("play",),
                    [
                        f"the records' play gap {best:.4g} m (rattle: {self._play_raw:.4g} +- {pf.std:.2g} m) is not "
                        f"the nominal's {g:.4g} m (equation error chi2 {chi_g - chi_best:.3g} worse)"
                    ],
                )
            )
            return False
        m.play_signature = {}
        beta = float(fg.beta[0])  # the play model's own nuisance: the inertance lost while rattling
        for v in self.views:
            A, B = sig[v.name]
            ((a, b),) = m.columns("play", v)
            v.r = v.r - m.whiten(v, A + beta * a, B + beta * b)
        self.chi0_t = sum(float(self.views[i].r @ self.views[i].r) for i in self.test_ids)
        self.chi0 = self.chi0_t + self.chi0_f
        self.play_nominal = True
        self.log.append(
            (
                "note",
                ("play",),
                [
                    f"the nominal's play gap {g:.4g} m agrees with the records' {best:.4g} m "
                    f"(chi2 {chi_g - chi_best:.3g} worse, <= {Z_SIGNIF**2:.0f}): part of the model"
                ],
            )
        )
        return True

    def _spike_sd(self) -> list[float]:
        out = []
        for w in self.views:
            ex, ey = w.series.resid.get("xdd"), w.series.resid.get("ydd")
            out.append(self.model.base.mass * self.model.tmd.mass * float(np.std(ex) * np.std(ey)) / math.sqrt(ex.size))
        return out
