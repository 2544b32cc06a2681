"""Run the FMUs and the exported SSP in an OMSimulator you point to, with its default settings.

    OMSIMULATOR=/path/to/OMSimulator python benchmarks/omsimulator_fmu.py [--omega 17 20] [--step 1e-3]
        [--periods 60] [--window 3] [--play-gap 1e-4] [--option=--directionalDerivatives=false ...]

OMSimulator cannot be installed from the package registries of this project's machines (its pip
sdist downloads a binary at install time); build it from its public source
(https://github.com/OpenModelica/OMSimulator) and set ``OMSIMULATOR`` to the executable. Without
it this script says so and exits with status 2, running nothing. How it was built for the
recorded run: benchmarks/README_fmu.md.

For each frequency it exports the base + TMD pair (Case 1, c = 10 N.s/m; with ``--play-gap`` the
play model of the inerter with that gear gap [m]) as an SSP
(:func:`pyfmu_wrapper.cosim.system.export_tmd_system`, start state the linear steady state, force
coupling: the algebraic loop of the ideal inerter, x, xd, xdd -> tmd, tmd.force -> base.f_link),
whose OMSimulator annotation names OMSimulator's default master (``oms-ma``) with the step
``--step`` (1e-3 s: OMSimulator's default step), and runs ``OMSimulator --stopTime=T
--resultFile=... system.ssp`` with nothing else changed (directional derivatives on, algebraic
loops by kinsol, as by default; ``--option`` adds OMSimulator options, for comparisons only). It
counts the ``error:`` and ``warning:`` lines of its log and compares the amplitude of base.x over
the last ``--window`` (3) of ``--periods`` periods (the cubic Hermite maximum through base.x and
base.xd at the communication points, the rule of benchmarks/accuracy_table.py for every master) (60: started from the monolithic linear steady state, the
co-simulation settles to its own steady state within 1e-5 after ~50 periods at 17 rad/s; after 25
it is still 0.1 % away) with the monolithic solver. It also runs each FMU alone
(``OMSimulator X.fmu``). Results: benchmarks/results/omsimulator_fmu.json.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _run(cmd, cwd, timeout):
    """Run OMSimulator; its log, exit status, error and warning lines, wall time."""
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, timeout=timeout)
    wall = time.perf_counter() - t0
    lines = (r.stdout + r.stderr).splitlines()
    errors = [ln for ln in lines if ln.lstrip().lower().startswith("error")]
    warnings = [ln for ln in lines if ln.lstrip().lower().startswith("warning")]
    return {
        "command": [str(c) for c in cmd],
        "returncode": r.returncode,
        "errors": len(errors),
        "warnings": len(warnings),
        "first_errors": errors[:5],
        "first_warnings": warnings[:5],
        "wall_time_s": round(wall, 2),
    }


def _hermite_max(x, v, t):
    """max |p| of the cubic Hermite interpolants through (t, x, v), step by step (any spacing)."""
    import numpy as np

    from pyfmu_wrapper.solvers.hermite import hermite_absmax_series

    x, v, t = (np.asarray(a, float) for a in (x, v, t))
    keep = np.concatenate([[True], np.diff(t) > 0])  # a result file may repeat a time (events)
    x, v, t = x[keep], v[keep], t[keep]
    return max(
        float(hermite_absmax_series(x[i : i + 2].copy(), v[i : i + 2].copy(), float(t[i + 1] - t[i])))
        for i in range(len(t) - 1)
    )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--omega", type=float, nargs="+", default=[17.0, 20.0])
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--periods", type=int, default=60)
    ap.add_argument("--window", type=int, default=3, help="periods at the end over which the amplitude is taken")
    ap.add_argument("--play-gap", type=float, default=0.0, help="gear gap eps [m] of the play model (0: ideal inerter)")
    ap.add_argument("--option", action="append", default=[], help="extra OMSimulator option (not default)")
    ap.add_argument("--out", default=str(REPO / "benchmarks" / "results" / "omsimulator_fmu.json"))
    args = ap.parse_args(argv)
    exe = os.environ.get("OMSIMULATOR") or shutil.which("OMSimulator")
    if not exe or not os.access(exe, os.X_OK):
        print(
            "OMSimulator not found: set OMSIMULATOR to an OMSimulator executable built from "
            "https://github.com/OpenModelica/OMSimulator. Nothing was run."
        )
        return 2

    from pyfmu_wrapper.fmubuild.build import ensure_fmus
    from pyfmu_wrapper.models import solve as mono
    from pyfmu_wrapper.models.base_tmd import UNIT
    from pyfmu_wrapper.models.base_tmd.cosim import export_tmd_system
    from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    version = subprocess.run([exe, "--version"], capture_output=True, text=True).stdout.strip()
    base = BaseParams()
    tmd = TMDParams(damping=10.0)
    if args.play_gap > 0:
        tmd = TMDParams(damping=10.0, inerter="play", play_gap=args.play_gap)
    results = {
        "omsimulator": exe,
        "version": version,
        "step": args.step,
        "play_gap": args.play_gap,
        "window": args.window,
        "options": args.option,
        "runs": [],
    }
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, fmu in ensure_fmus(pick(PROJECT_FMUS)).items():
            run = _run([exe, *args.option, str(fmu)], tmp, 600)
            results["runs"].append({"model": name, **run})
        for w in args.omega:
            T = 2 * math.pi / w
            stop = args.periods * T
            ssp = export_tmd_system(UNIT, tmp / f"case1_{w:g}.ssp", base, tmd, w, stop_time=stop, step_size=args.step)
            res = tmp / f"case1_{w:g}.csv"
            run = _run([exe, *args.option, f"--stopTime={stop}", f"--resultFile={res}", str(ssp)], tmp, 3600)
            amp, rule = None, None
            if res.is_file():
                with res.open() as f:
                    rows = list(csv.DictReader(f))
                cx = next((c for c in rows[0] if c.endswith("base.x")), None) if rows else None
                cv = next((c for c in rows[0] if c.endswith("base.xd")), None) if rows else None
                if cx:
                    win = [r for r in rows if float(r["time"]) >= stop - args.window * T - 1e-9]
                    rule = "hermite(base.x, base.xd)" if cv else "samples of base.x"
                    if len(win) < 2:  # the run stopped before the window (an FMU error): no amplitude
                        rule = f"none: the results end at t = {rows[-1]['time']} s"
                    elif cv:  # the Hermite maximum between communication points (as for every master)
                        amp = _hermite_max(
                            [float(r[cx]) for r in win], [float(r[cv]) for r in win], [float(r["time"]) for r in win]
                        )
                    else:
                        amp = max(abs(float(r[cx])) for r in win)
            ref = mono.steady_state(base, tmd, w).amplitude
            results["runs"].append(
                {
                    "omega": w,
                    **run,
                    "amplitude": amp,
                    "amplitude_rule": rule,
                    "monolithic": ref,
                    "relative_difference": None if amp is None else amp / ref - 1,
                }
            )
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(json.dumps(results, indent=2))
    return 0 if all(r["errors"] == 0 and r["returncode"] == 0 for r in results["runs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
