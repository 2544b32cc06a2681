"""The system FMUs (TMDSystem, FrameSystem) in Model Exchange and co-simulation, against the exact linear
response and the monolithic engine, with no Python of the project in the runs (issue 40).

    python benchmarks/bench_system_fmu.py [--fmusim PATH] [--fmuchk PATH] [--quick]

(or ``FMUSIM=...``, ``FMUCHK=...``; a tool not given is skipped and said so; the tools are built by hand from
their public sources: benchmarks/README_fmu.md).

1. Builds TMDSystem and FrameSystem natively (linux64, FMI 2.0 and 3.0) and copies them into a temporary folder
   outside the checkout.
2. TMDSystem, max |x| over the two periods after 30 s (the largest sample, refined by the parabola through
   its neighbours when smooth; output every T/200): Case 1 with c = 10 N s/m at 17 and 23 rad/s against the
   exact linear response (``models.solve.exact_amplitude``); the paper's full Case 1 (c = 10, df = 10, play
   eps = 1e-4) at 15 and 25 rad/s against the monolithic engine's simulation from rest over the same time
   (``models.solve.simulate``, 4001 samples over the two periods). Each under FMPy in Model Exchange
   (``simulate_fmu(..., fmi_type='ModelExchange', solver='CVode')``, relative tolerance 1e-10) and in
   co-simulation (h = 1 ms), FMI 2.0 and 3.0; each FMPy run in a child process started with ``env -i`` under
   ``strace -f -e trace=openat``: the files of the project, of numba and of llvmlite it opened are counted
   (must be 0) and the child reports the modules it imported of them (must be none).
3. With fmusim: the same cases in Model Exchange (``--solver cvode --tolerance 1e-10``) and co-simulation
   (h = 1 ms), output every 1e-4 s, also under strace with ``env -i``. With the compliance checker: Model
   Exchange and co-simulation of both system FMUs (FMI 2.0), its summary parsed.
4. FrameSystem: a 3-storey TMDI (TMD on the top, inerter to storey 2), Case 1 with c = 10 and the full TMD at
   20 rad/s, against the monolithic engine over the two periods after 10 s.

Results: benchmarks/results/bench_system_fmu.json (and a table on stdout).
"""

from __future__ import annotations

import argparse
import inspect
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import numpy as np  # noqa: E402

from pyfmu_wrapper.fmubuild.native_build import build_native_fmus  # noqa: E402
from pyfmu_wrapper.models.catalog import pick  # noqa: E402
from pyfmu_wrapper.models.frame_model import FrameParams  # noqa: E402
from pyfmu_wrapper.models.solve import exact_amplitude, simulate  # noqa: E402
from pyfmu_wrapper.physics.params import BaseParams, InerterModel, paper_case  # noqa: E402

LINEAR = {"c": 10.0}
FULL = {"c": 10.0, "df": 10.0, "inerter": 2, "eps": 1e-4}
FULL_TMD = paper_case(1, damping=10.0, friction_force=10.0, inerter=InerterModel.PLAY, play_gap=1e-4)
TMDI3 = FrameParams.uniform(3, 100.0, 1.2e5, 100.0, tmd_storey=3, inerter_to=2)
TMDI3_START = {"storeys": 3, "tmd_storey": 3, "inerter_to": 2, "k1": 1.2e5, "k2": 1.2e5, "k3": 1.2e5}
FORBIDDEN = re.compile(r"/(numba|llvmlite|pyfmu_wrapper)(/|$)")


def peak(t: object, x: object, t0: float, t1: float) -> float:
    """max |x| over [t0, t1] from samples, the largest refined by the parabola through it and its neighbours
    when its vertex lies within half a sample (a kink, a gear impact, is left as sampled)."""
    import numpy as np

    a, tt = np.abs(np.asarray(x, dtype=float)), np.asarray(t, dtype=float)
    m = np.flatnonzero((tt >= t0) & (tt <= t1))
    i = m[np.argmax(a[m])]
    if i == 0 or i == a.size - 1:
        return float(a[i])
    y0, y1, y2 = a[i - 1], a[i], a[i + 1]
    den = 2 * y1 - y0 - y2
    return float(y1 + 0.125 * (y0 - y2) ** 2 / den) if den > 0 and abs(y0 - y2) <= den else float(y1)


#: the FMPy run, in a child process that imports fmpy and numpy only (the same peak function)
CHILD = (
    inspect.getsource(peak)
    + """
import json, math, sys, time
from fmpy import simulate_fmu
fmu, kind, w, t_from, out, start = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), sys.argv[5], json.loads(sys.argv[6])
T = 2 * math.pi / w
kw = dict(solver="CVode", relative_tolerance=1e-10) if kind == "ModelExchange" else dict(step_size=1e-3)
t0 = time.perf_counter()
r = simulate_fmu(fmu, fmi_type=kind, start_values={"w": w, **start}, stop_time=t_from + 2.2 * T, output=[out],
                 output_interval=T / 200, **kw)
wall = time.perf_counter() - t0
bad = sorted(m for m in sys.modules if m.split(".")[0] in ("numba", "llvmlite", "pyfmu_wrapper"))
print(json.dumps({"peak": peak(r["time"], r[out], t_from, t_from + 2 * T), "wall": wall, "imported": bad}))
"""
)


