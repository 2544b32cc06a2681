"""The native FMUs in other vendors' tools with no Python on the machine (issue 30), in one run.

    FMUSIM=/path/fmusim FMUSIM_WIN=/path/fmusim.exe FMUCHK=/path/fmuCheck.linux64 \\
    VANDERPOL2=/path/VanDerPol-fmi2.fmu VANDERPOL3=/path/VanDerPol-fmi3.fmu \\
        python benchmarks/bench_native_external.py [--stop-time 2] [--steps 200000] [--rounds 3]

(or ``--fmusim``, ``--fmusim-win``, ``--fmuchk``, ``--vanderpol2``, ``--vanderpol3``; a tool not given
is skipped and said so). The tools are built by hand from their public sources (Reference-FMUs' fmusim and
VanDerPol, the FMI Compliance Checker); their versions are in benchmarks/README_fmu.md.

1. Builds the native FMUs and the Python-hosted FMUs (FMI 2.0 and 3.0) and copies them, with the
   VanDerPol FMUs, into a temporary folder outside the checkout.
2. Runs fmusim (co-simulation, h = 1 ms: the base with f_link = 50 sin(25 t), the TMD Case 1 with an
   ideal inerter and with play, inputs x, xd, xdd of x = 2 mm sin(25 t) from a CSV file, parameters
   as ``--start-value``; and the TMD with communication steps of 2 s) and the compliance checker
   (FMI 2.0 only: it reads no FMI 3.0) on the native FMUs and VanDerPol with ``env -i`` inside a
   user + mount namespace (``unshare -rm``) in which every Python installation, venv, site-packages
   folder, libpython and python executable is covered by an empty tmpfs or /dev/null, under
   ``strace -f -e trace=openat``; counts the Python files opened (must be 0), the exit status, the
   warnings and errors each tool reports and the FMI calls that did not return OK (fmusim's
   ``--log-fmi-calls``). The Python-hosted FMUs run the same commands without the namespace (they
   need Python). With ``FMUSIM_WIN``, fmusim built for Windows runs the native FMUs' win64 binaries
   under wine with the same arguments (the Python-hosted FMUs have no win64 binary).
3. Compares the native FMUs' outputs with the Python-hosted FMUs' (fmusim's CSV prints 16 significant
   digits; the checker's has 17, so identical text there means identical bits), and the win64
   binary's with the linux64 one's (values that differ, largest relative difference).
4. Measures, in one run with the C host of benchmarks/bench_native_step.py (FMI 2.0), the archive
   size, dlopen + instantiate + initialise, and set + doStep + get at h = 1 ms of the native FMUs,
   the Python-hosted FMUs and VanDerPol (no inputs: doStep + get); the kinds alternate within each
   round, medians over the rounds.

Results: benchmarks/results/bench_native_external.json.
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import os
import re
import shlex
import shutil
import site
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
sys.path.insert(0, str(REPO / "tests"))

from _fmu_support import extract  # noqa: E402
from bench_native_step import CASES, case_args, compile_fmu_timer, time_fmu  # noqa: E402

from pyfmu_wrapper.fmubuild.build import ensure_fmus  # noqa: E402
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus  # noqa: E402
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick  # noqa: E402

W, H = 25.0, 1e-3
#: a path opened that belongs to Python (interpreter, library, packages, bytecode, the project's venvs)
PYTHON_FILE = re.compile(r"python|site-packages|dist-packages|\.pyc?$|/\.venv/|\.pyenv|numba|numpy|llvmlite", re.I)
#: fmusim's log lines of a status worse than OK (the FMU's messages and its own)
FMUSIM_BAD = re.compile(r"^\[(Warning|Discard|Error|Fatal)\]", re.M)
#: fmusim's log of the FMI calls (--log-fmi-calls): the status each call returned
FMI_CALL_STATUS = re.compile(r"^(fmi[23]\w+)\(.*-> (OK|Warning|Discard|Error|Fatal|Pending)", re.M)
CHECKER_SUMMARY = re.compile(
    r"FMU reported:\s*(\d+) warning\(s\) and error\(s\)\s*Checker reported:\s*(\d+) Warning\(s\)\s*(\d+) Error\(s\)"
)


def hidden_paths() -> tuple[list[str], list[str]]:
    """The folders and files to cover: every Python installation, venv, site-packages, libpython, python."""
    dirs = set(glob.glob("/usr/lib/python3*") + glob.glob("/usr/local/lib/python3*") + glob.glob("/usr/share/python3*"))
    dirs |= set(glob.glob("/work/*/.venv") + glob.glob(os.path.expanduser("~/.pyenv")) + glob.glob("/root/.local/lib"))
    dirs |= {sys.prefix, sys.base_prefix, sys.exec_prefix, *site.getsitepackages()}
    files = set()
    for pat in ("/usr/lib/*/libpython*", "/usr/lib/libpython*", "/usr/local/lib/libpython*", "/usr/bin/python*",
                "/usr/local/bin/python*", f"{sys.base_prefix}/lib/libpython*"):  # fmt: skip
        files |= set(glob.glob(pat))
    real_dirs = sorted({os.path.realpath(d) for d in dirs if os.path.isdir(d)})
    top: list[str] = []
    for d in real_dirs:  # a folder inside a covered one is covered already
        if not any(d == t or d.startswith(t + "/") for t in top):
            top.append(d)
    real_files = sorted({os.path.realpath(f) for f in files if os.path.isfile(f)})
    real_files = [f for f in real_files if not any(f.startswith(t + "/") for t in top)]
    return top, real_files


def sandbox_script(dirs: list[str], files: list[str], cmd: list[str], trace: Path) -> str:
    """sh script for ``unshare -rm``: cover the paths, check they are empty, then run cmd under env -i and strace."""
    q = shlex.quote
    lines = ["set -e"]
    lines += [f"mount -t tmpfs -o ro,size=4k none {q(d)}" for d in dirs]
    lines += [f"mount --bind /dev/null {q(f)}" for f in files]
    lines += [f'[ -z "$(ls -A {q(d)})" ] || {{ echo "not hidden: {d}" >&2; exit 97; }}' for d in dirs]
    lines += [f'[ ! -s {q(f)} ] || {{ echo "not hidden: {f}" >&2; exit 97; }}' for f in files]
    lines.append(
        "exec /usr/bin/env -i /usr/bin/strace -f -qq -e trace=openat -o " + q(str(trace)) + " -- " + shlex.join(cmd)
    )
    return "\n".join(lines)


def run_tool(cmd: list[str], hide: tuple[list[str], list[str]] | None, trace: Path) -> dict:
    """Run cmd (hidden Python + env -i + strace when ``hide``); exit status, output, Python files opened."""
    if hide is None:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        return {"rc": r.returncode, "out": r.stdout + r.stderr, "python_files": None, "opened": None}
    script = sandbox_script(*hide, cmd, trace)
    r = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True, text=True, timeout=600)
    if r.returncode == 97:
        raise SystemExit(f"bench_native_external: could not hide Python: {r.stderr.strip()}")
    opened = re.findall(r'openat\([^"]*"([^"]*)"', trace.read_text()) if trace.exists() else []
    if not opened:  # every run opens its C library at least: no trace is no proof
        raise SystemExit(f"bench_native_external: strace recorded no file opened by {cmd[0]}: {r.stderr.strip()}")
    py = sorted({p for p in opened if PYTHON_FILE.search(p)})
    return {"rc": r.returncode, "out": r.stdout + r.stderr, "python_files": py, "opened": len(opened)}


def input_csvs(tmp: Path, stop: float) -> dict[str, Path]:
    """fmusim/checker input files: f_link = 50 sin(w t) for the base; x = 2 mm sin(w t), xd, xdd for the TMD."""
    n = round(stop / H)
    base, tmd = tmp / "in_base.csv", tmp / "in_tmd.csv"
    rows_b, rows_t = ['"time","f_link"'], ['"time","x","xd","xdd"']
    for k in range(n + 1):
        t = k * H
        s, c = math.sin(W * t), math.cos(W * t)
        rows_b.append(f"{t!r},{50.0 * s!r}")
        rows_t.append(f"{t!r},{2e-3 * s!r},{2e-3 * W * c!r},{-2e-3 * W * W * s!r}")
    base.write_text("\n".join(rows_b) + "\n")
    tmd.write_text("\n".join(rows_t) + "\n")
    return {"BaseOscillator": base, "TMDInerter": tmd}


def winpath(p: Path) -> str:
    """A path as wine's Windows programs see it (drive Z: is /)."""
    return "Z:" + str(p).replace("/", "\\")


