"""Full-size checks of ``diagnose`` (numbers recorded in docs/diagnose.md).

    python benchmarks/bench_diagnose.py [--out /tmp/bench_diagnose] [-n 40] [--n-system 12]

1. make-benchmark: n link-level datasets (25 % clean, 20 % with two hidden effects) and n_system
   system-level ones simulated with the monolithic solver; score prints top-1 accuracy, false
   positives on clean data, parameter errors and the held-out gap closed.
2. The BRFD measurements (data/brfd_link): attribution, held-out gap closed overall and per band.
"""
from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from pyfmu_wrapper.diagnose.benchmark import make_benchmark, score
from pyfmu_wrapper.diagnose.cli import run_diagnosis

ROOT = Path(__file__).resolve().parents[1]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/bench_diagnose")
    ap.add_argument("-n", type=int, default=40)
    ap.add_argument("--n-system", type=int, default=12)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise", type=float, default=0.5, help="link force noise [N] (0.5 default, 2.0 hard)")
    a = ap.parse_args()
    out = Path(a.out)
    t0 = time.perf_counter()
    make_benchmark(out / "bench", n=a.n, seed=a.seed, n_system=a.n_system, noise=a.noise)
    t1 = time.perf_counter()
    sc = score(out / "bench", progress=lambda r: None if r["correct"] else print("miss:", r))
    t2 = time.perf_counter()
    sys_rows = [r for r in sc["rows"] if r["dataset"].startswith("sys")]
    sc["summary"]["system_level_accuracy"] = (sum(r["correct"] for r in sys_rows) / len(sys_rows)) if sys_rows else None
    sc["summary"]["generate_s"], sc["summary"]["score_s"] = round(t1 - t0, 1), round(t2 - t1, 1)
    print(json.dumps(sc["summary"], indent=1))
    t3 = time.perf_counter()
    brfd = run_diagnosis(ROOT / "data" / "brfd_link", out=out / "brfd_report")
    t4 = time.perf_counter()
    b = {"verdict": brfd["attribution"]["verdict"], "params": brfd["attribution"]["params"],
         "std": brfd["attribution"]["std"], "held_out": brfd["held_out"],
         "ranking": [(c["effects"], round(c["delta_bic"], 1), c["gap_closed"]) for c in brfd["candidates"][:8]],
         "seconds": round(t4 - t3, 1)}
    print(json.dumps(b, indent=1))
    (out / "bench_diagnose.json").write_text(json.dumps({"benchmark": sc, "brfd": b}, indent=1))


if __name__ == "__main__":
    main()
