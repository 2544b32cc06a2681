"""Wall time of the paper-resolution maps with the map executors (numbers recorded in docs/reproduction.md).

    python benchmarks/bench_maps.py [--jobs 2] [--which fig4a fig5a] [--executor local]

fig4a: scenarios/paper/fig4_case1.yaml, study friction_map (df 0..100 N x omega, 51 x 101, Case 1);
fig5a: scenarios/paper/fig5_case1.yaml, study play_map (eps 0..2e-3 m x omega, 51 x 101, Case 1).
Targets: fig4a <= 60 s and fig5a <= 10 min on 2 cores. Each map is computed from scratch (no
checkpoint is read, but the finished rows are checkpointed where ``reproduce``
looks for them, results/paper/.cache/<scenario>/<study>/, so the report reuses them); the map is written to benchmarks/results/bench_maps_<which>.csv and the timings
to benchmarks/results/bench_maps.json (merged with earlier entries).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from pyfmu_wrapper.scenario import load_scenario
from pyfmu_wrapper.scenario.engines import RunSettings
from pyfmu_wrapper.scenario.executors import make_executor
from pyfmu_wrapper.scenario.runner import _Cache, map_response
from pyfmu_wrapper.scenario.tasks import code_version

ROOT = Path(__file__).resolve().parents[1]
MAPS = {
    "fig4a": ("scenarios/paper/fig4_case1.yaml", "friction_map"),
    "fig5a": ("scenarios/paper/fig5_case1.yaml", "play_map"),
}


def bench(which: str, jobs: int, executor_name: str, scheduler=None) -> dict:
    path, study_name = MAPS[which]
    scn = load_scenario(ROOT / path)
    study = next(s for s in scn.studies if s.name == study_name)
    settings = RunSettings.for_scenario(scn)
    ex = make_executor(executor_name, jobs=jobs, scheduler=scheduler)
    ckpt = ROOT / "results" / "paper" / ".cache" / scn.name
    from tqdm import tqdm

    try:
        with tqdm(total=len(study.values) * len(study.omegas), desc=which, unit="pt") as bar:
            t0 = time.perf_counter()
            data = map_response(scn, study, settings, bar.update, _Cache(ex, ckpt, resume=False))
            wall = time.perf_counter() - t0
    finally:
        ex.close()
    t = data.table
    out = ROOT / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    t.to_csv(out / f"bench_maps_{which}.csv", index=False, float_format="%.8g")
    return dict(
        scenario=path,
        study=study_name,
        values=len(study.values),
        omegas=len(study.omegas),
        points=int(len(t)),
        executor=ex.describe(),
        jobs=jobs,
        wall_s=round(wall, 2),
        cpu_s_in_solver=round(float(t["wall_time"].sum()), 1),
        ms_per_point=round(1e3 * wall / len(t), 2),
        not_converged=int((~t["converged"].astype(bool)).sum()),
        periods_mean=float(t["periods"].mean()),
        settings=settings.used(),
        cpu_count=os.cpu_count(),
        machine=platform.processor() or platform.machine(),
        date=time.strftime("%Y-%m-%d %H:%M:%S"),
        created=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()),
        code_version=code_version(),
    )


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--which", nargs="+", default=["fig4a"], choices=sorted(MAPS))
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--executor", default="local", choices=["local", "dask", "sequential"])
    ap.add_argument("--scheduler", default=None)
    a = ap.parse_args()
    res_file = ROOT / "benchmarks" / "results" / "bench_maps.json"
    results = json.loads(res_file.read_text()) if res_file.exists() else {}
    for w in a.which:
        r = bench(w, a.jobs, a.executor, a.scheduler)
        print(json.dumps(r, indent=2))
        results[w] = r
        res_file.parent.mkdir(parents=True, exist_ok=True)
        res_file.write_text(json.dumps(results, indent=2) + "\n")


if __name__ == "__main__":
    main()
