"""What an FRC diagnosis reports: its result (verdict, candidates, held-out gap), the markdown section
and the files of a stand-alone FRC diagnosis. Functions of a finished :class:`~.frc.FRCDiagnosis`
(its methods ``result``, ``markdown`` and ``write`` call them).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..shapes import FRCDiagnosisShape


def result(self: FRCDiagnosisShape) -> dict[str, Any]:
    nt = int(self.test.sum())
    xr = 1.0  # residuals are relative to x_max already
    c = self.chosen
    best = c or self.fits[0]
    verdict = (
        f"FRC: gap attributed to {c['effects'][0]}"
        if c
        else "FRC: no structural effect (held-out gap at the noise floor or no candidate beats it)"
    )
    if getattr(self, "unexplained", False):
        h = self.hint["effects"][0] if getattr(self, "hint", None) else None
        verdict = (
            (verdict + "; a structural gap remains that it does not explain")
            if c
            else "FRC: a structural gap remains that none of the candidates explains; it lives in the FRC"
            f" between {self.w.min():.4g} and {self.w.max():.4g} rad/s"
            + (f" (closest candidate, a hint not a cause: {h})" if h else "")
        )
    return {
        "records": self.names,
        "noise_floor": self.noise,
        "noise_relative": self.noise_rel,
        "where": {"omega": self.w.tolist(), "residual": (self.x - self.pred0).tolist()},
        "candidates": [{k: v for k, v in f.items() if k != "pred"} for f in self.fits],
        "attribution": {
            "structural": self.structural,
            "verdict": verdict,
            "effects": c["effects"] if c else [],
            "unexplained": bool(getattr(self, "unexplained", False)),
            "unexplained_share": getattr(self, "unexplained_share", None),
            "params": c["params"] if c else {},
            "std": c["std"] if c else {},
        },
        "held_out": {
            "nrmse_before": math.sqrt(self.rss0 / nt) / xr,
            "nrmse_after": math.sqrt(best["rss_test"] / nt) / xr,
            "gap_closed": best["gap_closed"] if c else None,
            "best_candidate": best["effects"][0],
        },
    }


def markdown(self: FRCDiagnosisShape) -> list[str]:
    res = result(self)
    h = res["held_out"]
    L = [
        "## Stepped-sine FRC records",
        "",
        f"**{res['attribution']['verdict']}**",
        "",
        "![frc](frc.png)",
        "",
        "| effect | held-out dBIC | gap closed | parameter (std) |",
        "|---|---|---|---|",
    ]
    for f in self.fits:
        k, v = next(iter(f["params"].items()))
        gc = "n/a" if f["gap_closed"] is None else f"{100 * f['gap_closed']:.0f} %"
        L.append(f"| {f['effects'][0]} | {f['delta_bic']:.1f} | {gc} | {k} = {v:.4g} ({f['std'][k]:.2g}) |")
    L += ["", f"Held-out NRMSE {h['nrmse_before']:.4f} -> {h['nrmse_after']:.4f}.", ""]
    return L


def write(self: FRCDiagnosisShape, out: Path, res: dict[str, Any] | None = None) -> None:
    out.mkdir(parents=True, exist_ok=True)
    from ..plotting import plot_frc

    plot_frc(self, out / "frc.png")
    (out / "diagnosis.json").write_text(json.dumps(res or result(self), indent=1))
    (out / "report.md").write_text("# FRC diagnosis\n\n" + "\n".join(markdown(self)) + "\n")
