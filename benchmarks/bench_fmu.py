"""Cost per fmi2DoStep in a pure C host and under fmpy: the stub alone, the real FMUs, PythonFMU.

    python benchmarks/bench_fmu.py [--steps 200000] [--real-steps 20000] [--fuzz 2000] [--no-pythonfmu]

Real FMUs: BaseOscillator and TMDInerter (Case 1: m = 9 kg, I = 1 kg, c = 10 N.s/m), h = 1 ms,
each with every step through the Python slave (PYFMU_NATIVE=0: the path every step took before
the native step) and with the native step, in the same run as the stub-alone baseline.
``--fuzz N`` also runs the C fuzz harness (tests/c_host/fmu_fuzz.c) with N sequences.

Builds the ``Trivial`` FMU (y = gain * u; doStep only advances time) with ``build-fmus`` and an
equivalent PythonFMU slave (``pip install pythonfmu``, the ``bench`` extra), then runs both in
tests/c_host/fmu_host.c (``bench`` mode: dlopen RTLD_LOCAL, no Python in the host). PythonFMU's
binary does not link libpython, so its run needs LD_PRELOAD=<libpython> (ours needs nothing).
The same loops are also timed inside this Python process through fmpy's FMU2Slave ("under
fmpy"). Results are written to benchmarks/results/bench_fmu.json and printed.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from _fmu_support import compile_c_host, extract, guid  # noqa: E402

from pyfmu_wrapper.fmubuild.build import build_fmus  # noqa: E402
from pyfmu_wrapper.fmubuild.standalone import libpython_path  # noqa: E402
from pyfmu_wrapper.models.catalog import pick  # noqa: E402

PYTHONFMU_SLAVE = textwrap.dedent('''
    from pythonfmu import Fmi2Causality, Fmi2Variability, Fmi2Slave, Real


    class TrivialPF(Fmi2Slave):
        """y = gain * u; doStep only advances time."""

        def __init__(self, **kwargs):
            super().__init__(**kwargs)
            self.gain = 2.0
            self.u = 0.0
            self.y = 0.0
            self.register_variable(Real("gain", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
            self.register_variable(Real("u", causality=Fmi2Causality.input))
            self.register_variable(Real("y", causality=Fmi2Causality.output))

        def do_step(self, current_time, step_size):
            self.y = self.gain * self.u
            return True
''')


def _bench(exe, d, g, u, y, steps, env, params=()):
    r = subprocess.run(
        [str(exe), "bench", str(steps), str(d), g, str(u), str(y), *params],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
    )
    if r.returncode != 0:
        return {"error": (r.stderr or r.stdout)[-2000:]}
    return {k: float(v) for k, v in (l.split() for l in r.stdout.splitlines()) if k.startswith("us_")}


def _bench_fmpy(fmu: Path, unzip: Path, u: int, y: int, steps: int, start: dict | None = None) -> dict:
    """The same loops inside this Python process through fmpy's FMU2Slave (the stub shares the
    running interpreter; PythonFMU's binary resolves its Python symbols from it too)."""
    import time

    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    md = read_model_description(str(fmu))
    s = FMU2Slave(
        guid=md.guid, unzipDirectory=str(unzip), modelIdentifier=md.coSimulation.modelIdentifier, instanceName="bench"
    )
    s.instantiate()
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for vr, v in (start or {}).items():
        s.setReal([vr], [v])
    s.exitInitializationMode()
    h, t = 1e-3, 0.0
    for _ in range(1000):
        s.doStep(t, h)
        t += h
    t0 = time.perf_counter()
    for _ in range(steps):
        s.doStep(t, h)
        t += h
    us_do = (time.perf_counter() - t0) / steps * 1e6
    t0 = time.perf_counter()
    for k in range(steps):
        s.setReal([u], [float(k % 7) * (1e-4 if start else 1.0)])
        s.doStep(t, h)
        s.getReal([y])
        t += h
    us_sdg = (time.perf_counter() - t0) / steps * 1e6
    s.terminate()
    s.freeInstance()
    return {"us_per_doStep": us_do, "us_per_set_doStep_get": us_sdg}


