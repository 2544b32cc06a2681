"""The diagnosis as a JSON-able dict and as a markdown report with PNG plots."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ...models.base_tmd.effects import VOCABULARY as VOCAB
from .. import plotting
from . import localise
from .fit import per_band

if TYPE_CHECKING:
    from typing import Any

    from numpy import float64

    from ..data import Dataset
    from .fit import Diagnosis, Fit
    from .models import LinkData


def _f(x: float | float64) -> float | None:
    if x is None:
        return None
    x = float(x)
    return None if not math.isfinite(x) else x


def fit_dict(f: Fit, diag: Diagnosis) -> dict[str, Any]:
    return {
        "effects": list(f.effects),
        "labels": list(f.labels),
        "params": f.params,
        "std": f.std,
        "rms_test": math.sqrt(f.rss_test / diag.n_test),
        "nrmse_test": _f(f.nrmse_test),
        "bic_test": f.bic,
        "delta_bic": f.bic - diag.bic0,
        "gap_closed": _f(f.closed),
        "n_params": f.n_params,
    }


def build_result(ds: Dataset, ld: LinkData, diag: Diagnosis) -> dict:
    r0 = ld.F - ld.F_nom
    chosen = diag.chosen
    best = chosen or diag.ranking[0]
    nt = diag.n_test
    frms = float(np.sqrt(np.mean(ld.F[diag.test] ** 2)))
    harm = localise.harmonics(ld, r0)
    c, rms_ph, _ = localise.by_phase(ld, r0)
    res = {
        "dataset": str(ds.path),
        "level": ds.level,
        "nominal": ds.nominal,
        "link_nominal": ld.nominal,
        "noise_floor": ld.noise,
        "split": {
            "train": sorted({ld.records[i].name for i in ld.rec[diag.train]}),
            "test": sorted({ld.records[i].name for i in ld.rec[diag.test]}),
        },
        "where": {
            "summary": localise.describe(ld, r0, harm, rms_ph),
            "per_record": localise.by_record(ld, r0),
            "harmonics": {"k": list(range(harm.size)), "amplitude": harm.tolist()},
            "phase": {"phase_deg": np.degrees(c).tolist(), "rms": [_f(x) for x in rms_ph]},
            "state": localise.state_summary(ld, r0),
        },
        "candidates": [fit_dict(f, diag) for f in diag.ranking],
        "attribution": {
            "structural": diag.structural,
            "verdict": diag.verdict,
            "effects": list(chosen.effects) if chosen else [],
            "labels": list(chosen.labels) if chosen else [],
            "elements": [VOCAB[e].element for e in chosen.effects] if chosen else [],
            "params": chosen.params if chosen else {},
            "std": chosen.std if chosen else {},
            "excess_over_noise": diag.excess,
        },
        "held_out": {
            "rms_before": math.sqrt(diag.nominal_rss_test / nt),
            "nrmse_before": math.sqrt(diag.nominal_rss_test / nt) / frms,
            "rms_after": math.sqrt(best.rss_test / nt),
            "nrmse_after": math.sqrt(best.rss_test / nt) / frms,
            "gap_closed": _f(best.closed) if chosen else None,
            "best_candidate": best.name,
            "per_band": per_band(ld, diag, best),
        },
    }
    return res


def write_report(res: dict, ld: LinkData, diag: Diagnosis, out: Path, frc: Any = None) -> None:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    best = diag.chosen or diag.ranking[0]
    plotting.plot_where(
        ld, ld.F - ld.F_nom, ld.F - best.pred, out / "where.png", title=f"gap of the nominal model; fitted: {best.name}"
    )
    plotting.plot_loops(ld, ld.F_nom, best.pred, diag.test, out / "loops.png")
    plotting.plot_candidates(diag.ranking, out / "candidates.png")
    if frc is not None:
        plotting.plot_frc(frc, out / "frc.png")
    (out / "diagnosis.json").write_text(json.dumps(res, indent=1, default=_json_default))
    a, h = res["attribution"], res["held_out"]
    L = [
        f"# Diagnosis of `{res['dataset']}`",
        "",
        f"Level: {res['level']}. Nominal link model: "
        + ", ".join(f"{k} = {v:g}" for k, v in res["link_nominal"].items())
        + ".",
        f"Training records: {', '.join(res['split']['train'])}. Held out: {', '.join(res['split']['test'])}.",
        f"Noise floor (robust scatter of the residual): {res['noise_floor']:.4g} N.",
        "",
        "## Verdict",
        "",
        f"**{a['verdict']}**",
        "",
    ]
    if a["effects"]:
        L += ["| parameter | fitted | std |", "|---|---|---|"]
        L += [f"| {k} | {v:.5g} | {a['std'].get(k, float('nan')):.2g} |" for k, v in a["params"].items()]
        L.append("")
    L += [
        "## Where the model misses",
        "",
        res["where"]["summary"],
        "",
        "![where](where.png)",
        "",
        "| record | w [rad/s] | amplitude | NRMSE (nominal) |",
        "|---|---|---|---|",
    ]
    L += [
        f"| {r['record']} | {_num(r['omega'])} | {_num(r['amplitude'])} | {r['nrmse']:.3f} |"
        for r in res["where"]["per_record"]
    ]
    L += [
        "",
        "## Which effect: candidates ranked by held-out BIC",
        "",
        "| rank | effect(s) | held-out NRMSE | dBIC vs nominal | gap closed | parameters (std) |",
        "|---|---|---|---|---|---|",
    ]
    for i, c in enumerate(res["candidates"], 1):
        ps = "; ".join(
            f"{k.split('.', 1)[1]} = {v:.4g} ({c['std'].get(k, float('nan')):.2g})" for k, v in c["params"].items()
        )
        gc = "n/a" if c["gap_closed"] is None else f"{100 * c['gap_closed']:.0f} %"
        L.append(f"| {i} | {' + '.join(c['labels'])} | {c['nrmse_test']:.4f} | {c['delta_bic']:.1f} | {gc} | {ps} |")
    L += [
        "",
        "![candidates](candidates.png)",
        "",
        "## How far: held-out gap before and after",
        "",
        f"NRMSE {h['nrmse_before']:.4f} -> {h['nrmse_after']:.4f} (rms {h['rms_before']:.4g} -> {h['rms_after']:.4g} N) "
        f"with {h['best_candidate']}; gap closed: "
        + ("n/a" if h["gap_closed"] is None else f"{100 * h['gap_closed']:.1f} %")
        + ".",
        "",
        "| band w [rad/s] | held-out records | NRMSE before | NRMSE after | gap closed |",
        "|---|---|---|---|---|",
    ]
    for b in h["per_band"]:
        gc = b.get("gap_closed")
        gc = "n/a" if gc is None or gc != gc else f"{100 * gc:.0f} %"
        L.append(
            f"| {_num(b['omega'])} | {', '.join(b['records'])} | {b['nrmse_before']:.4f} | {b.get('nrmse_after', float('nan')):.4f} | {gc} |"
        )
    L += ["", "![loops](loops.png)", ""]
    if frc is not None:
        L += frc.markdown()
    (out / "report.md").write_text("\n".join(L) + "\n")


def _num(x: float | None) -> str:
    """A table cell: the number, or 'none (transient)' for a record without a drive frequency."""
    return "none (transient)" if x is None else f"{x:.4g}"


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o))
