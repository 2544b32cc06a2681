"""Running a diagnosis (the compute side of the ``diagnose``, ``make-benchmark`` and ``score``
console scripts, whose argument parsing is :mod:`pyfmu_wrapper.cli.diagnose`). The output folders
are :mod:`.outfolder` (re-exported here).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import InputError, read_utf8
from .data import DataError, load_dataset

if TYPE_CHECKING:
    from pathlib import Path
    from typing import Any

    from ..inputs.yamlio import MarkedDict
    from .data import Dataset


def _load_model(spec: str | None) -> dict[str, Any] | MarkedDict | None:
    if spec is None:
        return None
    import yaml

    from ..inputs.yamlio import load_marked

    p = Path(spec)
    if not p.is_file():
        raise DataError(
            f"{spec}: model file not found (a YAML with 'nominal:' or 'base:'/'tmd:' keys, or link parameters)"
        )
    try:
        raw = load_marked(read_utf8(p, error=DataError), name=spec) or {}
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        raise DataError(
            f"{spec}{'' if mark is None else f':{mark.line + 1}'}: invalid YAML: {' '.join(str(e).split())}"
        ) from None
    if isinstance(raw, dict) and "schema_version" in raw:  # a project scenario file
        from ..physics.params import as_dict
        from ..scenario.loader import ScenarioError, load_scenario

        try:
            sc = load_scenario(p)
        except ScenarioError as e:
            raise DataError(str(e)) from None
        if hasattr(sc.base, "stiffnesses"):  # a frame scenario: its frame: and tmd: blocks
            fr = sc.base.resolved()
            return {
                "frame": {
                    "storeys": fr.n,
                    "mass": list(fr.masses),
                    "stiffness": list(fr.stiffnesses),
                    "damping": list(fr.dampings),
                    "force_storey": fr.force_storey,
                },
                "tmd": {**as_dict(sc.tmd), "storey": fr.tmd_storey, "inerter_to": fr.inerter_to},
            }
        return {"base": as_dict(sc.base), "tmd": as_dict(sc.tmd)}
    if isinstance(raw, dict) and "nominal" in raw:
        raw = raw["nominal"]
    if not isinstance(raw, dict):
        raise DataError(f"{spec}: model file must be a mapping")
    return raw


def _reduced(ds: Dataset) -> list:
    return [{"record": r.name, **r.meta["reduced"]} for r in ds.records if "reduced" in r.meta]


def _append_reduction(res: dict[str, Any], out: Path | None) -> None:
    """Say in report.md which long records were reduced, and how (res["input_reduced"])."""
    red = res.get("input_reduced")
    if not red or out is None or not (out / "report.md").is_file():
        return
    L = ["", "## Long records reduced", ""]
    L += [
        f"- {r['record']}: {r['rows']:,} rows -> {r['samples']:,} samples ({r['method']}: an anti-alias "
        f"low-pass before keeping every {r['block']}th sample)"
        + (f"; the last {r['dropped_rows']} rows (less than one block) not used" if r["dropped_rows"] else "")
        for r in red
    ]
    with open(out / "report.md", "a", encoding="utf-8") as fh:
        fh.write("\n".join(L) + "\n")


def run_diagnosis(
    dataset: Path | str, out: Path | None = None, model: str | None = None, log: Callable[[str], Any] | None = None
) -> dict:
    """Diagnose a dataset folder; write report.md, diagnosis.json and PNGs to ``out`` if given
    (``out`` is written as given: the CLI passes a fresh folder, see :class:`ResultFolder`)."""
    from . import progress
    from .records import say

    progress.stage("reading the dataset")
    ds = load_dataset(dataset, _load_model(model), log=log or say, model_source=model)
    red = _reduced(ds)
    res = _run(ds, None if out is None else Path(out), red)
    if red:
        res["input_reduced"] = red
        _append_reduction(res, None if out is None else Path(out))
    if out is not None and ds.level == "system" and "verdict" in res:
        _write_corrected(ds, res, Path(out))
    return res


def _write_corrected(ds: Dataset, res: dict[str, Any], out: Path) -> None:
    """``out/corrected/``: the nominal with the named effects (:mod:`.corrected`), said in report.md."""
    from .corrected import write_corrected

    files = write_corrected(ds, res, out / "corrected")
    res["corrected"] = [f"corrected/{f.name}" for f in files]
    js = out / "diagnosis.json"
    if js.is_file():  # the files, in diagnosis.json too (written before them)
        doc = json.loads(js.read_text(encoding="utf-8"))
        doc["corrected"] = res["corrected"]
        js.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    if (out / "report.md").is_file():
        named = bool(res["verdict"].get("effects"))
        L = ["", "## The corrected model", ""]
        L.append(
            ("The nominal with the named effects at their fitted values" if named else "The nominal (nothing named)")
            + ": `run-scenario corrected/<file>.yaml` computes its curves at the records' frequencies; the "
            ".ssv holds the same parameters for the FMUs (docs/diagnose.md, 'The corrected model')."
        )
        L += [f"- `{f}`" for f in res["corrected"]]
        with open(out / "report.md", "a", encoding="utf-8") as fh:
            fh.write("\n".join(L) + "\n")


def _run(ds: Dataset, out: Path | None, red: list[Any]) -> dict:
    from .link.fit import diagnose_link
    from .link.models import build_link_data
    from .link.report import build_result, write_report

    def finish(res: dict[str, Any]) -> dict[str, Any]:
        if red:
            res["input_reduced"] = red
        fl = _flagged(ds, res)
        if fl:
            res["flagged_records"] = fl
        return res

    from . import progress

    if ds.level == "system" and "frame" in ds.nominal:
        from .frame.report import run_frame

        progress.stage("frame: transient records")
        return finish(run_frame(ds, out))
    frc = None
    if any(r.kind == "frc" for r in ds.records):
        from .system.frc import diagnose_frc

        progress.stage("FRC records: fitting the candidates")
        frc = diagnose_frc(ds)
    if frc is not None and not any(r.kind != "frc" for r in ds.records):  # FRC records only
        res = finish(frc.result())
        res["verdict"] = frc_verdict(res)
        if out is not None:
            progress.stage("writing the report")
            frc.write(out, res)
        return res
    if ds.level == "system" and any(r.kind == "transient" for r in ds.records):
        from .system.transient_report import run_transient

        progress.stage("transient records: screening and fitting the candidates")
        return finish(run_transient(ds, out, lambda sub: _run(sub, None, [])))
    if ds.level == "system":
        from .system.diagnosis import SystemDiagnosis
        from .system.report import build_system_result, write_system_report

        sd = SystemDiagnosis(ds, frc)
        if not sd.views and frc is not None:  # no periodic time record: the FRC records alone
            res = finish(frc.result())
            res["verdict"] = frc_verdict(res)
            res["verdict"]["disagreements"] = [f"time record {n} not used: {w}" for n, w in sd.flagged]
            if out is not None:
                frc.write(out, res)
            return res
        if not sd.views:
            raise DataError(
                f"{ds.path}: no periodic system time record to diagnose ("
                + "; ".join(f"{n}: {w}" for n, w in sd.flagged)
                + ")"
                + (" -- give FRC records alone for an FRC-only diagnosis" if frc is None else "")
            )
        progress.stage("time records: fitting the candidates")
        sd.run()
        res = finish(build_system_result(ds, sd, frc))
        if out is not None:
            progress.stage("writing the report")
            write_system_report(res, sd, out, frc)
        return res
    progress.stage("link records: fitting the candidates")
    ld = build_link_data(ds)
    diag = diagnose_link(ld)
    res = finish(build_result(ds, ld, diag))
    if frc is not None:
        res["frc"] = frc.result()
    if out is not None:
        progress.stage("writing the report")
        write_report(res, ld, diag, out, frc=frc)
    return res


def _flagged(ds: Dataset, res: dict[str, Any]) -> list:
    """Records used only in part, beyond those the system analysis lists itself (time_records.flagged)."""
    known = {f["record"] for f in (res.get("time_records") or {}).get("flagged", [])}
    out = []
    for r in ds.records:
        if r.name in known:
            continue
        if r.kind == "time":
            miss = [c for c in ("xdd", "ydd") if not r.has(c)]
            if miss:
                out.append(
                    {
                        "record": r.name,
                        "reason": f"no {' or '.join(repr(c) for c in miss)} column: the play "
                        "(rattle) statistic cannot use this record",
                    }
                )
        if r.kind in ("link", "time") and r.meta.get("periodic") is False:
            out.append(
                {
                    "record": r.name,
                    "reason": "not periodic (no dominant frequency found): no harmonic analysis of this record",
                }
            )
    return out


def flagged_lines(res: dict) -> list:
    """Records left out of (part of) the analysis, one line each, for the printed verdict."""
    out = []
    for f in (res.get("time_records") or {}).get("flagged", []):
        out.append(f"{f['record']}: {f['reason']}")
    for f in res.get("flagged_records", []):
        out.append(f"{f['record']}: {f['reason']}")
    return out


def frc_verdict(res: dict) -> dict:
    """The top-level ``verdict`` of an FRC-only diagnosis."""
    from .system.effects import VOCAB

    a = res["attribution"]
    return {
        "structural": a["structural"],
        "effects": a["effects"],
        "elements": [VOCAB[e].element if e in VOCAB else "" for e in a["effects"]],
        "text": a["verdict"],
        "unexplained": a.get("unexplained", False),
        "unexplained_share": a.get("unexplained_share"),
        "parameters": {k: {"value": v, "std": a["std"].get(k)} for k, v in a["params"].items()},
        "held_out": {"gap_closed": res["held_out"]["gap_closed"]},
        "sources": {"frc_records": res["records"]},
        "disagreements": [],
        "rejected": [],
    }


def load_manifest(bench: Path) -> list:
    """The datasets of a benchmark folder's manifest.json (InputError when there is none or it is empty)."""
    bench = Path(bench)
    if not bench.is_dir():
        raise InputError(f"{bench}: not a folder (give a folder written by make-benchmark)")
    mf = bench / "manifest.json"
    if not mf.is_file():
        raise InputError(f"{mf}: file not found: {bench} is not a benchmark written by make-benchmark")
    try:
        doc = json.loads(read_utf8(mf, error=InputError))
    except json.JSONDecodeError as e:
        raise InputError(f"{mf}: line {e.lineno}, column {e.colno}: not valid JSON ({e.msg})") from None
    man = doc.get("datasets") if isinstance(doc, dict) else None
    if not isinstance(man, list):
        raise InputError(f"{mf}: no 'datasets' list: not a make-benchmark manifest")
    if not man:
        raise InputError(f"{mf}: the benchmark has no datasets: nothing to score")
    for i, m in enumerate(man):
        if not isinstance(m, dict) or not {"dataset", "hidden", "truth"} <= set(m):
            raise InputError(f"{mf}: datasets[{i}] needs keys 'dataset', 'hidden', 'truth'")
        if not (bench / str(m["dataset"])).is_dir():
            raise InputError(f"{mf}: datasets[{i}]: folder {bench / str(m['dataset'])} not found")
    return man
