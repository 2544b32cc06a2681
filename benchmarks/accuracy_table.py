"""One accuracy table of co-simulation masters on the same FMU pair, rerunnable.

    python benchmarks/accuracy_table.py [--steps 1e-3 3e-4 1e-4] [--periods 60] [--only this,ecos,...]

The pair: BaseOscillator + TMDInerter (this project's FMUs), Case 1 (m = 9 kg, I = 1 kg), damper
c = 10 N.s/m, ideal inerter, at 17 and 20 rad/s, and one play configuration (gear gap eps = 1e-4 m,
mesh ki = 2e7 N/m, same damper) at 17 rad/s. Every master runs ``--periods`` forcing periods with a
fixed communication step h from the same start (the monolithic linear steady state,
:func:`~pyfmu_wrapper.solvers.monolithic.initial_guess`) and the amplitude is max |base.x| over
the last 3 periods (20 with play, the monolithic solver's window), from base.x and base.xd at the
communication points with the cubic Hermite interpolant between them (the same rule for every
master). Error: amplitude / monolithic steady-state amplitude - 1. Observed order: log of the
error ratio between consecutive steps over log of the step ratio. Wall time per simulated
second: the transient part of the run (no sampling in it), FMU loading excluded.

Masters:
* this master (``pyfmu_wrapper.master``, compiled loop where it applies): the impulse coupling
  with the interface Jacobian (default of the cosim engine), the force coupling with the
  algebraic loop solved (Newton, Python path), Jacobi, Gauss-Seidel (quadratic extrapolation),
  and the naive zero-order-hold Jacobi;
* Ecos (pip ``ecospy``): its fixed-step master, force coupling (the value connections only);
* libcosim (pip ``libcosimpy``): its fixed-step algorithm, and ECCO (energy-conservation-based
  adaptive step with a power bond base.xd / tmd.force, its default tolerances, steps between h/10 and h; the mean step taken is recorded);
* OMSimulator when ``$OMSIMULATOR`` points to its executable (``benchmarks/omsimulator_fmu.py``
  exports the SSP and runs it with its defaults; its fixed-step master at h).

Results: benchmarks/results/accuracy_table.json and a markdown table on stdout (copied into
docs/cosimulation.md).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import sys
import tempfile
import time
import traceback
from importlib import metadata
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent

CONFIGS = {  # label -> (TMD overrides, omega)
    "c = 10, 17 rad/s": (dict(damping=10.0), 17.0),
    "c = 10, 20 rad/s": (dict(damping=10.0), 20.0),
    "play eps = 1e-4, c = 10, 17 rad/s": (dict(damping=10.0, inerter="play", play_gap=1e-4), 17.0),
}
THIS = {  # label -> (coupling, scheme, order)
    "this: impulse + interface Jacobian, o2": ("impulse", "jacobi", 2),
    "this: force, loop solved, o2": ("force", "loop", 2),
    "this: force, Jacobi, o2": ("force", "jacobi", 2),
    "this: force, Gauss-Seidel, o2": ("force", "gauss-seidel", 2),
    "this: force, zero-order hold (naive Jacobi)": ("force", "jacobi", 0),
}


def _version(name):
    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _hermite_max(x, v, t):
    """max |p| of the cubic Hermite interpolant through (t, x, v) (any spacing)."""
    from pyfmu_wrapper.solvers.hermite import hermite_absmax_series

    x, v, t = (np.asarray(a, float) for a in (x, v, t))
    dt = np.diff(t)
    if np.allclose(dt, dt[0], rtol=1e-6, atol=0):
        return float(hermite_absmax_series(x, v, float(dt[0])))
    return max(
        float(hermite_absmax_series(x[i : i + 2].copy(), v[i : i + 2].copy(), float(dt[i]))) for i in range(len(dt))
    )


def _setup(cfg):
    from pyfmu_wrapper.models.solve import initial_guess
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    over, w = CONFIGS[cfg]
    base, tmd = BaseParams(), TMDParams(**over)
    return base, tmd, w, initial_guess(base, tmd, w)


def _window(tmd):
    return 20 if tmd.inerter == "play" or str(tmd.inerter).endswith("PLAY") else 3


def run_this(label, cfg, h, periods):
    from pyfmu_wrapper.models.base_tmd.cosim import fmu_parameters, make_master

    coupling, scheme, order = THIS[label]
    base, tmd, w, z0 = _setup(cfg)
    T = 2 * math.pi / w
    W = _window(tmd)
    m = make_master(base, tmd, scheme, order, coupling=coupling)
    try:
        m.initialize(0.0, fmu_parameters(base, tmd, w, z0))
        n1 = int(round((periods - W) * T / h))
        n2 = int(round(periods * T / h)) - n1
        t0 = time.perf_counter()
        m.advance(n1, h)
        wall = time.perf_counter() - t0
        rec_t, rec_y = np.zeros(n2 + 1), np.zeros((n2 + 1, m.nsig))
        rec_t[0], rec_y[0] = m.t, m.y
        m.advance(n2, h, rec_t[1:], rec_y[1:])
        ix, iv = m.signals.index("base.x"), m.signals.index("base.xd")
        amp = _hermite_max(rec_y[:, ix], rec_y[:, iv], rec_t)
        return dict(amplitude=amp, wall_per_s=wall / (n1 * h))
    finally:
        m.close()


def _fmu_copies(tmp):
    from pyfmu_wrapper.fmubuild.build import ensure_fmus
    from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick

    p = ensure_fmus(pick(PROJECT_FMUS))
    return {n: Path(shutil.copy(p[n], Path(tmp) / p[n].name)) for n in ("BaseOscillator", "TMDInerter")}


def run_ecos(cfg, h, periods, fmus):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
    from _ecos_support import ecos_simulation

    base, tmd, w, z0 = _setup(cfg)
    T = 2 * math.pi / w
    W = _window(tmd)
    sim = ecos_simulation(fmus, base, tmd, w, z0, h)
    try:
        t1 = (periods - W) * T
        t0 = time.perf_counter()
        sim.step_until(t1)
        wall = time.perf_counter() - t0
        ts, xs, vs = [sim.get_time()], [sim.get_real("base::x")], [sim.get_real("base::xd")]
        while sim.get_time() < periods * T - 0.5 * h:
            sim.step(1)
            ts.append(sim.get_time())
            xs.append(sim.get_real("base::x"))
            vs.append(sim.get_real("base::xd"))
        sim.terminate()
    finally:
        sim.free()
    return dict(amplitude=_hermite_max(xs, vs, ts), wall_per_s=wall / t1)


def run_libcosim(cfg, h, periods, fmus, ecco=False):
    from libcosimpy.CosimAlgorithm import CosimAlgorithm, EccoParams
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver
    from libcosimpy.CosimSlave import CosimLocalSlave

    from pyfmu_wrapper.models.base_tmd.cosim import CONNECTIONS, fmu_parameters

    log_output_level(CosimLogLevel.ERROR)
    base, tmd, w, z0 = _setup(cfg)
    T = 2 * math.pi / w
    W = _window(tmd)
    if ecco:
        alg = CosimAlgorithm.create_ecco_algorithm(EccoParams(step_size=h, min_step_size=h / 10, max_step_size=h))
        ex = CosimExecution.from_algorithm(alg)
    else:
        ex = CosimExecution.from_step_size(int(round(h * 1e9)))  # nanoseconds
    idx = {
        "base": ex.add_local_slave(CosimLocalSlave(str(fmus["BaseOscillator"]), "base")),
        "tmd": ex.add_local_slave(CosimLocalSlave(str(fmus["TMDInerter"]), "tmd")),
    }
    vr = {(inst, v.name.decode()): int(v.reference) for inst, i in idx.items() for v in ex.slave_variables(i)}
    for c in CONNECTIONS:
        (si, sv), (di, dv) = (s.strip().split(".", 1) for s in c.split("->"))
        if ex.connect_real_variables(idx[si], vr[(si, sv)], idx[di], vr[(di, dv)]) < 0:
            raise RuntimeError(f"libcosim refused the connection {c}")
    if ecco:  # power bond: base (out: velocity, in: force) with tmd (out: force, in: velocity)
        alg.add_power_bond(
            idx["base"], vr[("base", "xd")], vr[("base", "f_link")], idx["tmd"], vr[("tmd", "force")], vr[("tmd", "xd")]
        )
    for key, val in fmu_parameters(base, tmd, w, z0).items():
        inst, var = key.split(".", 1)
        if isinstance(val, (bool, int)):
            ex.integer_initial_value(idx[inst], vr[(inst, var)], int(val))
        else:
            ex.real_initial_value(idx[inst], vr[(inst, var)], float(val))
    obs = CosimObserver.create_last_value()
    ex.add_observer(obs)
    t1 = (periods - W) * T
    t0 = time.perf_counter()
    if not ex.simulate_until(int(round(t1 * 1e9))):
        raise RuntimeError("libcosim: simulate_until failed")
    wall = time.perf_counter() - t0
    ts, xs, vs = [], [], []
    ib = idx["base"]
    k = 0
    while True:
        x, v = obs.last_real_values(ib, [vr[("base", "x")], vr[("base", "xd")]])
        ts.append(ex.status().current_time * 1e-9)
        xs.append(x)
        vs.append(v)
        if ts[-1] >= periods * T - 0.5 * h:
            break
        if not ex.step(1):
            raise RuntimeError("libcosim: step failed")
        k += 1
    # mean step over the sampled window (ECCO chooses its own steps, at most h)
    return dict(amplitude=_hermite_max(xs, vs, ts), wall_per_s=wall / t1, mean_step=(ts[-1] - ts[0]) / max(k, 1))


def run_omsimulator(cfg, h, periods):
    exe = os.environ.get("OMSIMULATOR")
    if not exe:
        return None
    import subprocess

    base, tmd, w, z0 = _setup(cfg)
    over = CONFIGS[cfg][0]
    if {k: v for k, v in over.items() if k not in ("inerter", "play_gap")} != dict(damping=10.0):
        return None  # omsimulator_fmu.py runs Case 1, c = 10, ideal or play inerter
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "oms.json"
        r = subprocess.run(
            [
                sys.executable,
                str(HERE / "omsimulator_fmu.py"),
                "--omega",
                str(w),
                "--step",
                str(h),
                "--periods",
                str(periods),
                "--window",
                str(_window(tmd)),
                "--play-gap",
                str(float(over.get("play_gap", 0.0))),
                "--out",
                str(out),
            ],
            capture_output=True,
            text=True,
        )
        if not out.is_file():
            raise RuntimeError((r.stderr or r.stdout)[-500:])
        data = json.loads(out.read_text())
    ssp = [x for x in data["runs"] if "omega" in x and abs(float(x["omega"]) - w) < 1e-9]
    if not ssp or ssp[0].get("amplitude") is None or ssp[0]["returncode"] != 0 or ssp[0]["errors"]:
        bad = ssp[0] if ssp else {}
        raise RuntimeError(f"OMSimulator: exit {bad.get('returncode')}, {bad.get('first_errors')}"[:300])
    # wall time: the OMSimulator process of the SSP run (FMU loading included), not this script's
    return dict(
        amplitude=float(ssp[0]["amplitude"]),
        wall_per_s=float(ssp[0]["wall_time_s"]) / (periods * 2 * math.pi / w),
        errors=ssp[0]["errors"],
        warnings=ssp[0]["warnings"],
    )


def reference(cfg):
    from pyfmu_wrapper.models import solve as mono

    base, tmd, w, _ = _setup(cfg)
    return float(mono.steady_state(base, tmd, w).amplitude)


MASTERS = list(THIS) + [
    "Ecos (fixed step, ZOH)",
    "libcosim fixed step (ZOH)",
    "libcosim ECCO (adaptive, h/10..h)",
    "OMSimulator oms-ma",
]


def run_one(master, cfg, h, periods, fmus):
    if master in THIS:
        return run_this(master, cfg, h, periods)
    if master.startswith("Ecos"):
        return run_ecos(cfg, h, periods, fmus)
    if master.startswith("libcosim fixed"):
        return run_libcosim(cfg, h, periods, fmus)
    if master.startswith("libcosim ECCO"):
        return run_libcosim(cfg, h, periods, fmus, ecco=True)
    return run_omsimulator(cfg, h, periods)


def markdown(res, steps) -> str:
    lines = []
    for cfg in res["reference"]:
        ref = res["reference"][cfg]
        lines.append(f"\n**{cfg}** (monolithic amplitude {ref:.6g} m)\n")
        head = " | ".join(f"h = {h:g} s" for h in steps)
        lines.append(
            f"| master | {head} | observed order | wall time / simulated s (h = {steps[0]:g}, {steps[-1]:g}) |"
        )
        lines.append("|---" * (len(steps) + 3) + "|")
        for master in MASTERS:
            rows = [res["runs"].get(f"{master}|{cfg}|{h!r}") for h in steps]
            if all(r is None for r in rows):
                continue
            cells, errs = [], []
            for r in rows:
                if r is None:
                    cells.append("not run")
                    errs.append(None)
                elif "error" in r:
                    cells.append("failed")
                    errs.append(None)
                else:
                    e = r["amplitude"] / ref - 1
                    cells.append(f"{e:+.2e}")
                    errs.append(abs(e))
            orders = []
            for (h1, e1), (h2, e2) in zip(zip(steps, errs), zip(steps[1:], errs[1:])):
                orders.append("-" if not e1 or not e2 else f"{math.log(e1 / e2) / math.log(h1 / h2):.2f}")
            walls = [f"{r['wall_per_s']:.3g} s" if r and "wall_per_s" in r else "-" for r in (rows[0], rows[-1])]
            lines.append(f"| {master} | {' | '.join(cells)} | {' / '.join(orders)} | {', '.join(walls)} |")
    return "\n".join(lines)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=float, nargs="+", default=[1e-3, 3e-4, 1e-4])
    p.add_argument("--periods", type=int, default=60)
    p.add_argument("--only", default="", help="comma-separated substrings of master names to run")
    p.add_argument("--configs", default="", help="comma-separated substrings of configurations to run")
    p.add_argument("--out", default=str(HERE / "results" / "accuracy_table.json"))
    args = p.parse_args(argv)
    masters = [m for m in MASTERS if not args.only or any(s.strip() and s.strip() in m for s in args.only.split(","))]
    cfgs = [c for c in CONFIGS if not args.configs or any(s.strip() in c for s in args.configs.split(","))]
    res = dict(
        machine=dict(
            cpus=os.cpu_count(),
            python=sys.version.split()[0],
            platform=platform.platform(),
            load_average=list(os.getloadavg()),
        ),
        versions={k: _version(k) for k in ("pyfmu-wrapper", "ecospy", "libcosimpy", "fmpy", "numpy")},
        omsimulator=os.environ.get("OMSIMULATOR"),
        periods=args.periods,
        steps=args.steps,
        reference={},
        runs={},
    )
    with tempfile.TemporaryDirectory() as tmp:
        fmus = _fmu_copies(tmp)
        for cfg in cfgs:
            res["reference"][cfg] = reference(cfg)
            for master in masters:
                for h in args.steps:
                    key = f"{master}|{cfg}|{h!r}"
                    try:
                        r = run_one(master, cfg, h, args.periods, fmus)
                    except Exception as e:  # noqa: BLE001  (a master that fails is a result of the table)
                        r = dict(error=f"{type(e).__name__}: {e}".splitlines()[0][:300])
                        traceback.print_exc(limit=2)
                    if r is not None:
                        res["runs"][key] = r
                        err = r.get("amplitude", float("nan")) / res["reference"][cfg] - 1
                        print(f"{key}: {r} error {err:+.3e}", flush=True)
    res["machine"]["load_average_end"] = list(os.getloadavg())
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(res, indent=1) + "\n")
    print(markdown(res, args.steps))
    print("wrote", args.out)


if __name__ == "__main__":
    main()
