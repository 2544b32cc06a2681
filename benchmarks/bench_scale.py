"""Co-simulation against the monolithic engine at scale (issue 42), whole ``run-scenario`` commands side by side.

    python benchmarks/bench_scale.py [--rounds 3] [--only frame20_tmd ...]

For each scenario, ``run-scenario SCENARIO --engine cosim`` and ``--engine monolithic`` (default executor: a
process per curve on every core, as a user runs it) are started in turn, A B A B ..., each a fresh process (its
imports, its workers, its FMU checks included; the FMUs are built once before, outside the timing), after one
warm-up pair. Wall and CPU seconds (the children's, from ``getrusage``) per run; the ratio cosim / monolithic is
taken pair by pair and its median reported, with the machine's load average before and after (the machine is
shared: a ratio in the same run, never an absolute time, is the figure).

Scenarios and targets (issue 42):

* ``scenarios/full_case1.yaml``: the paper's Case 1, 6 curves (two with the rattling play chain), 41 points each;
  target <= 1.0;
* ``benchmarks/scenarios/frame20_tmd.yaml``: a 20-storey frame with its TMD-inerter, 2 x 83 points; target <= 2;
* ``scenarios/frame10_tmd.yaml``: the 10-storey benchmark, 2 x 81 points; target <= 1.35.

Results: benchmarks/results/bench_scale.json.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = {
    "full_case1": (ROOT / "scenarios" / "full_case1.yaml", 1.0),
    "frame20_tmd": (ROOT / "benchmarks" / "scenarios" / "frame20_tmd.yaml", 2.0),
    "frame10_tmd": (ROOT / "scenarios" / "frame10_tmd.yaml", 1.35),
}


def run(path: Path, engine: str, out: Path) -> tuple[float, float]:
    """(wall, cpu) seconds of one run-scenario process and its children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    cmd = [sys.executable, "-m", "pyfmu_wrapper.cli.run_scenario", str(path), "--engine", engine]
    subprocess.run([*cmd, "--out", str(out), "--quiet", "--no-resume"], check=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--only", nargs="*", choices=sorted(SCENARIOS), default=sorted(SCENARIOS))
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "bench_scale.json"))
    args = ap.parse_args()
    from pyfmu_wrapper.fmubuild.native_build import ensure_native_fmus
    from pyfmu_wrapper.models.base_tmd.cosim import PAIR_FMUS
    from pyfmu_wrapper.models.frame_model.cosim import frame_fmus

    ensure_native_fmus(PAIR_FMUS)  # built once, outside the timing
    ensure_native_fmus(frame_fmus())
    result: dict = {"load_average_start": list(os.getloadavg()), "python": sys.version.split()[0], "scenarios": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.only:
            path, target = SCENARIOS[name]
            runs: dict[str, list[tuple[float, float]]] = {"cosim": [], "monolithic": []}
            for k in range(args.rounds + 1):
                for engine in ("cosim", "monolithic"):
                    wall, cpu = run(path, engine, Path(tmp) / f"{name}_{engine}_{k}")
                    if k:  # the first pair warms the caches
                        runs[engine].append((wall, cpu))
            pairs = list(zip(runs["cosim"], runs["monolithic"], strict=True))
            row = {
                "target": target,
                "ratio_wall": statistics.median(c[0] / m[0] for c, m in pairs),
                "ratio_cpu": statistics.median(c[1] / m[1] for c, m in pairs),
                "cosim_wall": [c[0] for c, _ in pairs],
                "monolithic_wall": [m[0] for _, m in pairs],
                "cosim_cpu": [c[1] for c, _ in pairs],
                "monolithic_cpu": [m[1] for _, m in pairs],
            }
            row["met"] = row["ratio_wall"] <= target
            result["scenarios"][name] = row
            print(
                f"{name}: cosim / monolithic wall {row['ratio_wall']:.2f}, cpu {row['ratio_cpu']:.2f} "
                f"(target <= {target}; medians of {args.rounds} pairs)",
                flush=True,
            )
    result["load_average_end"] = list(os.getloadavg())
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print("wrote", args.out, "load", result["load_average_start"], "->", result["load_average_end"])


if __name__ == "__main__":
    main()
