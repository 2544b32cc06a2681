"""A system-level diagnosis with transient records: run it (with the steady and FRC records of the
same dataset, when there are any), and write diagnosis.json, report.md and the plots."""

from __future__ import annotations

import copy
import json
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

    from ..data import Dataset
    from .transient import TransientDiagnosis


def run_transient(ds: Dataset, out: Path | None, steady_run: Callable[[Dataset], dict[str, Any]]) -> dict[str, Any]:
    """Diagnose the transient records; the steady-state and FRC records (if any) are diagnosed by
    ``steady_run`` on the rest of the dataset, and where the two verdicts name different effects
    the verdict says so (``verdict.disagreements``)."""
    from .transient import TransientDiagnosis

    td = TransientDiagnosis(ds)
    tres = td.run()
    v = dict(tres["verdict"])
    res: dict[str, Any] = {
        "schema": "pyfmu-diagnose/2",
        "dataset": str(ds.path),
        "level": "system",
        "kind": "transient",
        "verdict": v,
        "transient": {k: val for k, val in tres.items() if k != "verdict"},
    }
    v["sources"] = {"transient_records": [r["record"] for r in tres["records"]]}
    v["disagreements"] = []
    rest = [r for r in ds.records if r.kind != "transient"]
    if rest:
        sub = copy.copy(ds)
        sub.records = rest
        sres = steady_run(sub)
        res["steady"] = sres
        sv = sres.get("verdict") or {}
        v["sources"]["steady_records"] = [r.name for r in rest]
        se, te = sorted(sv.get("effects", [])), sorted(v["effects"])
        if se != te:
            v["disagreements"].append(
                f"the steady-state/FRC records alone give: {sv.get('text', '?')} -- the transient records: "
                f"{' + '.join(te) if te else 'no named effect'}"
            )
            if te and se and not set(se) & set(te):
                v["unexplained"] = True
                v["notes"] = [*v.get("notes", []), "the transient and the steady records name different effects"]
                v["text"] += " The steady-state records name a different effect: see the disagreements."
    if out is not None:
        write(res, td, out)
    return res


def write(res: dict[str, Any], td: TransientDiagnosis, out: Path) -> None:
    from .. import plotting

    out.mkdir(parents=True, exist_ok=True)
    (out / "diagnosis.json").write_text(json.dumps(res, indent=1, default=json_default))
    plotting.plot_transient(td, res["transient"], out / "where.png")
    v, t = res["verdict"], res["transient"]
    h = t["held_out"]["by_segment"]
    L = [
        f"# Diagnosis of {res['dataset']} (transient records)",
        "",
        f"**{v['text']}**",
        "",
        f"Held out by time segment (every record cut into 8, even segments fitted, odd predicted): "
        f"chi-square {h['chi2_before']:.6g} -> {h['chi2_after']:.6g} on {h['dof']} degrees of freedom "
        f"(z {h['z_before']:.1f} -> {h['z_after']:.1f}; {t['held_out']['level']}).",
        "",
    ]
    pb = t.get("play_band")
    if pb and "play" in pb:  # the band test ran (nothing explained the records sample by sample)
        L += [
            f"Play on the band below {pb['band_hz']:.3g} Hz (the rattle's spread in the noise; "
            f"{'named' if pb['named'] else 'not named: ' + pb['why']}): band chi2/dof of play "
            f"{pb['play']['red']:.4g} (gap {pb['play']['gap']:.4g} m), of the best other candidate "
            f"({pb['best_other']}) {pb['others'][pb['best_other']]['chi2'] / pb['others'][pb['best_other']]['dof']:.4g}, "
            f"of the nominal {pb['nominal']['chi2'] / pb['nominal']['dof']:.4g}.",
            "",
        ]
    if v["parameters"]:
        L += ["| parameter | value | std | unit |", "|---|---|---|---|"]
        L += [f"| {k} | {p['value']:.6g} | {p['std']:.2g} | {p['unit']} |" for k, p in v["parameters"].items()]
        L.append("")
    if t["held_out"]["by_record"]:
        L += [
            "Held out by record (each predicted from the others):",
            "",
            "| record | z before | z after | gap closed |",
        ]
        L.append("|---|---|---|---|")
        for r in t["held_out"]["by_record"]:
            zb = (r["chi2_before"] - r["dof"]) / (2 * r["dof"]) ** 0.5
            za = (r["chi2_after"] - r["dof"]) / (2 * r["dof"]) ** 0.5
            gc = "n/a" if r["gap_closed"] is None else f"{100 * r['gap_closed']:.1f} %"
            L.append(f"| {r['record']} | {zb:.1f} | {za:.1f} | {gc} |")
        L.append("")
    ag = t.get("agreement") or {}
    if ag.get("records"):
        pv = "n/a: no parameter votes" if ag.get("p_value") is None else f"{ag['p_value']:.3g}"
        L += [f"Parameters record by record (agreement p = {pv}):", ""]
        for r in ag["records"]:
            L.append(
                f"- {r['record']}: "
                + "; ".join(f"{k} = {p['value']:.5g} +- {p['std']:.2g}" for k, p in r["params"].items())
            )
        L.append("")
    L += [
        "## Where",
        "",
        t["where"]["text"],
        "",
        "![where](where.png)",
        "",
        "## Candidates (held-out time segments)",
        "",
    ]
    L += ["| effects | z | gap closed | parameters |", "|---|---|---|---|"]
    for c in t["candidates"]:
        if not c["ok"]:
            L.append(f"| {' + '.join(c['effects'])} | - | - | rejected: {c['reason']} |")
            continue
        gc = "n/a" if c["gap_closed"] is None else f"{100 * c['gap_closed']:.2f} %"
        ps = "; ".join(f"{k} = {p['value']:.4g} +- {p['std']:.2g}" for k, p in c["params"].items())
        L.append(f"| {' + '.join(c['effects'])} | {c['z']:.1f} | {gc} | {ps} |")
    L += ["", "## Records", "", "| record | fit rate [Hz] | samples averaged | start skipped [s] | noise std |"]
    L.append("|---|---|---|---|---|")
    noise = {n["record"]: n["noise_std"] for n in t["noise"]}
    for r in t["records"]:
        ns = ", ".join(f"{k} {s:.3g}" for k, s in noise[r["record"]].items())
        L.append(f"| {r['record']} | {r['fit_rate_hz']:.4g} | {r['averaged']} | {r['skipped_start_s']:.3g} | {ns} |")
    for d in v.get("disagreements", []):
        L += ["", f"Note: {d}"]
    (out / "report.md").write_text("\n".join(L) + "\n")


def json_default(o: Any) -> Any:
    """numpy scalars, arrays and tuples as JSON values (the `default` of json.dumps for a diagnosis)."""
    import numpy as np

    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, tuple):
        return list(o)
    raise TypeError(type(o))
