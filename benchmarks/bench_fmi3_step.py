"""Per-doStep cost of the FMI 3.0 FMUs against the FMI 2.0 ones, in pure C hosts (issue 21).

    python benchmarks/bench_fmi3_step.py [--steps 50000] [--rounds 3]

Builds both versions of ``Trivial`` (y = gain * u; doStep only advances time: the stub's own
cost), ``BaseOscillator`` and ``TMDInerter`` (Case 1, c = 10, h = 1 ms, native steps) and runs
each in a C host without Python: tests/c_host/fmu_host.c's ``bench`` mode (FMI 2.0) and
benchmarks/c_host/fmi3_bench.c (FMI 3.0, the same loop through the fmi3 functions). The versions
alternate within each round (the machine is shared: the ratio, measured side by side, is the
result; medians over the rounds). The checksum of the outputs must agree between the versions
(the same core computes both). Results: benchmarks/results/bench_fmi3_step.json.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from pyfmu_wrapper.fmubuild.build import build_fmus, fmi_headers_dir, fmi_out_dir  # noqa: E402
from pyfmu_wrapper.models.catalog import pick  # noqa: E402

#: model -> (input vr, output vr, parameters {vr: value}) as in benchmarks/bench_fmu.py
CASES = {"Trivial": (1, 2, {}), "BaseOscillator": (10, 20, {}), "TMDInerter": (30, 40, {2: 10.0})}


def _token(d: Path) -> str:
    for line in (d / "resources" / "pyfmu.cfg").read_text().splitlines():
        if line.startswith("guid="):
            return line[5:]
    raise KeyError("guid")


def _run(cmd) -> dict:
    r = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, timeout=1800)
    if r.returncode != 0:
        raise RuntimeError(f"{cmd[0]} failed ({r.returncode}): {r.stderr[-2000:]}")
    return {k: float(v) for k, v in (line.split() for line in r.stdout.splitlines())}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=50_000)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args(argv)
    inc = f"-I{fmi_headers_dir()}"
    out: dict = {}
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        host2, host3 = tmp / "fmu_host", tmp / "fmi3_bench"
        subprocess.run(
            ["gcc", "-O2", inc, str(REPO / "tests" / "c_host" / "fmu_host.c"), "-o", str(host2), "-ldl"], check=True
        )
        subprocess.run(
            ["gcc", "-O2", inc, str(REPO / "benchmarks" / "c_host" / "fmi3_bench.c"), "-o", str(host3), "-ldl"],
            check=True,
        )
        dirs = {}
        for v in (2, 3):
            for f in build_fmus(pick(CASES), fmi_out_dir(tmp / "fmus", v), fmi_version=v):
                d = tmp / f"x{v}" / f.stem
                with zipfile.ZipFile(f) as z:
                    z.extractall(d)
                dirs[(v, f.stem)] = d
        for name, (u, y, pars) in CASES.items():
            p = [f"r:{vr}={val!r}" for vr, val in pars.items()]
            runs: dict[int, list[dict]] = {2: [], 3: []}
            for _ in range(args.rounds):
                d2, d3 = dirs[(2, name)], dirs[(3, name)]
                runs[2].append(_run([host2, "bench", args.steps, d2, _token(d2), u, y, *p]))
                runs[3].append(_run([host3, args.steps, d3, _token(d3), u, y, *p]))
            med = {
                v: {k: statistics.median(r[k] for r in runs[v]) for k in ("us_per_doStep", "us_per_set_doStep_get")}
                for v in (2, 3)
            }
            same = {r["check"] for r in runs[2]} == {r["check"] for r in runs[3]}
            out[name] = {
                "fmi2": med[2],
                "fmi3": med[3],
                "ratio_doStep": med[3]["us_per_doStep"] / med[2]["us_per_doStep"],
                "ratio_set_doStep_get": med[3]["us_per_set_doStep_get"] / med[2]["us_per_set_doStep_get"],
                "same_outputs": same,
            }
    print(
        f"{'model':16s} {'FMI 2.0 us/doStep':>18s} {'FMI 3.0 us/doStep':>18s} {'ratio':>6s} "
        f"{'set+step+get 2.0':>17s} {'3.0':>8s} {'ratio':>6s} same outputs"
    )
    for name, r in out.items():
        print(
            f"{name:16s} {r['fmi2']['us_per_doStep']:18.3f} {r['fmi3']['us_per_doStep']:18.3f} {r['ratio_doStep']:6.2f} "
            f"{r['fmi2']['us_per_set_doStep_get']:17.3f} {r['fmi3']['us_per_set_doStep_get']:8.3f} "
            f"{r['ratio_set_doStep_get']:6.2f} {r['same_outputs']}"
        )
    res = REPO / "benchmarks" / "results"
    res.mkdir(exist_ok=True)
    (res / "bench_fmi3_step.json").write_text(json.dumps(out, indent=1))
    return 0 if all(r["same_outputs"] for r in out.values()) else 1


if __name__ == "__main__":
    sys.exit(main())