def fmusim_cmd(
    fmusim: list[str], fmu: Path, out: Path, stop: float, inp: Path | None, params: dict, interval: float = H
) -> list[str]:
    """fmusim's command line; ``fmusim`` ["wine", "fmusim.exe"]: the Windows build under wine, Windows paths."""
    path = winpath if fmusim[0] == "wine" else str
    cmd = [*fmusim, "--interface-type", "cs", "--logging-on", "--log-level", "ok", "--stop-time", repr(stop)]
    cmd += [
        "--output-interval",
        repr(interval),
        "--log-fmi-calls",
        "--fmi-log-file",
        path(out.with_suffix(".calls.txt")),
    ]
    for k, v in params.items():
        cmd += ["--start-value", k, repr(v)]
    if inp is not None:
        cmd += ["--input-file", path(inp)]
    return [*cmd, "--output-file", path(out), path(fmu)]


def checker_cmd(fmuchk: str, fmu: Path, out: Path, stop: float, inp: Path | None, work: Path) -> list[str]:
    cmd = [fmuchk, "-l", "3", "-k", "cs", "-s", repr(stop), "-h", repr(H), "-n", "0", "-f", "-t", str(work)]
    if inp is not None:
        cmd += ["-i", str(inp)]
    return [*cmd, "-o", str(out), str(fmu)]


