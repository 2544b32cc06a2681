"""Console scripts: ``diagnose``, ``make-benchmark``, ``score``."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import yaml

from .data import DataError, load_dataset


def _load_model(spec: str | None):
    if spec is None:
        return None
    p = Path(spec)
    if not p.is_file():
        raise DataError(f"{spec}: model file not found (a YAML with 'nominal:' or 'base:'/'tmd:' keys, "
                        "or link parameters)")
    raw = yaml.safe_load(p.read_text()) or {}
    if isinstance(raw, dict) and "schema_version" in raw:  # a project scenario file
        from ..physics.params import as_dict
        from ..scenario.loader import ScenarioError, load_scenario

        try:
            sc = load_scenario(p)
        except ScenarioError as e:
            raise DataError(f"{spec}: {e}") from None
        return {"base": as_dict(sc.base), "tmd": as_dict(sc.tmd)}
    if "nominal" in raw:
        raw = raw["nominal"]
    if not isinstance(raw, dict):
        raise DataError(f"{spec}: model file must be a mapping")
    return raw


def run_diagnosis(dataset, out=None, model: str | None = None) -> dict:
    """Diagnose a dataset folder; write report.md, diagnosis.json and PNGs to ``out`` if given."""
    from .fit import diagnose_link
    from .models import build_link_data
    from .report import build_result, write_report

    ds = load_dataset(dataset, _load_model(model))
    frc = None
    if any(r.kind == "frc" for r in ds.records):
        from .frc import diagnose_frc
        frc = diagnose_frc(ds)
    if not any(r.kind != "frc" for r in ds.records):
        res = frc.result()
        res["verdict"] = frc_verdict(res)
        if out is not None:
            frc.write(Path(out), res)
        return res
    if ds.level == "system":
        from .sysdiag import SystemDiagnosis
        from .sysreport import build_system_result, write_system_report

        sd = SystemDiagnosis(ds, frc)
        if not sd.views and frc is not None:  # no periodic time record: the FRC records alone
            res = frc.result()
            res["verdict"] = frc_verdict(res)
            res["verdict"]["disagreements"] = [f"time record {n} not used: {w}" for n, w in sd.flagged]
            if out is not None:
                frc.write(Path(out), res)
            return res
        if not sd.views:
            raise DataError(f"{ds.path}: no periodic system time record to diagnose ("
                            + "; ".join(f"{n}: {w}" for n, w in sd.flagged) + ")"
                            + (" -- give FRC records alone for an FRC-only diagnosis" if frc is None else ""))
        sd.run()
        res = build_system_result(ds, sd, frc)
        if out is not None:
            write_system_report(res, sd, Path(out), frc)
        return res
    ld = build_link_data(ds)
    diag = diagnose_link(ld)
    res = build_result(ds, ld, diag)
    if frc is not None:
        res["frc"] = frc.result()
    if out is not None:
        write_report(res, ld, diag, Path(out), frc=frc)
    return res


def frc_verdict(res: dict) -> dict:
    """The top-level ``verdict`` of an FRC-only diagnosis."""
    a = res["attribution"]
    return {"structural": a["structural"], "effects": a["effects"], "text": a["verdict"],
            "unexplained": a.get("unexplained", False), "unexplained_share": a.get("unexplained_share"),
            "parameters": {k: {"value": v, "std": a["std"].get(k)} for k, v in a["params"].items()},
            "held_out": {"gap_closed": res["held_out"]["gap_closed"]}, "sources": {"frc_records": res["records"]},
            "disagreements": [], "rejected": []}


def main_diagnose(argv=None):
    ap = argparse.ArgumentParser(prog="diagnose", description="Localise, attribute and quantify the gap "
                                 "between a nominal model and measurements (see docs/diagnose.md).")
    ap.add_argument("dataset", help="folder with dataset.yaml and CSV records")
    ap.add_argument("--model", help="YAML with the nominal model (overrides the dataset's 'nominal')")
    ap.add_argument("--out", required=True, help="output folder (report.md, diagnosis.json, PNGs)")
    a = ap.parse_args(argv)
    try:
        res = run_diagnosis(a.dataset, a.out, a.model)
    except DataError as e:
        print(f"diagnose: bad data: {e}", file=sys.stderr)
        return 2
    if "verdict" in res:
        print(res["verdict"]["text"])
        for d in res["verdict"].get("disagreements", []):
            print("note:", d)
    else:
        print(res["attribution"]["verdict"])
    h = res.get("held_out")
    if h and "nrmse_before" in h:
        gc = h["gap_closed"]
        print(f"held-out NRMSE {h['nrmse_before']:.4f} -> {h['nrmse_after']:.4f}"
              + ("" if gc is None else f", gap closed {100 * gc:.1f} %"))
    print(f"report: {Path(a.out) / 'report.md'}")
    return 0


def main_make_benchmark(argv=None):
    from .benchmark import make_benchmark

    ap = argparse.ArgumentParser(prog="make-benchmark", description="Generate withheld-effect datasets "
                                 "(labels in OUT/manifest.json, never read by diagnose).")
    ap.add_argument("--out", required=True)
    ap.add_argument("--suite", choices=["system", "link"], default="system",
                    help="system: the coupled base + TMD simulated and measured as a rig does (default); "
                         "link: one TMD link on a displacement-controlled rig")
    ap.add_argument("-n", type=int, default=None, help="number of datasets (default: system 52, link 40)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--clean-fraction", type=float, default=0.25)
    ap.add_argument("--pair-fraction", type=float, default=0.2)
    ap.add_argument("--noise", type=float, default=0.5, help="link suite: force noise std [N]")
    a = ap.parse_args(argv)
    if a.suite == "system":
        from .sysbench import make_system_benchmark

        man = make_system_benchmark(Path(a.out), n=a.n, seed=a.seed, progress=lambda r: print(
            f"{r['dataset']} written ({r['seconds']:.1f} s)", flush=True))  # the labels only in manifest.json
        print(f"wrote {len(man)} system-level datasets and manifest.json to {a.out}")
        return 0
    man = make_benchmark(Path(a.out), n=40 if a.n is None else a.n, seed=a.seed, clean_fraction=a.clean_fraction, pair_fraction=a.pair_fraction, noise=a.noise)
    print(f"wrote {len(man)} datasets and manifest.json to {a.out}")
    return 0


def main_score(argv=None):
    from .benchmark import score

    ap = argparse.ArgumentParser(prog="score", description="Run diagnose on a benchmark and score it.")
    ap.add_argument("benchmark", help="folder written by make-benchmark")
    ap.add_argument("--out", help="write score.json here (system suite default: BENCHMARK/score.json)")
    a = ap.parse_args(argv)
    man = Path(a.benchmark) / "manifest.json"
    if not man.is_file():
        print(f"score: {man}: file not found (a folder written by make-benchmark)", file=sys.stderr)
        return 2
    if json.loads(man.read_text()).get("suite") == "system":
        from .sysscore import row_line, score_system, table

        out = Path(a.out) if a.out else Path(a.benchmark) / "score.json"
        if not a.out and out.exists() and '"written_by": "score"' not in out.read_text():
            print(f"score: {out} exists and was not written by score; give --out", file=sys.stderr)
            return 2
        res = score_system(Path(a.benchmark), progress=lambda r: print(row_line(r), flush=True))
        print(table(res["summary"]))
        out.write_text(json.dumps(res, indent=1))
        print(f"score: {out}")
        return 0
    res = score(Path(a.benchmark), progress=lambda r: print(
        f"{r['dataset']}: hidden {r['hidden'] or '-'} found {r['found'] or '-'} {'ok' if r['correct'] else 'WRONG'}"))
    print(json.dumps(res["summary"], indent=1))
    if a.out:
        Path(a.out).write_text(json.dumps(res, indent=1))
    return 0
