"""Peak memory of ``diagnose`` on a very long record (issue 17: a 10-million-row CSV took 3 min
silently and 19.9 GB peak).

    python benchmarks/bench_diagnose_memory.py [--kind link|system] [--rows 10000000] [--keep DIR]

Generates a link-level record with ``--rows`` rows (t, displacement, force; about 35 bytes a row,
~350 MB for 10 million) of the link suite's nominal TMD link (k = 4e3 N/m, c = 40 N s/m, I = 1 kg)
with a hidden dry friction df = 6 N, driven at w = 20 rad/s, 20 mm, sampled at 100 kHz, force noise
0.5 N. Then runs ``diagnose`` on it in a subprocess and reports its wall time and peak resident
memory (``ru_maxrss`` of the child), next to the same run on a baseline record of 100,000 rows
(below the decimation threshold, read whole) made in the same run: the ratio shows whether memory
grows with the record length. Target: <= 2 GB for 10 million rows. The verdict and the fitted
friction force are checked too (the reduction must not change the answer).

``--kind system``: a system-level dataset instead: one long time record (t, force, x, y, xdd, ydd;
~70 bytes a row, 100 kHz) and two short ones (20,000 rows at 2 kHz) of the linear base + TMD (M = 100 kg,
K = 4e4 N/m, C = 100 N s/m; m = 9 kg, k = 4e3 N/m, c = 15 N s/m, ideal inerter I = 1 kg) with a
hidden extra damping dc = 5 N s/m in the link, steady state from the exact 2-DOF frequency
response, forced at 200 N, with noise (x, y: 1e-6 m; xdd, ydd: 1e-3 m/s^2;
force: 0.05 N). The check: the verdict names ``viscous`` with dc within 5 %.

The generated data go to a temporary folder (removed at the end unless --keep); never commit them.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import yaml

from pyfmu_wrapper.diagnose.link.benchmark import NOMINAL, link_force

W, AMP, FS, DF, NOISE = 20.0, 0.02, 1.0e5, 6.0, 0.5


def write_record(folder: Path, rows: int, seed: int = 5, chunk: int = 1_000_000) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    path = folder / "long.csv"
    with open(path, "w") as fh:
        fh.write("# synthetic link record: friction df = 6 N hidden (bench_diagnose_memory.py)\n")
        fh.write("t,displacement,force\n")
        for i0 in range(0, rows, chunk):
            t = np.arange(i0, min(rows, i0 + chunk)) / FS
            d, v, a = AMP * np.sin(W * t), AMP * W * np.cos(W * t), -AMP * W * W * np.sin(W * t)
            F = link_force(d, v, a, {"friction": DF}) + rng.normal(0.0, NOISE, t.size)
            pd.DataFrame({"t": t, "d": d, "F": F}).to_csv(fh, header=False, index=False, float_format="%.9g")
    (folder / "dataset.yaml").write_text(
        yaml.safe_dump(
            {
                "level": "link",
                "description": f"{rows:,}-row synthetic link record",
                "nominal": dict(NOMINAL),
                "records": [{"file": "long.csv", "omega": W}],
            },
            sort_keys=False,
        )
    )
    return path


SYS_NOM = {
    "base": {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0},
    "tmd": {
        "mass": 9.0,
        "stiffness": 4.0e3,
        "damping": 15.0,
        "inertance": 1.0,
        "inerter": "ideal",
        "friction_force": 0.0,
    },
}
DC = 5.0
SYS_NOISE = {"force": 0.05, "x": 1e-6, "y": 1e-6, "xdd": 1e-3, "ydd": 1e-3}


def _sys_response(w):
    """Complex amplitudes (X, Y) of the linear base + TMD (link damping c + DC) under 200 cos(w t)."""
    b, t = SYS_NOM["base"], SYS_NOM["tmd"]
    zl = t["stiffness"] + 1j * w * (t["damping"] + DC) - t["inertance"] * w * w
    A = np.array(
        [[b["stiffness"] + 1j * w * b["damping"] - b["mass"] * w * w + zl, -zl], [-zl, -t["mass"] * w * w + zl]]
    )
    return np.linalg.solve(A, np.array([b["force_amplitude"], 0.0]))


def write_system(folder: Path, rows: int, seed: int = 5, chunk: int = 500_000) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    recs = []
    for name, w, n, fs in (
        ("long.csv", 19.0, rows, FS),
        ("w17.csv", 17.0, 20_000, 2e3),
        ("w21.csv", 21.0, 20_000, 2e3),
    ):
        X, Y = _sys_response(w)
        with open(folder / name, "w") as fh:
            fh.write("t,force,x,y,xdd,ydd\n")
            for i0 in range(0, n, chunk):
                t = np.arange(i0, min(n, i0 + chunk)) / fs
                e = np.exp(1j * w * t)
                cols = {
                    "t": t,
                    "force": SYS_NOM["base"]["force_amplitude"] * np.cos(w * t),
                    "x": np.real(X * e),
                    "y": np.real(Y * e),
                }
                cols["xdd"], cols["ydd"] = -w * w * cols["x"], -w * w * cols["y"]
                for k, sd in SYS_NOISE.items():
                    cols[k] = cols[k] + rng.normal(0.0, sd, t.size)
                pd.DataFrame(cols).to_csv(fh, header=False, index=False, float_format="%.9g")
        recs.append({"file": name, "omega": w, "force_amplitude": SYS_NOM["base"]["force_amplitude"]})
    (folder / "dataset.yaml").write_text(
        yaml.safe_dump(
            {
                "level": "system",
                "description": f"{rows:,}-row synthetic system record",
                "nominal": SYS_NOM,
                "records": recs,
            },
            sort_keys=False,
        )
    )
    return folder / "long.csv"


CHILD = (
    "import resource, sys, time\n"
    "from pyfmu_wrapper.cli.diagnose import main_diagnose\n"
    "t0 = time.perf_counter()\n"
    "rc = main_diagnose(sys.argv[1:])\n"
    "print(f'@@ wall {time.perf_counter() - t0:.2f} maxrss_kb '"
    "f'{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss}', flush=True)\n"
    "sys.exit(rc)\n"
)


def run_diagnose(ds: Path, out: Path) -> dict:
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-c", CHILD, str(ds), "--out", str(out)],
        capture_output=True,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"diagnose failed ({p.returncode}):\n{p.stdout}\n{p.stderr}")
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("@@ ")][-1].split()
    res = json.loads((out / "diagnosis.json").read_text())
    par = res["attribution"]["params"]
    return {
        "wall_s": wall,
        "diagnose_s": float(line[2]),
        "peak_rss_mb": int(line[4]) / 1024.0,
        "effects": res["attribution"]["effects"],
        "param": par.get("friction.friction_force", par.get("viscous.delta_damping")),
        "reduced": res.get("input_reduced"),
        "stdout": p.stdout,
        "stderr": p.stderr,
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kind", choices=("link", "system"), default="link")
    ap.add_argument("--rows", type=int, default=10_000_000)
    ap.add_argument("--baseline-rows", type=int, default=100_000)
    ap.add_argument("--keep", default=None, help="keep the generated data in this folder")
    a = ap.parse_args(argv)
    root = Path(a.keep) if a.keep else Path(tempfile.mkdtemp(prefix="bench_diag_mem_"))
    try:
        out = {}
        truth = ("df [N]", DF, "friction") if a.kind == "link" else ("dc [N s/m]", DC, "viscous")
        for label, rows in (("baseline", a.baseline_rows), ("long", a.rows)):
            t0 = time.perf_counter()
            f = (write_record if a.kind == "link" else write_system)(root / label, rows)
            gen = time.perf_counter() - t0
            r = run_diagnose(root / label, root / f"{label}_out")
            r.update(rows=rows, csv_mb=f.stat().st_size / 2**20, generate_s=gen)
            out[label] = r
            print(
                f"{label}: {rows:,} rows ({r['csv_mb']:.0f} MB, generated in {gen:.0f} s): diagnose {r['wall_s']:.1f} s "
                f"wall, peak RSS {r['peak_rss_mb']:.0f} MB; found {r['effects']}, {truth[0]} = "
                f"{r['param'] if r['param'] is None else round(r['param'], 3)} (hidden {truth[1]})",
                flush=True,
            )
        b, l = out["baseline"], out["long"]
        print(
            f"\nlong / baseline: rows x{l['rows'] / b['rows']:.0f}, peak RSS x{l['peak_rss_mb'] / b['peak_rss_mb']:.2f}, "
            f"wall x{l['wall_s'] / b['wall_s']:.1f}; target peak RSS <= 2048 MB: "
            f"{'met' if l['peak_rss_mb'] <= 2048 else 'NOT met'}"
        )
        print("console lines of the long run (stderr):")
        print("\n".join("  " + ln for ln in l["stderr"].splitlines()))
        print(f"machine: {os.cpu_count()} cores, load average {', '.join(f'{x:.2f}' for x in os.getloadavg())}")
        ok = (
            l["peak_rss_mb"] <= 2048
            and l["effects"] == [truth[2]]
            and l["param"] is not None
            and abs(l["param"] - truth[1]) < 0.05 * truth[1]
        )
        return 0 if ok else 1
    finally:
        if not a.keep:
            shutil.rmtree(root, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