def token_of(fmu_dir: Path) -> str:
    md = (fmu_dir / "modelDescription.xml").read_text()
    m = re.search(r'\b(?:guid|instantiationToken)="([^"]+)"', md)
    if m is None:
        raise SystemExit(f"bench_native_external: no guid in {fmu_dir / 'modelDescription.xml'}")
    return m.group(1)


def tool_runs(a: argparse.Namespace, tmp: Path, fmus: dict, hide: tuple[list[str], list[str]]) -> list[dict]:
    """fmusim (FMI 2.0, 3.0) and the checker (FMI 2.0) on every FMU; native and VanDerPol with Python hidden."""
    inputs = input_csvs(tmp, a.stop_time)
    runs = []
    jobs = []  # (tool, FMI version, kind, case, command, output file)
    sims = [("fmusim", [a.fmusim])] if a.fmusim else []
    wine = [("win64", ["wine", a.fmusim_win])] if a.fmusim_win else []
    for v in (2, 3):
        kinds = ["native", "hosted"] + (["reference"] if ("vanderpol", v) in fmus else [])
        for kind in kinds:
            cases = (
                {"VanDerPol": ("VanDerPol", {})}
                if kind == "reference"
                else {c: (m, p) for c, (m, p, _) in CASES.items()}
            )
            group = "vanderpol" if kind == "reference" else kind
            for case, (model, params) in cases.items():
                fmu, inp = fmus[(group, v)][model], inputs.get(model)
                for k, sim in sims + (wine if kind == "native" else []):  # the win64 binary: fmusim.exe under wine
                    k = kind if k == "fmusim" else k
                    out = tmp / f"fmusim_{k}{v}_{case}.csv"
                    jobs.append(("fmusim", v, k, case, fmusim_cmd(sim, fmu, out, a.stop_time, inp, params), out))
                    if case == "tmd_ideal":  # communication steps of 2 s (the hosted FMU takes them in pieces)
                        out = tmp / f"fmusim_{k}{v}_tmd_step2s.csv"
                        cmd = fmusim_cmd(sim, fmu, out, 6.0, None, {"y0": 0.01}, interval=2.0)
                        jobs.append(("fmusim", v, k, "tmd_step2s", cmd, out))
                if a.fmuchk and v == 2 and case != "tmd_play":  # the checker sets no parameter: the defaults
                    case = "tmd_default" if case == "tmd_ideal" else case
                    work = tmp / f"chk_{kind}_{case}"
                    work.mkdir()
                    out = tmp / f"checker_{kind}{v}_{case}.csv"
                    jobs.append(
                        ("checker", v, kind, case, checker_cmd(a.fmuchk, fmu, out, a.stop_time, inp, work), out)
                    )
    for tool, v, kind, case, cmd, out in jobs:
        sandbox = hide if kind in ("native", "reference") else None
        r = run_tool(cmd, sandbox, tmp / f"strace_{tool}_{kind}{v}_{case}.txt")
        row = {"tool": tool, "fmi": v, "kind": kind, "case": case, "rc": r["rc"], "python_files": r["python_files"]}
        row["files_opened"] = r["opened"]
        if tool == "fmusim":
            bad = FMUSIM_BAD.findall(r["out"])
            row["warnings"] = sum(b == "Warning" for b in bad)
            row["errors"] = len(bad) - row["warnings"]
            calls_log = out.with_suffix(".calls.txt")
            calls = FMI_CALL_STATUS.findall(calls_log.read_text()) if calls_log.exists() else []
            row["fmi_calls"] = len(calls)
            row["fmi_calls_not_ok"] = sorted({f"{f} -> {st}" for f, st in calls if st != "OK"})
        else:
            m = CHECKER_SUMMARY.search(r["out"])
            row["fmu_reported"], row["warnings"], row["errors"] = (int(g) for g in m.groups()) if m else (-1,) * 3
        row["output"] = str(out)
        row["rows"] = len(out.read_text().splitlines()) if out.exists() else 0
        if row["rc"] or row["errors"] or row["warnings"] or row.get("fmi_calls_not_ok"):
            row["log"] = r["out"][-2000:]
        runs.append(row)
        print(
            f"{tool:8s} FMI {v}.0 {kind:9s} {case:10s} rc {row['rc']} warnings {row['warnings']} errors "
            f"{row['errors']} rows {row['rows']}"
            + (f" FMI calls {row['fmi_calls']} not OK {len(row['fmi_calls_not_ok'])}" if tool == "fmusim" else "")
            + " Python files opened "
            f"{'n/a' if r['python_files'] is None else len(r['python_files'])}"
            + (f" of {r['opened']}" if r["opened"] is not None else "")
        )
    return runs


