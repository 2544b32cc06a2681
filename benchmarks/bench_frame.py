"""The 10-storey frame with its TMD-inerter (scenarios/frame10_tmd.yaml), 81-point FRC: the
co-simulation (ShearFrame + TMDInerter FMUs; native, and Python-hosted) against the monolithic
engine's integrated steady states (shooting; not the exact path), side by side in one run, each held
against the exact response of the structure's matrices (physics/frame.py).

Run by hand:  python benchmarks/bench_frame.py [--count N] [--profile]
Prints the table; the numbers are recorded in benchmarks/README.md. Timings are a ratio in the same
run (the machine is shared and noisy). Target of issue 29: the co-simulation at most 2x monolithic.
``--profile``: where one point's time goes (20 rad/s, each build): periods, communication steps, and
the time per communication step inside the ShearFrame FMU, inside the TMDInerter FMU and in the
master's compiled loop (:meth:`~pyfmu_wrapper.master.master.Master.timing`).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from pyfmu_wrapper.cosim.periods import run_steady
from pyfmu_wrapper.cosim.settings import CosimSettings
from pyfmu_wrapper.models.frame_model import UNIT, FrameParams
from pyfmu_wrapper.models.frame_model import cosim as frame_system
from pyfmu_wrapper.models.solve import sweep as mono_sweep
from pyfmu_wrapper.physics import frame as ref
from pyfmu_wrapper.physics.params import TMDParams

FRAME = FrameParams.uniform(10, 100.0, 1.8e6, 200.0, force_amplitude=200.0, tmd_storey=10)
TMD = TMDParams(mass=15.0, stiffness=8000.0, damping=40.0, inerter="ideal", inertance=5.0)
#: the frame's co-simulation as run-scenario calls it
cosim_sweep = UNIT.cosim().sweep
BUILDS = {"native": "native FMUs (no Python)", "python": "Python-hosted FMUs"}


def profile(omega: float = 20.0) -> None:
    """One point of each co-simulation build, without the coupling check (the engine's run at one step count,
    :func:`~pyfmu_wrapper.cosim.periods.run_steady`): where the time goes."""
    settings = replace(CosimSettings(), accuracy=frame_system.FRAME_ACCURACY)
    n = settings.steps_for(TMD)
    print(f"one point, {omega:g} rad/s, {n} steps per period (no coupling check)")
    print("| build | periods | steps | wall | ShearFrame per step | TMDInerter per step | master per step |")
    print("|---|---|---|---|---|---|---|")
    for build, label in BUILDS.items():
        master = frame_system.make_master(FRAME, TMD, settings.order, settings.fmi_version, build)
        try:
            system = frame_system.FramePairSystem(UNIT, FRAME, TMD)
            run_steady(master, system, omega, None, settings, {}, n)  # warm up
            before = master.timing()
            t0 = time.perf_counter()
            ss = run_steady(master, system, omega, None, settings, {}, n)
            wall = time.perf_counter() - t0
            after = master.timing()
        finally:
            master.close()
        us = {
            k: 1e6 * (v["seconds"] - before["fmus"][k]["seconds"]) / max(v["calls"] - before["fmus"][k]["calls"], 1)
            for k, v in after["fmus"].items()
        }
        own = 1e6 * (after["master_seconds"] - before["master_seconds"]) / ss.steps
        print(
            f"| {label} | {ss.periods} | {ss.steps} | {wall * 1e3:.1f} ms | {us['frame']:.2f} us | "
            f"{us['tmd']:.2f} us | {own:.2f} us |"
        )


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=81, help="frequencies over 10-30 rad/s (81: the scenario's)")
    ap.add_argument("--profile", action="store_true", help="also where one point's time goes, per build")
    args = ap.parse_args()
    w = np.linspace(10.0, 30.0, args.count)
    exact = ref.top_amplitude(
        ref.ShearFrame.uniform(10, 100.0, 1.8e6, 200.0, force_amplitude=200.0),
        ref.LinearTMD(10, 15.0, 8000.0, 40.0, 5.0),
        w,
    )
    # warm up every engine (numba compile, FMU builds) on one point
    mono_sweep(FRAME, TMD, w[:1])
    for build in BUILDS:
        cosim_sweep(FRAME, TMD, w[:1], settings=CosimSettings(fmu_build=build))
    rows = []
    t0 = time.perf_counter()
    mono = mono_sweep(FRAME, TMD, w).table
    t_mono = time.perf_counter() - t0
    e_mono = np.max(np.abs(mono["amplitude"].to_numpy() / exact - 1))
    rows.append(("monolithic (RODAS4 + shooting)", t_mono, mono["periods"].mean(), e_mono, "", ""))
    for build, label in BUILDS.items():
        t0 = time.perf_counter()
        co = cosim_sweep(FRAME, TMD, w, settings=CosimSettings(fmu_build=build))
        t_co = time.perf_counter() - t0
        e_co = np.max(np.abs(co["amplitude"].to_numpy() / exact - 1))
        checked = f"{co['coupling_error'].max():.1e}, {int(co['converged'].sum())}/{len(co)} converged"
        rows.append((f"co-simulation, {label}", t_co, co["periods"].mean(), e_co, checked, f"{t_co / t_mono:.2f}x"))
    print(f"10-storey frame + TMD-inerter, {len(w)} frequencies, 10-30 rad/s")
    print("| engine | wall time | periods (mean) | max relative error | coupling check (max estimate) | ratio |")
    print("|---|---|---|---|---|---|")
    for name, t, periods, err, checked, ratio in rows:
        print(f"| {name} | {t:.2f} s | {periods:.1f} | {err:.2e} | {checked} | {ratio} |")
    print("target of issue 29: co-simulation / monolithic <= 2x")
    if args.profile:
        profile()


if __name__ == "__main__":
    main()
