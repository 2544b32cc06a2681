"""Run the FMUs and the exported SSP in an OMSimulator you point to, with its default settings.

    OMSIMULATOR=/path/to/OMSimulator python benchmarks/omsimulator_fmu.py [--omega 17 20] [--step 1e-3]

OMSimulator cannot be installed from the package registries of this project's machines (its pip
sdist downloads a binary at install time); build it from its public source
(https://github.com/OpenModelica/OMSimulator) and set ``OMSIMULATOR`` to the executable. Without
it this script says so and exits with status 2, running nothing.

For each frequency it exports the base + TMD pair (Case 1, c = 10 N.s/m) as an SSP
(:func:`pyfmu_wrapper.cosim.system.export_tmd_system`, start state the linear steady state), runs
``OMSimulator --stopTime=T --intervals=N --resultFile=... system.ssp`` with nothing else changed
(directional derivatives on, as by default), counts the error lines in its log, and compares the
amplitude of base.x over the last three periods with the monolithic solver. It also loads each
FMU alone (``OMSimulator X.fmu``). Results: benchmarks/results/omsimulator_fmu.json.
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
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--omega", type=float, nargs="+", default=[17.0, 20.0])
    ap.add_argument("--step", type=float, default=1e-3)
    ap.add_argument("--periods", type=int, default=25)
    args = ap.parse_args(argv)
    exe = os.environ.get("OMSIMULATOR") or shutil.which("OMSimulator")
    if not exe or not os.access(exe, os.X_OK):
        print("OMSimulator not found: set OMSIMULATOR to an OMSimulator executable built from "
              "https://github.com/OpenModelica/OMSimulator. Nothing was run.")
        return 2

    from pyfmu_wrapper.fmi.build import ensure_fmus
    from pyfmu_wrapper.cosim.system import export_tmd_system
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams
    from pyfmu_wrapper.solvers import monolithic as mono

    base, tmd = BaseParams(), TMDParams(damping=10.0)
    results = {"omsimulator": exe, "step": args.step, "runs": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, fmu in ensure_fmus().items():
            r = subprocess.run([exe, str(fmu)], capture_output=True, text=True, cwd=tmp, timeout=600)
            log = r.stdout + r.stderr
            results["runs"].append({"model": name, "returncode": r.returncode,
                                    "errors": sum("error" in line.lower() for line in log.splitlines())})
        for w in args.omega:
            T = 2 * math.pi / w
            stop = args.periods * T
            ssp = export_tmd_system(tmp / f"case1_{w:g}.ssp", base, tmd, w, stop_time=stop)
            res = tmp / f"case1_{w:g}.csv"
            cmd = [exe, f"--stopTime={stop}", f"--intervals={int(round(stop / args.step))}", f"--resultFile={res}",
                   str(ssp)]
            r = subprocess.run(cmd, capture_output=True, text=True, cwd=tmp, timeout=3600)
            log = r.stdout + r.stderr
            errors = [line for line in log.splitlines() if "error" in line.lower()]
            amp = None
            if res.is_file():
                with res.open() as f:
                    rows = list(csv.DictReader(f))
                col = next((c for c in rows[0] if c.endswith("base.x")), None) if rows else None
                if col:
                    amp = max(abs(float(row[col])) for row in rows if float(row["time"]) >= stop - 3 * T)
            ref = mono.steady_state(base, tmd, w).amplitude
            results["runs"].append({"omega": w, "command": cmd, "returncode": r.returncode, "errors": len(errors),
                                    "first_errors": errors[:5], "amplitude": amp, "monolithic": ref,
                                    "relative_difference": None if amp is None else amp / ref - 1})
    out = REPO / "benchmarks" / "results" / "omsimulator_fmu.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(results, indent=2))
    print(json.dumps(results, indent=2))
    return 0 if all(r.get("errors", 0) == 0 and r.get("returncode", 0) == 0 for r in results["runs"]) else 1


if __name__ == "__main__":
    sys.exit(main())