def _pf_guid(d: Path) -> str:
    import re

    return re.search(r'guid="([^"]+)"', (d / "modelDescription.xml").read_text()).group(1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=200000)
    ap.add_argument("--real-steps", type=int, default=20000, help="steps of the real FMUs (per path)")
    ap.add_argument("--no-pythonfmu", action="store_true", help="skip the PythonFMU comparison")
    ap.add_argument("--fuzz", type=int, default=0, help="also run the C fuzz harness with this many sequences")
    args = ap.parse_args(argv)
    res = {"steps": args.steps, "real_steps": args.real_steps}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        exe = compile_c_host(tmp)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD"))}
        (fmu,) = build_fmus(pick("Trivial"), tmp / "ours")
        d = extract(fmu, tmp / "x")
        res["pyfmu_wrapper_stub"] = _bench(exe, d, guid(d), 1, 2, args.steps, env)
        res["pyfmu_wrapper_stub_fmpy"] = _bench_fmpy(fmu, d, 1, 2, args.steps // 4)
        # the real FMUs, h = 1 ms, Case 1 (m = 9, I = 1, c = 10): Python step vs native step
        real = build_fmus(pick(("BaseOscillator", "TMDInerter")), tmp / "real")
        cases = {"BaseOscillator": (10, 20, {}), "TMDInerter": (30, 40, {2: 10.0})}
        for f in real:
            dr = extract(f, tmp / "xr")
            u, y, start = cases[f.stem]
            params = [f"r:{vr}={v!r}" for vr, v in start.items()]
            for native in ("0", "1"):
                key = f"{f.stem}_{'native' if native == '1' else 'python'}"
                res[key] = _bench(exe, dr, guid(dr), u, y, args.real_steps, dict(env, PYFMU_NATIVE=native), params)
                os.environ["PYFMU_NATIVE"] = native  # read by the stub at fmi2Instantiate
                res[key + "_fmpy"] = _bench_fmpy(f, dr, u, y, args.real_steps // 4, start)
            os.environ.pop("PYFMU_NATIVE", None)
        if args.fuzz:
            import time

            from _fmu_support import run_fuzz  # noqa: E402

            t0 = time.perf_counter()
            fz = run_fuzz(tmp / "fuzz", args.fuzz, 160, seed=2026)
            fz.pop("stderr", None)
            res["fuzz"] = dict(fz, seconds=time.perf_counter() - t0)
        try:
            if args.no_pythonfmu:
                raise ImportError("skipped (--no-pythonfmu)")
            script = tmp / "TrivialPF.py"
            script.write_text(PYTHONFMU_SLAVE)
            subprocess.run(
                [sys.executable, "-m", "pythonfmu", "build", "-f", str(script), "-d", str(tmp / "pf")],
                check=True,
                capture_output=True,
                text=True,
            )
            pf = tmp / "pf" / "TrivialPF.fmu"
            dpf = extract(pf, tmp / "x")
            vrs = {}
            import fmpy

            for v in fmpy.read_model_description(str(pf)).modelVariables:
                vrs[v.name] = v.valueReference
            penv = dict(env, LD_PRELOAD=str(libpython_path()))
            sp = [p for p in sys.path if p.endswith("site-packages")]
            penv["PYTHONPATH"] = os.pathsep.join(sp)
            res["pythonfmu_no_preload"] = _bench(exe, dpf, _pf_guid(dpf), vrs["u"], vrs["y"], 1000, env)
            res["pythonfmu_ld_preload"] = _bench(exe, dpf, _pf_guid(dpf), vrs["u"], vrs["y"], args.steps, penv)
            res["pythonfmu_fmpy"] = _bench_fmpy(pf, dpf, vrs["u"], vrs["y"], args.steps // 4)
        except (subprocess.CalledProcessError, ImportError, FileNotFoundError) as e:
            res["pythonfmu_error"] = str(e) + getattr(e, "stderr", "")
    out = REPO / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_fmu.json").write_text(json.dumps(res, indent=2))
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