def traced(cmd: list[str], trace: Path, cwd: Path) -> tuple[subprocess.CompletedProcess[str], int]:
    """cmd with ``env -i`` under strace; (its result, the files of the project, numba or llvmlite it opened).
    Refused unless the trace shows the FMU's binary opened (the trace works)."""
    if shutil.which("strace") is None:
        raise SystemExit("bench_system_fmu: strace is needed (apt-get install strace)")
    env = {"PATH": "/usr/bin:/bin", "HOME": str(cwd)}
    full = ["strace", "-f", "-qq", "-e", "trace=openat", "-o", str(trace), *cmd]
    r = subprocess.run(full, cwd=cwd, env=env, capture_output=True, text=True)
    opened = re.findall(r'openat\([^"]*"([^"]*)"', trace.read_text()) if trace.exists() else []
    if r.returncode == 0 and not any(re.search(r"/(TMD|Frame)System\.so$", p) for p in opened):
        raise SystemExit(f"bench_system_fmu: strace shows no FMU binary opened by {cmd[0]}")
    bad = [p for p in opened if str(REPO) in p or FORBIDDEN.search(p)]
    return r, len(bad)


def mono_peak(structure: object, tmd: object, w: float, t_from: float) -> float:
    T = 2 * math.pi / w
    ts = np.linspace(t_from, t_from + 2 * T, 4001)
    _, z = simulate(structure, tmd, w, t_from + 2 * T, sample_times=ts)
    return peak(ts, z[:, 0], t_from, t_from + 2 * T)


def fmusim_peak(
    fmusim: str, fmu: Path, kind: str, w: float, t_from: float, start: dict, tmp: Path, tag: str
) -> dict[str, object]:
    T = 2 * math.pi / w
    csv = tmp / f"{tag}.csv"
    args = [fmusim, "--interface-type", "me" if kind == "ModelExchange" else "cs"]
    args += ["--solver", "cvode", "--tolerance", "1e-10"] if kind == "ModelExchange" else []
    args += ["--stop-time", repr(t_from + 2.2 * T), "--output-interval", "1e-4" if kind == "ModelExchange" else "1e-3"]
    for k, v in {"w": w, **start}.items():
        args += ["--start-value", k, repr(v)]
    args += ["--output-variable", "x", "--output-file", str(csv), str(fmu)]
    t0 = time.perf_counter()
    r, bad = traced(args, tmp / f"strace_{tag}.txt", tmp)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        return {"exit": r.returncode, "error": r.stderr[-500:], "python_files": bad}
    data = np.loadtxt(csv, delimiter=",", skiprows=1)
    return {"exit": 0, "peak": peak(data[:, 0], data[:, 1], t_from, t_from + 2 * T), "wall": wall, "python_files": bad}


