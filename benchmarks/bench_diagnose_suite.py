"""Score ``diagnose`` on a system, transient or link benchmark with each diagnosis's cost (issue 41,
"bounded": CPU median and worst per dataset of each suite, peak memory <= 1 GB):

    make-benchmark --suite transient --out BENCH [--seed S] [-n N] [--seconds 20]
    nice python benchmarks/bench_diagnose_suite.py BENCH --out RESULTS [--code SOURCE_TREE] [--resume]
        [--only tr003,tr007] [--timeout 900]

Runs ``diagnose`` on every dataset of BENCH one process at a time, each as a child whose CPU time
(user + sys) and peak memory (maxrss) come from ``os.wait4`` (the runner of
``bench_diagnose_frame.py``, which scores the frame suite), then scores the verdicts with the suite's
own scorer (``score``: top-1 of singles, false effects on clean datasets, pairs, out-of-vocabulary
honesty, parameter errors). A dataset diagnose refuses, fails, or does not finish within
``--timeout`` wall seconds is scored as a failure. With ``--only`` or a run stopped early, only the
datasets diagnosed are scored (said in the summary).

Writes RESULTS/results.json (rewritten after every dataset; ``--resume`` goes on from it) and each
diagnosis under RESULTS/runs/.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling script, also when loaded by path
from bench_diagnose_frame import LIMITS, run_one  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def _score(bench: Path, results: dict[str, Any]) -> dict[str, Any]:
    """The suite's scorer on the datasets that have a verdict (the others are left out, not failed)."""
    import tempfile

    from pyfmu_wrapper.diagnose.link.benchmark import score

    doc = json.loads((bench / "manifest.json").read_text(encoding="utf-8"))
    with tempfile.TemporaryDirectory() as tmp:  # a manifest of the diagnosed datasets only
        view = Path(tmp)
        doc["datasets"] = [d for d in doc["datasets"] if d["dataset"] in results]
        (view / "manifest.json").write_text(json.dumps(doc))
        for d in doc["datasets"]:
            (view / d["dataset"]).symlink_to((bench / d["dataset"]).resolve())
        return score(view, results)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bench", type=Path, help="folder written by make-benchmark (system, transient or link suite)")
    ap.add_argument("--out", type=Path, required=True, help="results folder (new, or a previous one with --resume)")
    ap.add_argument("--code", type=Path, default=ROOT, help="source tree diagnose runs from")
    ap.add_argument("--resume", action="store_true", help="keep the datasets of a previous results.json")
    ap.add_argument("--only", default="", help="comma-separated dataset names (default: all)")
    ap.add_argument("--timeout", type=float, default=900.0, help="wall seconds per diagnosis before it is killed")
    ap.add_argument("--nice", type=int, default=10, help="niceness of each diagnose process")
    a = ap.parse_args(argv)
    mf = a.bench / "manifest.json"
    try:
        man = json.loads(mf.read_text(encoding="utf-8"))["datasets"]
        names = [str(d["dataset"]) for d in man]
    except (OSError, ValueError, KeyError, TypeError) as e:
        print(f"bench_diagnose_suite: {mf}: not a make-benchmark manifest ({e})", file=sys.stderr)
        return 2
    if a.only:
        want = [s.strip() for s in a.only.split(",") if s.strip()]
        unknown = [s for s in want if s not in names]
        if unknown:
            print(f"bench_diagnose_suite: --only {unknown}: not in {mf}", file=sys.stderr)
            return 2
        names = [n for n in names if n in want]
    res_file = a.out / "results.json"
    if a.out.exists() and any(a.out.iterdir()) and not (a.resume and res_file.is_file()):
        print(f"bench_diagnose_suite: --out {a.out}: not empty (use a new folder, or --resume)", file=sys.stderr)
        return 2
    (a.out / "runs").mkdir(parents=True, exist_ok=True)
    costs: dict[str, dict[str, Any]] = json.loads(res_file.read_text())["costs"] if res_file.is_file() else {}
    results: dict[str, Any] = {}
    for name in names:
        run = a.out / "runs" / name
        if name not in costs or not (run / "diagnosis.json").is_file():
            costs[name] = run_one(a.bench / name, run, a.out / "runs" / f"{name}.log", a.code, a.timeout, a.nice)
            print(f"{name}: exit {costs[name]['exit']}, {costs[name]['cpu_s']} s CPU", flush=True)
        if (run / "diagnosis.json").is_file() and costs[name]["exit"] == 0:
            results[name] = json.loads((run / "diagnosis.json").read_text())
        res_file.write_text(json.dumps({"bench": str(a.bench), "costs": costs}, indent=1))
    cpu = [c["cpu_s"] for c in costs.values()]
    rss = [c["peak_rss_mb"] for c in costs.values()]
    out = {
        "bench": str(a.bench.resolve()),
        "diagnosed": len(costs),
        "of": len(man),
        "failed": sorted(n for n, c in costs.items() if c["exit"] != 0),
        "cpu_s": {"median": statistics.median(cpu), "worst": max(cpu)},
        "peak_rss_mb": max(rss),
        "limits": LIMITS,
        "costs": costs,
        "score": _score(a.bench, results) if results else None,
    }
    res_file.write_text(json.dumps(out, indent=1, default=str))
    s = out["score"]["summary"] if out["score"] else {}
    print(json.dumps({k: v for k, v in s.items() if not isinstance(v, (dict, list))}, indent=1))
    print(
        f"diagnosed {len(costs)} of {len(man)}; CPU median {out['cpu_s']['median']} s, worst {out['cpu_s']['worst']} s "
        f"(limit {LIMITS['worst_cpu_s']:g}); peak {out['peak_rss_mb']} MB (limit {LIMITS['peak_rss_mb']:g})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
