"""Speed and memory of ``diagnose`` on transient records (issue 31):

    nice python benchmarks/bench_diagnose_transient.py [--out /tmp/bench_transient] [--seconds 120] [--fs 4000]
        [--compare OLD_SOURCE_TREE]

With ``--compare`` (a checkout of the code to compare with, e.g. ``git archive main | tar -x -C OLD``)
every dataset is also diagnosed by that code (PYTHONPATH=OLD, same interpreter and packages), side
by side. Each row gives wall time and the child's CPU time (user + sys: less sensitive to the load
of a shared machine; with threads it can exceed the wall time).

Four datasets of 4 transient records each (an up-sweep, a log down-sweep, band-limited random force,
a free decay), ``--seconds`` long at ``--fs`` Hz, measured with a declared 4th-order Butterworth on
the accelerometers and 1 % noise, truths: clean, extra damping 10 N s/m, dry friction 5 N, OOV
quadratic damping c2 = 20 N s^2/m^2 (simulated by transient_truth's own odeint integrator, on the
record's own grid). Each ``diagnose`` runs as a separate process (``python -m pyfmu_wrapper.cli``
is not needed: the console script), timed by wall clock, its peak memory and CPU time from ``os.wait4`` of
the child. The baseline measured in the same run: one steady-state FRC sweep (21 points, Case 1), as in
bench_diagnose.py, so that the ratio carries over between machines and loads.
Targets: median <= 30 s, worst <= 90 s, peak memory <= 1 GB (2-core machine, low load).
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

import numpy as np
import yaml

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
FILT = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 400.0}}
TRUTHS = {"clean": {}, "viscous": {"dc": 10.0}, "friction": {"df": 5.0}, "quadratic_damping": {"c2": 20.0}}
KINDS = [
    ("sweep_lin", {"f0": 1.5, "f1": 5.0}),
    ("sweep_log", {"f0": 5.0, "f1": 1.5}),
    ("random", {"f_lo": 1.0, "f_hi": 8.0, "amp": 60.0}),
    ("decay", {}),
]


def make(path: Path, changes: dict, T: float, fs: float, seed: int) -> None:
    from pyfmu_wrapper.diagnose.records import write_record
    from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    acq = {"xdd": FILT, "ydd": FILT}
    recs = []
    for i, (kind, kw) in enumerate(KINDS):
        kw = dict(kw)
        t = np.arange(0.0, T, 1.0 / fs)
        F = force_signal(kind, rng, T, kw.pop("amp", 150.0), **kw)
        z0 = np.array([0.005, 0.0, 0.01, 0.0]) if kind == "decay" else None
        sig = Truth(BASE, TMD, T, **changes).simulate(F, t, z0)
        if kind == "decay":
            sig.pop("force")
        m = measure(sig, t, 1, rng, {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}, acq)
        write_record(path / f"r{i}.csv", m)
        recs.append({"file": f"r{i}.csv", "kind": "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": acq}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))


def sweep_baseline() -> float:
    from pyfmu_wrapper.models.solve import steady_state
    from pyfmu_wrapper.physics.params import BaseParams, paper_case

    base, tmd = BaseParams(), paper_case(1)
    steady_state(base, tmd, 20.0)  # compile
    t0 = time.perf_counter()
    for w in np.linspace(15, 25, 21):
        steady_state(base, tmd, float(w))
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/bench_transient")
    ap.add_argument("--seconds", type=float, default=120.0)
    ap.add_argument("--fs", type=float, default=4000.0)
    ap.add_argument("--compare", default=None, help="source tree of the code to compare with (PYTHONPATH)")
    a = ap.parse_args()
    out = Path(a.out)
    rows = []
    base = sweep_baseline()
    exe = Path(sys.executable).with_name("diagnose")
    for k, (name, ch) in enumerate(TRUTHS.items()):
        ds = out / name
        if not (ds / "dataset.yaml").is_file():
            t0 = time.perf_counter()
            make(ds, ch, a.seconds, a.fs, seed=k)
            print(f"{name}: generated in {time.perf_counter() - t0:.0f} s", flush=True)
        for code, tree in (("new", None), ("old", a.compare)):
            if code == "old" and not tree:
                continue
            res_dir = out / f"{name}.{code}.out"
            env = dict(os.environ, **({"PYTHONPATH": str(tree)} if tree else {}))
            t0 = time.perf_counter()
            log = out / f"{name}.{code}.log"
            with log.open("w") as fo:  # wait4: this child's own CPU time and peak memory
                p = subprocess.Popen([str(exe), str(ds), "--out", str(res_dir)], stdout=fo, stderr=fo, env=env)
                _, status, ru = os.wait4(p.pid, 0)
            wall = time.perf_counter() - t0
            cpu = ru.ru_utime + ru.ru_stime
            text = log.read_text().strip()
            verdict = text[-300:]  # the failure's message; on success the verdict's first sentence
            if os.waitstatus_to_exitcode(status) == 0 and (res_dir / "diagnosis.json").is_file():
                verdict = json.loads((res_dir / "diagnosis.json").read_text())["verdict"]["text"].split("; it ")[0]
            row: dict[str, Any] = {
                "dataset": name,
                "code": code,
                "seconds": round(wall, 1),
                "cpu_seconds": round(cpu, 1),
                "ratio_to_sweep": round(wall / base, 1),
                "peak_rss_mb": round(ru.ru_maxrss / 1024, 0),
                "exit": os.waitstatus_to_exitcode(status),
                "verdict": verdict,
                "load": os.getloadavg()[0],
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    summary: dict = {"records": f"4 x {a.seconds:g} s at {a.fs:g} Hz", "sweep_baseline_s": round(base, 2)}
    for code in ("new", "old"):
        rs = [r for r in rows if r["code"] == code]
        if rs:
            summary[code] = {
                "median_s": statistics.median(r["seconds"] for r in rs),
                "worst_s": max(r["seconds"] for r in rs),
                "median_cpu_s": statistics.median(r["cpu_seconds"] for r in rs),
                "worst_cpu_s": max(r["cpu_seconds"] for r in rs),
                "peak_rss_mb": max(r["peak_rss_mb"] for r in rs),
            }
    print(json.dumps(summary))
    (out / "bench_transient.json").write_text(json.dumps({"rows": rows, "summary": summary}, indent=1))


if __name__ == "__main__":
    main()
