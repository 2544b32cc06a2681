"""Console scripts: ``diagnose``, ``make-benchmark``, ``score``.

Bad input (data, model file, command line, output folder) is one line on stderr naming the file,
row/line and key, exit status 2 (:mod:`pyfmu_wrapper.cli.errors`). Output folders: a new or empty
folder, or a previous result of the same tool (marked by a marker file); the result is written to
a hidden sibling folder first and swapped in, so a failed run leaves the old result, and nothing the
tool did not write is ever deleted or overwritten.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from pathlib import Path

from ..cli.errors import InputError, cli_main, read_utf8
from .data import DataError, load_dataset

DIAGNOSE_MARKER = ".pyfmu-diagnose"  #: marks a folder written by diagnose
BENCHMARK_MARKER = ".pyfmu-benchmark"  #: marks a folder written by make-benchmark
#: files of a result written before the markers existed (recognised as a previous result)
_LEGACY = {DIAGNOSE_MARKER: ("diagnosis.json", {"report.md", "diagnosis.json"}, (".png",)),
           BENCHMARK_MARKER: ("manifest.json", {"manifest.json", "score.json"}, ())}


def _load_model(spec: str | None):
    if spec is None:
        return None
    import yaml

    from ..scenario.yamlio import load_marked

    p = Path(spec)
    if not p.is_file():
        raise DataError(f"{spec}: model file not found (a YAML with 'nominal:' or 'base:'/'tmd:' keys, "
                        "or link parameters)")
    try:
        raw = load_marked(read_utf8(p, error=DataError), name=spec) or {}
    except yaml.YAMLError as e:
        mark = getattr(e, "problem_mark", None)
        raise DataError(f"{spec}{'' if mark is None else f':{mark.line + 1}'}: invalid YAML: "
                        f"{' '.join(str(e).split())}") from None
    if isinstance(raw, dict) and "schema_version" in raw:  # a project scenario file
        from ..physics.params import as_dict
        from ..scenario.loader import ScenarioError, load_scenario

        try:
            sc = load_scenario(p)
        except ScenarioError as e:
            raise DataError(str(e)) from None
        return {"base": as_dict(sc.base), "tmd": as_dict(sc.tmd)}
    if isinstance(raw, dict) and "nominal" in raw:
        raw = raw["nominal"]
    if not isinstance(raw, dict):
        raise DataError(f"{spec}: model file must be a mapping")
    return raw


def _files(folder: Path) -> set:
    return {str(p.relative_to(folder)) for p in folder.rglob("*") if not p.is_dir()}


def _foreign(folder: Path, marker: str) -> list | None:
    """Files in ``folder`` that the tool writing ``marker`` did not write (None: not a result at all)."""
    m = folder / marker
    if m.is_file():
        try:
            written = set(json.loads(m.read_text(encoding="utf-8"))["files"])
        except (ValueError, KeyError, TypeError, OSError):
            return None
        return sorted(_files(folder) - written - {marker})
    key, names, suffixes = _LEGACY[marker]  # a result written before the marker existed
    if not (folder / key).is_file():
        return None
    bad = []
    for e in folder.iterdir():
        if e.is_file() and (e.name in names or e.suffix in suffixes):
            continue
        if marker == BENCHMARK_MARKER and e.is_dir() and (e / "dataset.yaml").is_file():
            continue
        bad.append(e.name)
    return sorted(bad)


def _is_result(folder: Path, marker: str) -> bool:
    """True when ``folder`` holds a previous result of the tool that writes ``marker``, and nothing else."""
    return _foreign(folder, marker) == []


def check_out_folder(out, tool: str, marker: str) -> Path:
    """Refuse (InputError, before any computing) an --out that is a file, or a non-empty folder
    that is not a previous result of ``tool`` (or holds files ``tool`` did not write)."""
    out = Path(out)
    if out.exists() or out.is_symlink():
        if not out.is_dir():
            raise InputError(f"--out {out}: is a file, not a folder; {tool} writes a folder and never overwrites "
                             "a file: choose a new folder name")
        if any(out.iterdir()):
            bad = _foreign(out, marker)
            if bad is None:
                raise InputError(f"--out {out}: the folder is not empty and is not a previous {tool} result (no "
                                 f"{marker} marker): choose a new or empty folder; {tool} never deletes or "
                                 "overwrites files it did not write")
            if bad:
                raise InputError(f"--out {out}: a previous {tool} result, but it also holds files {tool} did not "
                                 f"write ({', '.join(bad[:3])}{', ...' if len(bad) > 3 else ''}): move them or "
                                 "choose another folder; the result is replaced as a whole")
    elif not out.parent.is_dir() and out.parent != Path(""):
        out.parent.mkdir(parents=True, exist_ok=True)
    return out


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _interrupt(signum, frame):
    raise KeyboardInterrupt(f"signal {signum}")


class ResultFolder:
    """``with ResultFolder(out, marker) as tmp:`` write into tmp; on success tmp replaces ``out``
    (a previous result of the same tool, or an empty folder); on failure, Ctrl-C, SIGTERM or SIGHUP
    tmp is removed. Partial folders of a killed run (``.<out>.partial-<pid>-*`` of a dead process)
    are removed on the next start, and said so."""

    def __init__(self, out, marker):
        self.out, self.marker = Path(out), marker
        self.parent = self.out.parent if str(self.out.parent) else Path(".")

    def _stale(self):
        for p in self.parent.glob(f".{self.out.name}.partial-*"):
            try:
                pid = int(p.name.rsplit(".partial-", 1)[1].split("-")[0])
            except ValueError:
                continue
            if p.is_dir() and not _pid_alive(pid):
                shutil.rmtree(p, ignore_errors=True)
                print(f"removed {p}: the partial result of an interrupted run (process {pid})", file=sys.stderr)

    def __enter__(self) -> Path:
        import signal
        import threading

        self._stale()
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.out.name}.partial-{os.getpid()}-", dir=self.parent))
        self.saved = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGTERM, getattr(signal, "SIGHUP", None)):
                if sig is not None:
                    self.saved[sig] = signal.signal(sig, _interrupt)
        return self.tmp

    def __exit__(self, et, ev, tb):
        import signal

        for sig, h in self.saved.items():
            signal.signal(sig, h)
        if et is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)
            return False
        files = sorted(_files(self.tmp))
        (self.tmp / self.marker).write_text(json.dumps({
            "note": "written by pyfmu_wrapper; replaced as a whole when the tool runs again with the same --out, "
                    "refused if other files are added", "files": files}, indent=0) + "\n")
        old = None
        if self.out.exists():  # checked before computing: a previous result or an empty folder
            if not (not any(self.out.iterdir()) or _is_result(self.out, self.marker)):
                raise InputError(f"--out {self.out}: files appeared in the folder during the run; nothing there "
                                 f"was touched and the result was left in {self.tmp}")
            old = self.parent / f".{self.out.name}.old-{os.getpid()}"
            os.replace(self.out, old)
        os.replace(self.tmp, self.out)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
        return False


def _reduced(ds) -> list:
    return [{"record": r.name, **r.meta["reduced"]} for r in ds.records if "reduced" in r.meta]


def _append_reduction(res, out: Path | None):
    """Say in report.md which long records were reduced, and how (res["input_reduced"])."""
    red = res.get("input_reduced")
    if not red or out is None or not (out / "report.md").is_file():
        return
    L = ["", "## Long records reduced", ""]
    L += [f"- {r['record']}: {r['rows']:,} rows -> {r['samples']:,} samples ({r['method']}: an anti-alias "
          f"low-pass before keeping every {r['block']}th sample)"
          + (f"; the last {r['dropped_rows']} rows (less than one block) not used" if r["dropped_rows"] else "")
          for r in red]
    with open(out / "report.md", "a", encoding="utf-8") as fh:
        fh.write("\n".join(L) + "\n")


def run_diagnosis(dataset, out=None, model: str | None = None, log=None) -> dict:
    """Diagnose a dataset folder; write report.md, diagnosis.json and PNGs to ``out`` if given
    (``out`` is written as given: the CLI passes a fresh folder, see :class:`ResultFolder`)."""
    from .data import _stderr

    ds = load_dataset(dataset, _load_model(model), log=log or _stderr, model_source=model)
    red = _reduced(ds)
    res = _run(ds, None if out is None else Path(out), red)
    if red:
        res["input_reduced"] = red
        _append_reduction(res, None if out is None else Path(out))
    return res


def _run(ds, out, red) -> dict:
    from .fit import diagnose_link
    from .models import build_link_data
    from .report import build_result, write_report

    def finish(res):
        if red:
            res["input_reduced"] = red
        fl = _flagged(ds, res)
        if fl:
            res["flagged_records"] = fl
        return res

    frc = None
    if any(r.kind == "frc" for r in ds.records):
        from .frc import diagnose_frc
        frc = diagnose_frc(ds)
    if frc is not None and not any(r.kind != "frc" for r in ds.records):  # FRC records only
        res = finish(frc.result())
        res["verdict"] = frc_verdict(res)
        if out is not None:
            frc.write(out, res)
        return res
    if ds.level == "system":
        from .sysdiag import SystemDiagnosis
        from .sysreport import build_system_result, write_system_report

        sd = SystemDiagnosis(ds, frc)
        if not sd.views and frc is not None:  # no periodic time record: the FRC records alone
            res = finish(frc.result())
            res["verdict"] = frc_verdict(res)
            res["verdict"]["disagreements"] = [f"time record {n} not used: {w}" for n, w in sd.flagged]
            if out is not None:
                frc.write(out, res)
            return res
        if not sd.views:
            raise DataError(f"{ds.path}: no periodic system time record to diagnose ("
                            + "; ".join(f"{n}: {w}" for n, w in sd.flagged) + ")"
                            + (" -- give FRC records alone for an FRC-only diagnosis" if frc is None else ""))
        sd.run()
        res = finish(build_system_result(ds, sd, frc))
        if out is not None:
            write_system_report(res, sd, out, frc)
        return res
    ld = build_link_data(ds)
    diag = diagnose_link(ld)
    res = finish(build_result(ds, ld, diag))
    if frc is not None:
        res["frc"] = frc.result()
    if out is not None:
        write_report(res, ld, diag, out, frc=frc)
    return res


def _flagged(ds, res) -> list:
    """Records used only in part, beyond those the system analysis lists itself (time_records.flagged)."""
    known = {f["record"] for f in (res.get("time_records") or {}).get("flagged", [])}
    out = []
    for r in ds.records:
        if r.name in known:
            continue
        if r.kind == "time":
            miss = [c for c in ("xdd", "ydd") if not r.has(c)]
            if miss:
                out.append({"record": r.name, "reason": f"no {' or '.join(repr(c) for c in miss)} column: the play "
                            "(rattle) statistic cannot use this record"})
        if r.kind in ("link", "time") and r.meta.get("periodic") is False:
            out.append({"record": r.name, "reason": "not periodic (no dominant frequency found): no harmonic "
                        "analysis of this record"})
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
    a = res["attribution"]
    return {"structural": a["structural"], "effects": a["effects"], "text": a["verdict"],
            "unexplained": a.get("unexplained", False), "unexplained_share": a.get("unexplained_share"),
            "parameters": {k: {"value": v, "std": a["std"].get(k)} for k, v in a["params"].items()},
            "held_out": {"gap_closed": res["held_out"]["gap_closed"]}, "sources": {"frc_records": res["records"]},
            "disagreements": [], "rejected": []}


@cli_main("diagnose")
def main_diagnose(argv=None):
    ap = argparse.ArgumentParser(prog="diagnose", description="Localise, attribute and quantify the gap "
                                 "between a nominal model and measurements (see docs/diagnose.md).")
    ap.add_argument("dataset", help="folder with dataset.yaml and CSV records")
    ap.add_argument("--model", help="YAML with the nominal model (overrides the dataset's 'nominal')")
    ap.add_argument("--out", required=True, help="output folder (report.md, diagnosis.json, PNGs): new, empty, or "
                    "a previous diagnose result (replaced as a whole)")
    a = ap.parse_args(argv)
    out = check_out_folder(a.out, "diagnose", DIAGNOSE_MARKER)
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        res = run_diagnosis(a.dataset, tmp, a.model)
    if "verdict" in res:
        print(res["verdict"]["text"])
        for d in res["verdict"].get("disagreements", []):
            print("note:", d)
    else:
        print(res["attribution"]["verdict"])
    for line in flagged_lines(res):
        print("flagged:", line)
    for r in res.get("input_reduced", []):
        print(f"reduced: {r['record']}: {r['rows']:,} rows -> {r['samples']:,} samples (averages of {r['block']})")
    h = res.get("held_out")
    if h and "nrmse_before" in h:
        gc = h["gap_closed"]
        print(f"held-out NRMSE {h['nrmse_before']:.4f} -> {h['nrmse_after']:.4f}"
              + ("" if gc is None else f", gap closed {100 * gc:.1f} %"))
    print(f"report: {out / 'report.md'}")
    return 0


@cli_main("make-benchmark")
def main_make_benchmark(argv=None):
    from .benchmark import make_benchmark

    ap = argparse.ArgumentParser(prog="make-benchmark", description="Generate withheld-effect datasets "
                                 "(labels in OUT/manifest.json, never read by diagnose and never printed).")
    ap.add_argument("--out", required=True, help="output folder: new, empty, or a previous make-benchmark result")
    ap.add_argument("--suite", choices=["system", "link"], default="system",
                    help="system: the coupled base + TMD simulated and measured as a rig does (default); "
                         "link: one TMD link on a displacement-controlled rig")
    ap.add_argument("-n", type=int, default=None, help="number of datasets (default: system 52, link 40)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--clean-fraction", type=float, default=0.25)
    ap.add_argument("--pair-fraction", type=float, default=0.2)
    ap.add_argument("--noise", type=float, default=0.5, help="link suite: force noise std [N]")
    a = ap.parse_args(argv)
    if a.n is not None and a.n < 1:
        raise InputError(f"-n {a.n}: the number of datasets must be >= 1")
    for name, v in (("--clean-fraction", a.clean_fraction), ("--pair-fraction", a.pair_fraction)):
        if not 0.0 <= v <= 1.0:
            raise InputError(f"{name} {v}: must be in [0, 1]")
    if a.clean_fraction + a.pair_fraction > 1.0:
        raise InputError(f"--clean-fraction + --pair-fraction = {a.clean_fraction + a.pair_fraction:g}: must be <= 1")
    if not a.noise >= 0.0 or a.noise == float("inf"):
        raise InputError(f"--noise {a.noise}: must be a finite force noise std >= 0 N")
    out = check_out_folder(a.out, "make-benchmark", BENCHMARK_MARKER)
    with ResultFolder(out, BENCHMARK_MARKER) as tmp:
        if a.suite == "system":
            from .sysbench import make_system_benchmark

            # progress without the labels: a blind benchmark does not print what it hides
            man = make_system_benchmark(tmp, n=a.n, seed=a.seed, progress=lambda r: print(
                f"{r['dataset']}: written" + (f" ({r['seconds']:.1f} s)" if "seconds" in r else ""), flush=True))
        else:
            man = make_benchmark(tmp, n=40 if a.n is None else a.n, seed=a.seed, clean_fraction=a.clean_fraction,
                                 pair_fraction=a.pair_fraction, noise=a.noise)
    print(f"wrote {len(man)} {'system' if a.suite == 'system' else 'link'}-level datasets and manifest.json "
          f"(the hidden labels) to {out}")
    return 0


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


@cli_main("score")
def main_score(argv=None):
    from .benchmark import score

    ap = argparse.ArgumentParser(prog="score", description="Run diagnose on a benchmark and score it.")
    ap.add_argument("benchmark", help="folder written by make-benchmark")
    ap.add_argument("--out", help="write score.json here (a new file, or a previous score.json)")
    a = ap.parse_args(argv)
    load_manifest(Path(a.benchmark))
    if a.out:
        o = Path(a.out)
        if o.is_dir():
            raise InputError(f"--out {o}: is a folder; give a file name for score.json")
        if o.exists():
            try:
                prev = json.loads(o.read_text(encoding="utf-8"))
                ours = isinstance(prev, dict) and {"summary", "rows"} <= set(prev)
            except (ValueError, OSError):
                ours = False
            if not ours:
                raise InputError(f"--out {o}: the file exists and is not a previous score result: choose a new name "
                                 "(score never overwrites files it did not write)")
    res = score(Path(a.benchmark), progress=lambda r: print(
        f"{r['dataset']}: hidden {r['hidden'] or '-'} found {r['found'] or '-'} {'ok' if r['correct'] else 'WRONG'}"))
    print(json.dumps(res["summary"], indent=1))
    if res.get("suite") == "system":  # the system suite's table (OOV classes, unexplained), docs/diagnose.md
        from .sysscore import table
        print(table(res["summary"]))
    if a.out:
        tmp = Path(a.out).with_name(f".{Path(a.out).name}.partial-{os.getpid()}")
        tmp.write_text(json.dumps(res, indent=1))
        os.replace(tmp, a.out)
    return 0