def compare_outputs(runs: list[dict]) -> dict[str, bool]:
    """Native against Python-hosted: the same tool's output text, per FMI version and case."""
    out = {}
    by = {(r["tool"], r["fmi"], r["kind"], r["case"]): r for r in runs}
    for (tool, v, kind, case), r in by.items():
        other = by.get((tool, v, "hosted", case))
        if kind == "native" and other is not None:
            a, b = Path(r["output"]), Path(other["output"])
            out[f"{tool} FMI {v}.0 {case}"] = a.exists() and b.exists() and a.read_bytes() == b.read_bytes()
    return out


def compare_win64(runs: list[dict]) -> dict[str, dict]:
    """The win64 binary (fmusim.exe under wine) against the linux64 one (fmusim), per output column: how many
    values differ, and the largest difference relative to the column's largest magnitude."""
    out = {}
    by = {(r["tool"], r["fmi"], r["kind"], r["case"]): r for r in runs}
    for (tool, v, kind, case), r in by.items():
        lin = by.get((tool, v, "native", case))
        if kind != "win64" or lin is None or not r["rows"] or r["rows"] != lin["rows"]:
            continue
        w, x = ([line.split(",") for line in Path(q["output"]).read_text().splitlines()] for q in (r, lin))
        cols = {}
        for j, name in enumerate(x[0][1:], 1):
            pairs = [(float(rw[j]), float(rx[j])) for rw, rx in zip(w[1:], x[1:])]
            scale = max(abs(b) for _, b in pairs) or 1.0
            diff = [abs(a - b) for a, b in pairs if a != b]
            if diff:
                cols[name.strip('"')] = {"differ": len(diff), "of": len(pairs), "max_rel": max(diff) / scale}
        out[f"FMI {v}.0 {case}"] = {"columns": cols, "max_rel": max((c["max_rel"] for c in cols.values()), default=0.0)}
    return out