def checker(fmuchk: str, fmu: Path, kind: str, tmp: Path) -> dict[str, object]:
    log = tmp / f"chk_{fmu.stem}_{kind}.log"
    h = "1e-4" if kind == "me" else "1e-3"
    cmd = [fmuchk, "-k", kind, "-l", "3", "-s", "3", "-h", h, "-n", "300", "-e", str(log), "-o", str(log) + ".csv"]
    r, bad = traced([*cmd, str(fmu)], tmp / f"strace_chk_{fmu.stem}_{kind}.txt", tmp)
    text = log.read_text() if log.exists() else r.stderr
    m = re.search(r"Checker reported:\s*(\d+) Warning\(s\)\s*(\d+) Error\(s\)", text)
    fmu_rep = re.search(r"FMU reported:\s*(\d+) warning\(s\) and error\(s\)", text)
    return {
        "exit": r.returncode,
        "checker_warnings": int(m.group(1)) if m else None,
        "checker_errors": int(m.group(2)) if m else None,
        "fmu_reported": int(fmu_rep.group(1)) if fmu_rep else None,
        "python_files": bad,
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--fmusim", default=os.environ.get("FMUSIM"))
    ap.add_argument("--fmuchk", default=os.environ.get("FMUCHK"))
    ap.add_argument("--quick", action="store_true", help="FMI 2.0 only, no FrameSystem")
    a = ap.parse_args()
    rows: list[dict[str, object]] = []
    with tempfile.TemporaryDirectory(prefix="pyfmu_system_") as tmp_name:
        tmp = Path(tmp_name)
        versions = (2,) if a.quick else (2, 3)
        fmus = {}
        for v in versions:
            for f in build_native_fmus(
                pick(("TMDSystem", "FrameSystem")), tmp / f"build{v}", fmi_version=v, win64=False
            ):
                dst = tmp / f"fmi{v}" / f.name
                dst.parent.mkdir(exist_ok=True)
                shutil.copy(f, dst)
                fmus[(v, f.stem)] = dst
        cases = [("linear c=10", w, LINEAR, float(exact_amplitude(BaseParams(), paper_case(1, damping=10.0), [w])[0]),
                  "exact") for w in (17.0, 23.0)]  # fmt: skip
        cases += [
            ("full Case 1", w, FULL, mono_peak(BaseParams(), FULL_TMD, w, 30.0), "monolithic") for w in (15.0, 25.0)
        ]
        for name, w, start, ref, against in cases:
            for v in versions:
                for kind in ("ModelExchange", "CoSimulation"):
                    tag = f"fmpy_{v}_{kind}_{w:g}_{name.split()[0]}"
                    cmd = [
                        sys.executable,
                        "-c",
                        CHILD,
                        str(fmus[(v, "TMDSystem")]),
                        kind,
                        repr(w),
                        "30.0",
                        "x",
                        json.dumps(start),
                    ]
                    r, bad = traced(cmd, tmp / f"strace_{tag}.txt", tmp)
                    if r.returncode != 0:
                        raise SystemExit(f"bench_system_fmu: FMPy run {tag} failed:\n{r.stderr[-3000:]}")
                    res = json.loads(r.stdout.strip().splitlines()[-1])
                    rows.append(dict(fmu="TMDSystem", case=name, w=w, tool="FMPy", fmi=v, kind=kind, value=res["peak"],
                                     reference=ref, against=against, rel=res["peak"] / ref - 1.0, wall=res["wall"],
                                     python_files=bad, imported=res["imported"]))  # fmt: skip
                    if a.fmusim:
                        f = fmusim_peak(
                            a.fmusim, fmus[(v, "TMDSystem")], kind, w, 30.0, start, tmp, tag.replace("fmpy", "fmusim")
                        )
                        row = dict(fmu="TMDSystem", case=name, w=w, tool="fmusim", fmi=v, kind=kind, reference=ref,
                                   against=against, **f)  # fmt: skip
                        if "peak" in f:
                            row.update(value=f["peak"], rel=float(f["peak"]) / ref - 1.0)  # type: ignore[arg-type]
                        rows.append(row)
        if not a.quick:
            for name, tmd, start in (
                ("TMDI linear c=10", paper_case(1, damping=10.0), LINEAR),
                ("TMDI full", FULL_TMD, FULL),
            ):
                ref = mono_peak(TMDI3, tmd, 20.0, 10.0)
                for kind in ("ModelExchange", "CoSimulation"):
                    cmd = [sys.executable, "-c", CHILD, str(fmus[(2, "FrameSystem")]), kind, "20.0", "10.0", "x_top",
                           json.dumps({**TMDI3_START, **start})]  # fmt: skip
                    r, bad = traced(cmd, tmp / f"strace_frame_{kind}_{name[5:8]}.txt", tmp)
                    if r.returncode != 0:
                        raise SystemExit(f"bench_system_fmu: FMPy run of FrameSystem failed:\n{r.stderr[-3000:]}")
                    res = json.loads(r.stdout.strip().splitlines()[-1])
                    rows.append(dict(fmu="FrameSystem", case=name, w=20.0, tool="FMPy", fmi=2, kind=kind,
                                     value=res["peak"], reference=ref, against="monolithic", rel=res["peak"] / ref - 1,
                                     wall=res["wall"], python_files=bad, imported=res["imported"]))  # fmt: skip
        checks = {}
        if a.fmuchk:
            for name in ("TMDSystem", "FrameSystem"):
                for kind in ("me", "cs"):
                    checks[f"{name} {kind}"] = checker(a.fmuchk, fmus[(2, name)], kind, tmp)
    print(f"{'fmu':11} {'case':17} {'w':>4} {'tool':6} {'fmi':3} {'kind':13} {'max|x|':>12} {'against':10} "
          f"{'rel. diff':>10} {'wall s':>7} {'py files':>8}")  # fmt: skip
    for r_ in rows:
        print(f"{r_['fmu']:11} {r_['case']:17} {r_['w']:4g} {r_['tool']:6} {r_['fmi']:3} {r_['kind']:13} "
              f"{r_.get('value', float('nan')):12.9g} {r_['against']:10} {r_.get('rel', float('nan')):10.2e} "
              f"{r_.get('wall', float('nan')):7.2f} {r_['python_files']:8}")  # fmt: skip
    for k, v_ in checks.items():
        print(f"compliance checker {k}: {v_}")
    if not a.fmusim:
        print("fmusim: not given (--fmusim or FMUSIM), skipped")
    if not a.fmuchk:
        print("compliance checker: not given (--fmuchk or FMUCHK), skipped")
    out = REPO / "benchmarks" / "results" / "bench_system_fmu.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(
        json.dumps(
            {"rows": rows, "checker": checks, "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}, indent=1
        )
    )
    print(f"written {out}")


if __name__ == "__main__":
    main()
