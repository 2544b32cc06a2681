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


class PlayMixin:
    # what the mixin reads of the diagnosis it is mixed into (SystemDiagnosis)
    model: Any
    play: Any
    folds: Any
    views: Any
    train_ids: Any
    log: Any

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

    def _refine_play(self, factor: float = 1.25) -> None:
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

    def _spike_sd(self) -> list[float]:
        out = []
        for w in self.views:
            ex, ey = w.series.resid.get("xdd"), w.series.resid.get("ydd")
            out.append(self.model.base.mass * self.model.tmd.mass * float(np.std(ex) * np.std(ey)) / math.sqrt(ex.size))
        return out