def c_host_timing(a: argparse.Namespace, tmp: Path, fmus: dict) -> dict:
    """Size, instantiate + initialise and set + doStep + get of the FMI 2.0 FMUs in bench_native_step's C host."""
    host = compile_fmu_timer(tmp)
    targets = []  # (label, fmu, binary, resources uri, token, args)
    for case, (model, _, _) in CASES.items():
        for kind in ("native", "hosted"):
            d = extract(fmus[(kind, 2)][model], tmp / f"x_{kind}_{case}")
            so = d / "binaries" / "linux64" / f"{model}.so"
            targets.append(
                (f"{case} {kind}", fmus[(kind, 2)][model], so, (d / "resources").as_uri(), token_of(d), case_args(case))
            )
    if ("vanderpol", 2) in fmus:
        f = fmus[("vanderpol", 2)]["VanDerPol"]
        d = extract(f, tmp / "x_vdp")
        args = ["1", "", "0", "0", "0"]  # output x0 (vr 1), no inputs
        targets.append(("VanDerPol reference", f, d / "binaries" / "linux64" / "VanDerPol.so", (d / "resources").as_uri(), token_of(d), args))  # fmt: skip
    us: dict[str, list[float]] = {t[0]: [] for t in targets}
    init: dict[str, list[float]] = {t[0]: [] for t in targets}
    sums: dict[str, set[str]] = {t[0]: set() for t in targets}
    for _ in range(a.rounds):
        for label, _f, so, uri, token, args in targets:
            step_us, total, init_ms = time_fmu(host, so, uri, token, a.steps, args)
            us[label].append(step_us)
            init[label].append(init_ms)
            sums[label].add(total)
    rows = {}
    for label, f, *_ in targets:
        rows[label] = {
            "bytes": f.stat().st_size,
            "init_ms": statistics.median(init[label]),
            "step_us": statistics.median(us[label]),
            "rounds_init_ms": init[label],
            "rounds_step_us": us[label],
            "sum": sorted(sums[label]),
        }
    for case in CASES:
        n, h = rows[f"{case} native"], rows[f"{case} hosted"]
        n["same_outputs_as_hosted"] = n["sum"] == h["sum"] and len(n["sum"]) == 1
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fmusim", default=os.environ.get("FMUSIM"), help="fmusim executable (env FMUSIM)")
    ap.add_argument(
        "--fmusim-win", default=os.environ.get("FMUSIM_WIN"), help="fmusim.exe, run by wine (env FMUSIM_WIN)"
    )
    ap.add_argument("--fmuchk", default=os.environ.get("FMUCHK"), help="FMI Compliance Checker (env FMUCHK)")
    ap.add_argument("--vanderpol2", default=os.environ.get("VANDERPOL2"), help="VanDerPol FMI 2.0 (env VANDERPOL2)")
    ap.add_argument("--vanderpol3", default=os.environ.get("VANDERPOL3"), help="VanDerPol FMI 3.0 (env VANDERPOL3)")
    ap.add_argument("--stop-time", type=float, default=2.0)
    ap.add_argument("--steps", type=int, default=200_000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args()
    tools = {n: getattr(a, n) for n in ("fmusim", "fmusim_win", "fmuchk", "vanderpol2", "vanderpol3")}
    for name, p in tools.items():
        if p is not None and not Path(p).is_file():
            print(f"bench_native_external: --{name.replace('_', '-')} {p}: no such file", file=sys.stderr)
            sys.exit(2)
        if p is None:
            print(f"bench_native_external: no {name} given: skipped", file=sys.stderr)
    if a.fmusim_win and shutil.which("wine") is None:
        print("bench_native_external: --fmusim-win needs wine (apt-get install wine64)", file=sys.stderr)
        sys.exit(2)
    if (a.fmusim or a.fmuchk) and (shutil.which("strace") is None or shutil.which("unshare") is None):
        print(
            "bench_native_external: strace and unshare are needed (apt-get install strace util-linux)", file=sys.stderr
        )
        sys.exit(2)
    hide = hidden_paths()
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        assert not tmp.resolve().is_relative_to(REPO)
        fmus: dict[tuple[str, int], dict[str, Path]] = {}
        for v in (2, 3):
            fmus[("native", v)] = {
                p.stem: p for p in build_native_fmus(pick(PROJECT_FMUS), out_dir=tmp / f"native{v}", fmi_version=v)
            }
            (tmp / f"hosted{v}").mkdir()
            fmus[("hosted", v)] = {
                n: Path(shutil.copy(p, tmp / f"hosted{v}" / p.name))
                for n, p in ensure_fmus(pick(PROJECT_FMUS), fmi_version=v).items()
            }
            vdp = getattr(a, f"vanderpol{v}")
            if vdp:
                (tmp / f"vdp{v}").mkdir()
                fmus[("vanderpol", v)] = {"VanDerPol": Path(shutil.copy(vdp, tmp / f"vdp{v}" / "VanDerPol.fmu"))}
        runs = tool_runs(a, tmp, fmus, hide)
        same = compare_outputs(runs)
        for k, ok in same.items():
            print(f"native vs Python-hosted, {k}: {'identical' if ok else 'DIFFERENT'}")
        win = compare_win64(runs)
        for k, d in win.items():
            cols = ", ".join(f"{n} {c['differ']}/{c['of']} ({c['max_rel']:.2g})" for n, c in d["columns"].items())
            print(
                f"win64 (wine) vs linux64, {k}: max rel to the column's range {d['max_rel']:.3g}; {cols or 'identical'}"
            )
        timing = c_host_timing(a, tmp, fmus)
        for r in runs:
            r.pop("output")
    load = Path("/proc/loadavg").read_text().split()[:3]
    print(f"\n{'FMU (FMI 2.0, C host)':28s} {'bytes':>9s} {'init ms':>9s} {'us/step':>8s}  same outputs")
    for label, r in timing.items():
        print(
            f"{label:28s} {r['bytes']:9d} {r['init_ms']:9.3f} {r['step_us']:8.3f}  {r.get('same_outputs_as_hosted', '')}"
        )
    print("hidden:", len(hide[0]), "folders,", len(hide[1]), "files; load", load)
    out = {
        "stop_time": a.stop_time, "h": H, "steps": a.steps, "rounds": a.rounds, "load": load, "tools": tools,
        "hidden_dirs": hide[0], "hidden_files": hide[1], "runs": runs, "same_outputs": same, "win64_vs_linux64": win, "c_host": timing,
    }  # fmt: skip
    res = REPO / "benchmarks" / "results"
    res.mkdir(exist_ok=True)
    (res / "bench_native_external.json").write_text(json.dumps(out, indent=1))
    bad = [r for r in runs if r["rc"] or r["warnings"] or r["errors"] or r["python_files"] or r.get("fmi_calls_not_ok")]
    if bad or not all(same.values()):
        sys.exit(1)


if __name__ == "__main__":
    main()
