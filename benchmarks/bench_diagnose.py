"""Full-size checks of ``diagnose`` (numbers recorded in docs/diagnose.md and benchmarks/README.md).

    python benchmarks/bench_diagnose.py [--out /tmp/bench_diagnose] [-n 40] [--seed 11] [--skip-link]

1. System suite (``make-benchmark --suite system``): n datasets simulated with the project's solver
   and measured as a rig does; ``score`` prints top-1 on single effects, false positives on clean
   sets, pairs with both named, median parameter error and held-out gap closed, per effect.
2. Speed: the wall time of each ``diagnose`` of four time records + an FRC, against the time of one
   steady-state FRC sweep (21 points, Case 1) measured in the same run (the ratio is what carries
   over between machines and loads).
3. The link suite (40 datasets) and the BRFD measurements (data/brfd_link).
4. Speed target of issues 19 and 31: one ``diagnose`` of 6 steady time records + 2 FRCs (at 200
   and 100 N; issue 31: <= 30 s median, <= 90 s worst on the 2-core machine, peak <= 1 GB), for a clean set, an in-vocabulary effect, an FRC-led effect (cubic) and an
   out-of-vocabulary x-sensor gain (every candidate then gets its FRC fit: the slowest path); the
   wall time, the CPU time and peak memory of the ``diagnose`` child process, the same ratio against
   the sweep baseline and the load average are recorded.

    python benchmarks/bench_diagnose.py --speed-only [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from pyfmu_wrapper.diagnose.link.benchmark import make_benchmark, score
from pyfmu_wrapper.diagnose.run import run_diagnosis
from pyfmu_wrapper.diagnose.system.suite import make_system_benchmark

ROOT = Path(__file__).resolve().parents[1]


def sweep_baseline():
    from pyfmu_wrapper.models.solve import steady_state
    from pyfmu_wrapper.physics.params import BaseParams, paper_case

    tmd = paper_case(1, damping=15.0, friction_force=3.0)
    t0 = time.perf_counter()
    hint = {}
    for w in np.linspace(15, 25, 21):
        steady_state(BaseParams(), tmd, float(w), hint=hint)
    return time.perf_counter() - t0


def speed_six_records(out: Path) -> dict:
    """Wall time, CPU time and peak memory of one ``diagnose`` (a child process, as users run it) of
    6 steady time records + 2 FRCs (issue 31: median <= 30 s, worst <= 90 s, peak <= 1 GB)."""
    import os
    import subprocess
    import sys

    import pandas as pd
    import yaml

    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset

    rows = {}
    exe = Path(sys.executable).with_name("diagnose")
    for name, hidden, gain in (
        ("clean", {}, 0.0),
        ("viscous", {"viscous": 6.0}, 0.0),
        ("cubic", {"cubic": 1e5}, 0.0),
        ("x_gain_oov", {}, 0.03),
    ):
        d = out / "speed6" / name
        if not (d / "dataset.yaml").is_file():
            make_system_dataset(d, hidden, seed=61, case=1, n_records=6, frc=True, n_frc=2)
            if gain:
                for r in yaml.safe_load((d / "dataset.yaml").read_text())["records"]:
                    df = pd.read_csv(d / r["file"], comment="#")
                    for c in ("x", "x_max"):
                        if c in df:
                            df[c] *= 1 + gain
                    df.to_csv(d / r["file"], index=False, float_format="%.9g")
        b0 = sweep_baseline()
        load0 = os.getloadavg()[0]
        res_dir = out / "speed6" / f"{name}.out"
        t0 = time.perf_counter()
        with (out / "speed6" / f"{name}.log").open("w") as fo:  # wait4: the child's own CPU and peak memory
            p = subprocess.Popen([str(exe), str(d), "--out", str(res_dir)], stdout=fo, stderr=fo)
            _, status, ru = os.wait4(p.pid, 0)
        dt = time.perf_counter() - t0
        b1 = sweep_baseline()
        res = json.loads((res_dir / "diagnosis.json").read_text()) if (res_dir / "diagnosis.json").is_file() else {}
        verdict = res.get("verdict", {})
        rows[name] = {
            "seconds": round(dt, 2),
            "cpu_seconds": round(ru.ru_utime + ru.ru_stime, 2),
            "peak_rss_mb": round(ru.ru_maxrss / 1024),
            "exit": os.waitstatus_to_exitcode(status),
            "over_sweep": round(dt / (0.5 * (b0 + b1)), 1),
            "load_average_1min": round(0.5 * (load0 + os.getloadavg()[0]), 2),
            "effects": verdict.get("effects"),
            "unexplained": verdict.get("unexplained"),
        }
        print(name, rows[name], flush=True)
    secs = [r["seconds"] for r in rows.values()]
    rows["summary"] = {
        "shape": "6 steady time records + 2 FRCs (21 points at 200 N and 100 N)",
        "median_s": statistics.median(secs),
        "worst_s": max(secs),
        "median_cpu_s": statistics.median(r["cpu_seconds"] for r in rows.values() if "cpu_seconds" in r),
        "peak_rss_mb": max(r["peak_rss_mb"] for r in rows.values() if "peak_rss_mb" in r),
    }
    print(json.dumps(rows["summary"]), flush=True)
    return rows


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/bench_diagnose")
    ap.add_argument("-n", type=int, default=40)
    ap.add_argument("--seed", type=int, default=11)
    ap.add_argument("--skip-link", action="store_true")
    ap.add_argument("--speed-only", action="store_true", help="only the 6-record + 2-FRC timing (issues 19, 31)")
    a = ap.parse_args()
    out = Path(a.out)
    res = {}
    if a.speed_only:
        res["speed_6_records"] = speed_six_records(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "bench_speed6.json").write_text(json.dumps(res, indent=1))
        return
    res["speed_6_records"] = speed_six_records(out)
    t0 = time.perf_counter()
    make_system_benchmark(out / "system", n=a.n, seed=a.seed)
    t1 = time.perf_counter()
    base0 = sweep_baseline()
    sc = score(
        out / "system",
        progress=lambda r: print(
            f"{r['dataset']}: hidden {r['hidden'] or '-'} found {r['found'] or '-'} "
            f"{'ok' if r['correct'] else 'WRONG'} ({r['seconds']:.1f} s)",
            flush=True,
        ),
    )
    base1 = sweep_baseline()
    secs = [r["seconds"] for r in sc["rows"]]
    sc["summary"].update(
        generate_s=round(t1 - t0, 1),
        score_s=round(sum(secs), 1),
        baseline_sweep_s=round(0.5 * (base0 + base1), 3),
        diagnose_over_sweep_median=round(statistics.median(secs) / (0.5 * (base0 + base1)), 1),
        diagnose_over_sweep_max=round(max(secs) / (0.5 * (base0 + base1)), 1),
    )
    print(json.dumps(sc["summary"], indent=1))
    res["system"] = sc
    if not a.skip_link:
        make_benchmark(out / "link", n=40, seed=1)
        sl = score(out / "link")
        print(json.dumps({k: v for k, v in sl["summary"].items() if k != "per_effect"}, indent=1))
        res["link"] = sl
    t3 = time.perf_counter()
    brfd = run_diagnosis(ROOT / "data" / "brfd_link", out=out / "brfd_report")
    t4 = time.perf_counter()
    res["brfd"] = {
        "verdict": brfd["attribution"]["verdict"],
        "params": brfd["attribution"]["params"],
        "held_out": brfd["held_out"],
        "seconds": round(t4 - t3, 1),
    }
    print(json.dumps(res["brfd"], indent=1, default=str))
    (out / "bench_diagnose.json").write_text(json.dumps(res, indent=1, default=str))


if __name__ == "__main__":
    main()
