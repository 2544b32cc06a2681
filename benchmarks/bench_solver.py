"""Monolithic solver speed against scipy Radau with a plain Python right-hand side, in one run.

Run by hand:  python benchmarks/bench_solver.py [--quick]
Prints a table and writes benchmarks/results/bench_solver.json. Numbers are recorded in
benchmarks/README.md. Timings are ratios in the same run (the machine is shared and noisy).

Cases (issue "Foundation", Speed):
1. dry friction, Case 1, df = 10 N, c = 0, 101-point FRC over 15-25 rad/s, accurate to 1e-4
   relative (checked against a tight-tolerance run of the same solver and, on a few points, the
   scipy baseline);
2. full model, Case 1 (c = 10, df = 10, eps = 1e-4, ki = 2e7, ci = 0.01), 101-point FRC, windowed
   steady state to 1e-4.
The scipy baseline integrates period after period from the previous frequency's state with
solve_ivp(method="Radau") until the per-period maximum of |x| changes by less than 1e-5
relative; it runs on a few points and is extrapolated to 101.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
from scipy.integrate import solve_ivp

from pyfmu_wrapper.models.solve import steady_state, sweep
from pyfmu_wrapper.physics.params import BaseParams, paper_case
from pyfmu_wrapper.solvers.monolithic import SolverSettings


def python_rhs(base, tmd, omega):
    M, K, C, F = base.mass, base.stiffness, base.damping, base.force_amplitude
    m, k, c, df, s, I = tmd.mass, tmd.stiffness, tmd.damping, tmd.friction_force, tmd.friction_slope, tmd.inertance

    def f(t, z):
        x, xd, y, yd = z
        Fs = k * (x - y) + c * (xd - yd) + df * 2 / math.pi * math.atan(s * (xd - yd))
        r1 = F * math.cos(omega * t) - C * xd - K * x - Fs
        det = (M + I) * (m + I) - I * I
        return [xd, ((m + I) * r1 + I * Fs) / det, yd, (I * r1 + (M + I) * Fs) / det]

    return f


def scipy_baseline(base, tmd, omegas, z0, tol=1e-5, max_periods=400):
    z = np.array(z0[:4], dtype=float)
    amps, t0 = [], time.perf_counter()
    for w in omegas:
        T = 2 * math.pi / w
        f = python_rhs(base, tmd, w)
        prev = None
        for _ in range(max_periods):
            sol = solve_ivp(f, (0, T), z, method="Radau", rtol=1e-8, atol=1e-11, dense_output=True)
            z = sol.y[:, -1]
            a = np.max(np.abs(sol.sol(np.linspace(0, T, 2001))[0]))
            if prev is not None and abs(a - prev) <= tol * a:
                break
            prev = a
        amps.append(a)
    return np.array(amps), time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true", help="fewer baseline points")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    base = BaseParams()
    w = np.linspace(15, 25, 101)
    out = {"machine": f"{os.cpu_count()} cores", "date": time.strftime("%Y-%m-%d")}

    # warm the compiled kernels (compilation is cached on disk, not part of the measurement)
    steady_state(base, paper_case(1, friction_force=10.0), 19.0)

    # --- 1. dry friction FRC ------------------------------------------------------------
    tmd = paper_case(1, friction_force=10.0)
    fast = SolverSettings(rtol=1e-7, atol_scale=1e-7, tol=1e-5)
    t0 = time.perf_counter()
    res = sweep(base, tmd, w, "up", fast).table
    t_ours = time.perf_counter() - t0
    ref = sweep(base, tmd, w, "up", SolverSettings(rtol=1e-11, atol_scale=1e-11, tol=1e-10)).table
    err = float(np.max(np.abs(res.amplitude.values / ref.amplitude.values - 1)))
    pts = w[::25] if not args.quick else w[::50]
    ss0 = steady_state(base, tmd, float(pts[0]))
    amps_b, t_b = scipy_baseline(base, tmd, pts, ss0.state)
    refb = ref.set_index("omega").amplitude.loc[pts].values
    err_b = float(np.max(np.abs(amps_b / refb - 1)))
    t_b101 = t_b / len(pts) * len(w)
    out["friction_frc"] = dict(
        points=len(w),
        ours_s=t_ours,
        ours_max_rel_err=err,
        scipy_points=len(pts),
        scipy_s=t_b,
        scipy_extrapolated_101_s=t_b101,
        scipy_max_rel_err=err_b,
        speedup=t_b101 / t_ours,
        periods=int(res.periods.sum()),
        steps=int(res.steps.sum()),
    )
    print(json.dumps(out["friction_frc"], indent=1))

    # --- 2. full model FRC ----------------------------------------------------------------
    full = paper_case(
        1, damping=10.0, friction_force=10.0, inerter="play", play_gap=1e-4, mesh_stiffness=2e7, mesh_damping=0.01
    )
    st = SolverSettings(rtol=1e-7, atol_scale=1e-7)
    for workers in sorted({1, args.workers}):
        t0 = time.perf_counter()
        r = sweep(base, full, w, "up", st, workers=workers).table
        dt = time.perf_counter() - t0
        out[f"full_frc_workers{workers}"] = dict(
            points=len(w),
            seconds=dt,
            periods=int(r.periods.sum()),
            steps=int(r.steps.sum()),
            rejected=int(r.rejected.sum()),
            converged=bool(r.converged.all()),
            peak=float(r.amplitude.max()),
            peak_omega=float(r.omega[r.amplitude.idxmax()]),
        )
        print(json.dumps(out[f"full_frc_workers{workers}"], indent=1))
    os.makedirs(os.path.join(os.path.dirname(__file__), "results"), exist_ok=True)
    with open(os.path.join(os.path.dirname(__file__), "results", "bench_solver.json"), "w") as fh:
        json.dump(out, fh, indent=1)


if __name__ == "__main__":
    main()
