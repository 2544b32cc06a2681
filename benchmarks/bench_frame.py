"""The 10-storey frame with its TMD-inerter (scenarios/frame10_tmd.yaml), 81-point FRC: the
co-simulation (ShearFrame + TMDInerter FMUs, Python-hosted) against the monolithic engine's integrated
steady states (shooting; not the exact path), side by side in one run, each held against the exact
response of the structure's matrices (physics/frame.py).

Run by hand:  python benchmarks/bench_frame.py [--count N]
Prints the table; the numbers are recorded in benchmarks/README.md. Timings are a ratio in the same
run (the machine is shared and noisy). Target of issue 29: the co-simulation at most 2x monolithic.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from pyfmu_wrapper.cosim.frame_system import sweep as cosim_sweep
from pyfmu_wrapper.cosim.settings import CosimSettings
from pyfmu_wrapper.physics import frame as ref
from pyfmu_wrapper.physics.frame_model import FrameParams
from pyfmu_wrapper.physics.params import TMDParams
from pyfmu_wrapper.solvers.sweep import sweep as mono_sweep


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--count", type=int, default=81, help="frequencies over 10-30 rad/s (81: the scenario's)")
    args = ap.parse_args()
    frame = FrameParams.uniform(10, 100.0, 1.8e6, 200.0, force_amplitude=200.0, tmd_storey=10)
    tmd = TMDParams(mass=15.0, stiffness=8000.0, damping=40.0, inerter="ideal", inertance=5.0)
    w = np.linspace(10.0, 30.0, args.count)
    exact = ref.top_amplitude(
        ref.ShearFrame.uniform(10, 100.0, 1.8e6, 200.0, force_amplitude=200.0),
        ref.LinearTMD(10, 15.0, 8000.0, 40.0, 5.0),
        w,
    )
    # warm up both (numba compile, FMU build) on one point
    mono_sweep(frame, tmd, w[:1])
    cosim_sweep(frame, tmd, w[:1], settings=CosimSettings())
    t0 = time.perf_counter()
    mono = mono_sweep(frame, tmd, w).table
    t_mono = time.perf_counter() - t0
    t0 = time.perf_counter()
    co = cosim_sweep(frame, tmd, w, settings=CosimSettings())
    t_co = time.perf_counter() - t0
    e_mono = np.max(np.abs(mono["amplitude"].to_numpy() / exact - 1))
    e_co = np.max(np.abs(co["amplitude"].to_numpy() / exact - 1))
    print(f"10-storey frame + TMD-inerter, {len(w)} frequencies, 10-30 rad/s")
    print("| engine | wall time | periods (mean) | max relative error against the exact response |")
    print("|---|---|---|---|")
    print(f"| monolithic (RODAS4 + shooting) | {t_mono:.2f} s | {mono['periods'].mean():.1f} | {e_mono:.2e} |")
    print(f"| co-simulation (Python-hosted FMUs) | {t_co:.2f} s | {co['periods'].mean():.1f} | {e_co:.2e} |")
    print(f"ratio co-simulation / monolithic: {t_co / t_mono:.1f}x (target <= 2x)")


if __name__ == "__main__":
    main()
