"""What a system diagnosis reports besides its verdict: the held-out chi-squares and gaps before and
after the named effects (time records, FRC points, rattle statistic) and the table of candidate
effects with their evidence. Functions of a finished :class:`~.diagnosis.SystemDiagnosis` (its
methods ``held_out`` and ``candidates`` call them).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

from ..gates import plausibility
from .model import EFFECT_PARAMS

if TYPE_CHECKING:
    from ..shapes import SystemDiagnosisShape


def held_out(self: SystemDiagnosisShape) -> dict[str, Any]:
    """Held-out chi-squares and gaps (time records + FRC points + rattle statistic), before and
    after the named effects."""
    dof = self.dof
    cur = self.cur if self.chosen else None
    chi1 = cur.chi if cur else self.chi0
    g0, g1 = max(self.chi0 - dof, 0.0), max(chi1 - dof, 0.0)
    sp0 = sp1 = 0.0
    if self.play_ok:
        sd = [max(s, 1e-300) for s in self._spike_sd()]
        for h in self.play.ho:
            i = [w.name for w in self.views].index(h["record"])
            sp0 += (h["S_measured"] / sd[i]) ** 2
            sp1 += ((h["S_measured"] - h["S_predicted"]) / sd[i]) ** 2
        if "play" not in self.chosen:
            sp1 = sp0
    G0, G1 = g0 + sp0, g1 + sp1
    per = []
    for i in self.test_ids:
        c0 = float(self.views[i].r @ self.views[i].r)
        c1 = self.final.chi2_ho_rec[i] if self.final else c0
        n = self.views[i].r.size
        per.append(
            {
                "record": self.views[i].name,
                "omega": self.views[i].omega,
                "dof": n,
                "chi2_before": c0,
                "chi2_after": c1,
                "gap_closed": (1 - max(c1 - n, 0) / (c0 - n)) if c0 > n else None,
            }
        )
    return {
        "chi2_before": self.chi0,
        "chi2_after": chi1,
        "dof": dof,
        "time": {"chi2_before": self.chi0_t, "chi2_after": cur.chi_t if cur else self.chi0_t, "dof": self.dof_t},
        "frc": (
            {"chi2_before": self.chi0_f, "chi2_after": cur.chi_f if cur else self.chi0_f, "dof": self.nf}
            if self.frc is not None
            else None
        ),
        "rattle_chi2_before": sp0,
        "rattle_chi2_after": sp1,
        "excess_before": G0,
        "excess_after": G1,
        "gap_closed": (1 - G1 / G0) if (self.chosen and G0 > 0) else None,
        "rms_before_noise_units": math.sqrt(self.chi0 / dof),
        "rms_after_noise_units": math.sqrt(chi1 / dof),
        "per_record": per,
    }


def candidates(self: SystemDiagnosisShape) -> list[dict[str, Any]]:
    rows: list[dict[str, Any]] = []
    base: tuple[str, ...] = ("play",) if self.play_ok else ()
    chi_b = self._cand(base).chi if base else self.chi0
    for e, f in self.singles.items():
        c = self.cands.get(f.effects)
        chi = c.chi if c is not None else f.chi2_ho + (self.chi0_f if not base else self._cand(base).chi_f)
        rows.append(
            {
                "effects": list(f.effects),
                "params": c.params if c else f.params,
                "std": c.std if c else f.std,
                "chi2_held_out": chi,
                "chi2_held_out_time": f.chi2_ho,
                "evidence": chi_b - chi - len(EFFECT_PARAMS[e]) * math.log(self.n),
                "frc_evidence": self.frc_ev.get(f.effects),
                "frc_source": c.frc_source if c else "",
                "gap_closed": (1 - max(chi - self.dof, 0) / (self.chi0 - self.dof)) if self.chi0 > self.dof else None,
                "rejected": c.why if c else plausibility(f.params, f.std, self.model.tmd, self.motion, self.model.base),
            }
        )
    rows.sort(key=lambda r: -r["evidence"])
    return rows
