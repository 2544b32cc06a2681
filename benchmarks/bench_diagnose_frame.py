"""Score ``diagnose`` on a frame benchmark (issue 41):

    make-benchmark --suite frame --out BENCH [--seed S] [-n N]
    nice python benchmarks/bench_diagnose_frame.py BENCH --out RESULTS [--code SOURCE_TREE] [--resume]
        [--only fr003,fr007] [--timeout 900]

Runs ``diagnose`` on every dataset of BENCH (its manifest.json, /work/notes/frame_contract.md), one
process at a time at nice 10, each as a child whose CPU time (user + sys) and peak memory (maxrss)
come from ``os.wait4``; ``--code`` is the source tree diagnose runs from (PYTHONPATH; default the tree
this script is in). A dataset diagnose refuses (exit status 2), fails, or does not finish within
``--timeout`` wall seconds is an error; the scorer goes on with the next one.

The four measures of the issue, each over every dataset of its class (an error counts as a failure
of the measure: not right for singles and pairs, a false effect for a clean dataset, confidently
wrong for an out-of-vocabulary one; the errors are also counted apart):

* singles right: exactly one effect named, the truth's (effect, element) -- target >= 90 %;
* pairs right: both true (effect, element) named -- target >= 75 %;
* clean false: a clean dataset with an effect named -- target <= 10 %;
* OOV confidently wrong: an effect named and ``unexplained`` false -- target <= 10 %;

and the worst CPU time and peak memory of one diagnosis (limits 120 s and 1 GB). ``verdict.ambiguous``
(alternatives explaining the data equally well) is reported apart: a dataset whose truth is only among
the alternatives is not counted right. Writes RESULTS/results.json (rewritten after every dataset, so a
stopped run can go on with ``--resume``), RESULTS/results.md, and each diagnosis under RESULTS/runs/.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

TARGETS = {
    "singles_right": (">=", 0.90),
    "pairs_right": (">=", 0.75),
    "clean_false": ("<=", 0.10),
    "oov_confidently_wrong": ("<=", 0.10),
}
LIMITS = {"worst_cpu_s": 120.0, "peak_rss_mb": 1024.0}
DIAGNOSE = "import sys; from pyfmu_wrapper.cli.diagnose import main_diagnose; sys.exit(main_diagnose())"


class Refused(Exception):
    """Bad command line or benchmark folder: one line on stderr, exit status 2."""


def load_manifest(bench: Path) -> dict:
    mf = bench / "manifest.json"
    if not mf.is_file():
        raise Refused(f"{mf}: file not found: {bench} is not a benchmark written by make-benchmark --suite frame")
    try:
        doc = json.loads(mf.read_text(encoding="utf-8"))
    except ValueError as e:
        raise Refused(f"{mf}: not valid JSON ({e})") from None
    if not isinstance(doc, dict) or doc.get("suite") != "frame" or not isinstance(doc.get("datasets"), list):
        raise Refused(f"{mf}: not a frame benchmark (needs suite 'frame' and a 'datasets' list)")
    for i, d in enumerate(doc["datasets"]):
        if not isinstance(d, dict) or not {"name", "class", "truth"} <= set(d):
            raise Refused(f"{mf}: datasets[{i}] needs keys 'name', 'class', 'truth'")
        if d["class"] not in ("clean", "single", "pair", "oov"):
            raise Refused(f"{mf}: datasets[{i}].class must be clean, single, pair or oov, got {d['class']!r}")
        if not (bench / str(d["name"]) / "dataset.yaml").is_file():
            raise Refused(f"{mf}: datasets[{i}]: {bench / str(d['name']) / 'dataset.yaml'} not found")
    if not doc["datasets"]:
        raise Refused(f"{mf}: the benchmark has no datasets")
    return doc


def run_one(ds: Path, out: Path, log: Path, code: Path, timeout: float, niceness: int) -> dict[str, Any]:
    """diagnose DS --out OUT as a child at ``niceness``: exit status, wall and CPU seconds, peak RSS."""
    env = dict(os.environ, PYTHONPATH=str(code))
    t0 = time.perf_counter()
    with log.open("w") as fo:
        p = subprocess.Popen(
            # -P: no current folder ahead of PYTHONPATH (a checkout there would shadow --code)
            [sys.executable, "-P", "-c", DIAGNOSE, str(ds.resolve()), "--out", str(out.resolve()), "--quiet"],
            stdout=fo,
            stderr=subprocess.STDOUT,
            env=env,
            preexec_fn=lambda: os.nice(niceness),  # noqa: PLW1509 - only os.nice, no threads in the parent
        )
        timed_out = False
        while True:
            pid, status, ru = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout:
                timed_out = True
                p.kill()
                _, status, ru = os.wait4(p.pid, 0)
                break
            time.sleep(0.2)
    p.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait again
    return {
        "exit": p.returncode,
        "timed_out": timed_out,
        "wall_s": round(time.perf_counter() - t0, 1),
        "cpu_s": round(ru.ru_utime + ru.ru_stime, 1),
        "peak_rss_mb": round(ru.ru_maxrss / 1024.0, 1),  # Linux: KiB
    }


def pairs_of(effects: list, elements: list | None) -> list[tuple[str, str | None]]:
    els = list(elements or [])
    return [(str(e), str(els[i]) if i < len(els) else None) for i, e in enumerate(effects or [])]


def score_row(m: dict, res: dict | None, run: dict) -> dict[str, Any]:
    """The row of one dataset: what was named, and the outcome of its class."""
    truth = [(t["effect"], t["element"]) for t in m["truth"]]
    row: dict[str, Any] = {
        "name": m["name"],
        "class": m["class"],
        "storeys": m.get("storeys"),
        "truth": [f"{e}@{el}" for e, el in truth],
        "oov_kind": m.get("oov_kind"),
        "visible_chi2": m.get("visible_chi2"),
        **run,
    }
    error = res is None
    v = (res or {}).get("verdict") or {}
    named = pairs_of(v.get("effects", []), v.get("elements"))
    unexplained = bool(v.get("unexplained", False))
    amb = [pairs_of(a.get("effects", []), a.get("elements")) for a in v.get("ambiguous") or [] if isinstance(a, dict)]
    row.update(
        error=error,
        named=[f"{e}@{el}" for e, el in named],
        unexplained=unexplained,
        text=str(v.get("text", ""))[:400],
        ambiguous=[[f"{e}@{el}" for e, el in a] for a in amb],
        truth_among_ambiguous=any(set(truth) <= set(a) for a in amb) if truth else False,
    )
    cls = m["class"]
    if cls == "single":
        row["right"] = not error and named == truth
        row["effect_right"] = not error and [e for e, _ in named] == [e for e, _ in truth]
    elif cls == "pair":
        row["right"] = not error and set(truth) <= set(named)
        row["exact"] = not error and sorted(named, key=str) == sorted(truth, key=str)
    elif cls == "clean":
        row["false_effect"] = error or bool(named)
    else:
        row["outcome"] = (
            "error" if error else "honest" if unexplained else "confidently_wrong" if named else "nothing_named"
        )
    perr = {}
    for t in m["truth"]:
        if (t["effect"], t["element"]) in named and t.get("value"):
            p = (v.get("parameters") or {}).get(f"{t['effect']}@{t['element']}.{t['param']}")
            est = p.get("value") if isinstance(p, dict) else p
            if isinstance(est, (int, float)):
                perr[f"{t['effect']}@{t['element']}"] = round(abs(est - t["value"]) / abs(t["value"]), 4)
    row["param_rel_error"] = perr
    return row


def _rate(rows: list, pred: Any) -> float | None:
    return round(sum(1 for r in rows if pred(r)) / len(rows), 4) if rows else None


def summarise(rows: list[dict]) -> dict[str, Any]:
    by = {c: [r for r in rows if r["class"] == c] for c in ("clean", "single", "pair", "oov")}
    s: dict[str, Any] = {
        "n": len(rows),
        **{f"n_{c}": len(v) for c, v in by.items()},
        "singles_right": _rate(by["single"], lambda r: r["right"]),
        "pairs_right": _rate(by["pair"], lambda r: r["right"]),
        "clean_false": _rate(by["clean"], lambda r: r["false_effect"]),
        "oov_confidently_wrong": _rate(by["oov"], lambda r: r["outcome"] in ("confidently_wrong", "error")),
        "singles_effect_right": _rate(by["single"], lambda r: r["effect_right"]),
        "pairs_exact": _rate(by["pair"], lambda r: r["exact"]),
        "oov_honest": _rate(by["oov"], lambda r: r["outcome"] == "honest"),
        "unexplained_on_clean_single_pair": _rate(by["clean"] + by["single"] + by["pair"], lambda r: r["unexplained"]),
        "errors": {c: sum(1 for r in v if r["error"]) for c, v in by.items()},
        "truth_only_among_ambiguous": sum(
            1 for r in by["single"] + by["pair"] if not r["right"] and r["truth_among_ambiguous"]
        ),
        "worst_cpu_s": max((r["cpu_s"] for r in rows), default=None),
        "median_cpu_s": round(statistics.median(r["cpu_s"] for r in rows), 1) if rows else None,
        "worst_wall_s": max((r["wall_s"] for r in rows), default=None),
        "peak_rss_mb": max((r["peak_rss_mb"] for r in rows), default=None),
    }
    perr = [e for r in rows for e in r["param_rel_error"].values()]
    s["param_rel_error_median"] = statistics.median(perr) if perr else None
    per: dict[str, dict[str, int]] = {}
    for r in by["single"]:
        d = per.setdefault(r["truth"][0].split("@")[0], {"n": 0, "right": 0})
        d["n"] += 1
        d["right"] += int(r["right"])
    s["singles_per_effect"] = dict(sorted(per.items()))
    po: dict[str, dict[str, int]] = {}
    for r in by["oov"]:
        d = po.setdefault(str(r["oov_kind"]), {})
        d[r["outcome"]] = d.get(r["outcome"], 0) + 1
    s["oov_per_kind"] = dict(sorted(po.items()))
    met = {}
    for k, (op, lim) in TARGETS.items():
        val = s[k]
        met[k] = {
            "target": f"{op} {lim:g}",
            "value": val,
            "met": None if val is None else (val >= lim if op == ">=" else val <= lim),
        }
    for k, lim in LIMITS.items():
        val = s[k]
        met[k] = {"target": f"<= {lim:g}", "value": val, "met": None if val is None else val <= lim}
    s["targets"] = met
    return s


def code_version(code: Path) -> dict[str, Any]:
    """The commit of the source tree diagnose runs from and whether its work tree differs (None: not git)."""
    try:
        head = subprocess.run(["git", "-C", str(code), "rev-parse", "HEAD"], capture_output=True, text=True, check=True)
        st = subprocess.run(
            ["git", "-C", str(code), "status", "--porcelain", "--untracked-files=no"],
            capture_output=True,
            text=True,
            check=True,
        )
    except (OSError, subprocess.CalledProcessError):
        return {"code_commit": None, "code_dirty": None}
    return {"code_commit": head.stdout.strip(), "code_dirty": bool(st.stdout.strip())}


def outcome_of(r: dict) -> str:
    """One word for a row: error, right / WRONG (singles, pairs), ok / false effect (clean), the OOV outcome."""
    if r["error"]:
        return "error" + (" (timeout)" if r.get("timed_out") else "")
    if r["class"] == "oov":
        return str(r["outcome"])
    if r["class"] == "clean":
        return "false effect" if r["false_effect"] else "ok"
    return "right" if r["right"] else "WRONG"


def markdown(doc: dict) -> str:
    s = doc["summary"]
    pct = lambda v: "-" if v is None else f"{100 * v:.0f} %"  # noqa: E731
    lines = [
        f"# Frame benchmark: {doc['bench']} (seed {doc['seed']})",
        "",
        f"diagnose from {doc['code']} (commit {doc.get('code_commit')}{', modified' if doc.get('code_dirty') else ''}); "
        f"{s['n']} datasets ({s['n_clean']} clean, {s['n_single']} singles, "
        f"{s['n_pair']} pairs, {s['n_oov']} out of vocabulary); load average {doc['load']}; "
        "an error counts as a failure of its class's measure.",
        "",
        "| measure | value | target | met |",
        "|---|---|---|---|",
    ]
    for k, t in s["targets"].items():
        val = t["value"]
        shown = pct(val) if k in TARGETS else ("-" if val is None else f"{val:g}")
        ok = "-" if t["met"] is None else "yes" if t["met"] else "NO"
        lines.append(f"| {k} | {shown} | {t['target']} | {ok} |")
    lines += [
        "",
        f"errors per class: {s['errors']}; truth only among the ambiguous alternatives: "
        f"{s['truth_only_among_ambiguous']}; singles with the right effect (any element): {pct(s['singles_effect_right'])}; "
        f"pairs exact: {pct(s['pairs_exact'])}; OOV honest (unexplained): {pct(s['oov_honest'])}; "
        f"unexplained on clean/single/pair: {pct(s['unexplained_on_clean_single_pair'])}; median parameter error "
        f"of the right ones: {s['param_rel_error_median']}; median CPU {s['median_cpu_s']} s.",
        "",
        "| dataset | class | storeys | truth | named | unexplained | outcome | chi2 | CPU s | RSS MB | exit |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in doc["rows"]:
        outcome = outcome_of(r)
        truth = ", ".join(r["truth"]) or (r["oov_kind"] or "-")
        lines.append(
            f"| {r['name']} | {r['class']} | {r['storeys']} | {truth} | {', '.join(r['named']) or '-'} | "
            f"{r['unexplained']} | {outcome} | {r['visible_chi2']:.3g} | {r['cpu_s']} | {r['peak_rss_mb']} | {r['exit']} |"
        )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bench", help="folder written by make-benchmark --suite frame")
    ap.add_argument("--out", required=True, help="results folder: new, empty, or a previous results folder")
    ap.add_argument("--code", default=str(Path(__file__).resolve().parents[1]), help="source tree diagnose runs from")
    ap.add_argument(
        "--resume",
        action="store_true",
        help="keep the rows of a previous results.json in --out (those datasets are not diagnosed again, "
        "except the ones --only names)",
    )
    ap.add_argument("--only", default=None, help="comma-separated dataset names (default: all)")
    ap.add_argument("--timeout", type=float, default=900.0, help="wall seconds per diagnosis before it is killed")
    ap.add_argument("--nice", type=int, default=10, help="niceness of each diagnose process (default 10)")
    a = ap.parse_args(argv)
    try:
        bench, out, code = Path(a.bench), Path(a.out), Path(a.code)
        if not bench.is_dir():
            raise Refused(f"{bench}: not a folder (give a folder written by make-benchmark --suite frame)")
        doc = load_manifest(bench)
        if not (code / "pyfmu_wrapper" / "__init__.py").is_file():
            raise Refused(f"--code {code}: not a source tree (no pyfmu_wrapper/__init__.py)")
        if not a.timeout > 0:
            raise Refused(f"--timeout {a.timeout}: must be > 0 s")
        if out.exists() and (not out.is_dir() or (any(out.iterdir()) and not (out / "results.json").is_file())):
            raise Refused(f"--out {out}: exists and is not an empty folder or a previous results folder")
        names = [d["name"] for d in doc["datasets"]]
        if a.only:
            want = [x.strip() for x in a.only.split(",") if x.strip()]
            bad = sorted(set(want) - set(names))
            if bad:
                raise Refused(f"--only: unknown dataset(s) {bad}; the benchmark has {names[0]}..{names[-1]}")
            names = [x for x in names if x in want]
    except Refused as e:
        print(f"bench_diagnose_frame: error: {e}", file=sys.stderr)
        return 2
    (out / "runs").mkdir(parents=True, exist_ok=True)
    done: dict[str, dict] = {}
    if a.resume and (out / "results.json").is_file():
        done = {r["name"]: r for r in json.loads((out / "results.json").read_text())["rows"]}
    by_name = {d["name"]: d for d in doc["datasets"]}
    order = {d["name"]: i for i, d in enumerate(doc["datasets"])}
    # rows of a resumed run outside --only are kept: results.json always holds every dataset scored
    rows: list[dict] = [r for n, r in done.items() if n not in names and n in order]
    res_doc: dict[str, Any] = {"bench": str(bench), "seed": doc.get("seed"), "code": str(code), **code_version(code)}
    for name in names:
        if name in done and not a.only:
            rows.append(done[name])
            continue
        run = run_one(bench / name, out / "runs" / name, out / "runs" / f"{name}.log", code, a.timeout, a.nice)
        res = None
        dj = out / "runs" / name / "diagnosis.json"
        if run["exit"] == 0 and dj.is_file():
            try:
                res = json.loads(dj.read_text())
            except ValueError:
                res = None
        if res is None:
            tail = (out / "runs" / f"{name}.log").read_text(errors="replace").strip().splitlines()[-3:]
            run["message"] = " | ".join(tail)[-400:]
        row = score_row(by_name[name], res, run)
        rows.append(row)
        rows.sort(key=lambda r: order[r["name"]])
        brief = outcome_of(row)
        print(
            f"{name} {row['class']}: named {row['named'] or '-'} unexplained={row['unexplained']} {brief} "
            f"(CPU {run['cpu_s']} s, {run['peak_rss_mb']} MB, exit {run['exit']})",
            flush=True,
        )
        res_doc.update(load=round(os.getloadavg()[0], 2), rows=rows, summary=summarise(rows))
        (out / "results.json").write_text(json.dumps(res_doc, indent=1))
    rows.sort(key=lambda r: order[r["name"]])
    res_doc.update(load=round(os.getloadavg()[0], 2), rows=rows, summary=summarise(rows))
    (out / "results.json").write_text(json.dumps(res_doc, indent=1))
    (out / "results.md").write_text(markdown(res_doc))
    print(markdown(res_doc).split("\n\n| dataset")[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
