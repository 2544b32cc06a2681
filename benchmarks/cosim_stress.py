"""The co-simulation against the monolithic solver on a grid of stress cases (issue 28).

    nice python benchmarks/cosim_stress.py [--quick] [--out benchmarks/results/cosim_stress.json]

Grid: base mass M in {1e-3, 0.1, 100, 1e4} kg x link (TMD spring) stiffness k in {1e2, 4e3, 2e5,
1e7} N/m x forcing omega in {0.05, 0.5, 5, 20, 200} rad/s, the ideal inerter of Case 1 (m = 9 kg,
I = 1 kg) with c = 10 N s/m (so that no amplitude is zero to rounding), base K = 4e4 N/m,
C = 100 N s/m, F = 200 N; plus a few points of the play model (eps = 1e-4 m, ki = 2e7 N/m).
Reference: the exact frequency response (linear, ideal inerter) or the monolithic steady-state
solver (play). Each point: the co-simulated amplitude, its deviation cosim / reference - 1,
whether the co-simulation reported it converged, the coupling-error estimate, the steps per
period and the reason of a flagged point. Target: no point reported converged and off by more
than 0.5 %. Prints a markdown table (for docs/cosimulation.md) and writes the JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent

MASSES = (1e-3, 0.1, 100.0, 1e4)
STIFFNESSES = (1e2, 4e3, 2e5, 1e7)
OMEGAS = (0.05, 0.5, 5.0, 20.0, 200.0)
#: (M, k, omegas) of the play points
PLAY = (
    (100.0, 4e3, (5.0, 18.0, 22.0)),
    (0.1, 4e3, (18.0, 22.0)),
    (1e-3, 4e3, (20.0,)),
    (100.0, 2e5, (20.0,)),
    (1e4, 4e3, (5.0,)),
)
TARGET = 5e-3


def _pair(M: float, k: float, play: bool) -> tuple:
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    base = BaseParams(mass=M, stiffness=4e4, damping=100.0, force_amplitude=200.0)
    tmd = TMDParams(mass=9.0, inertance=1.0, stiffness=k, damping=10.0, inerter="ideal")
    if play:
        tmd = TMDParams(
            mass=9.0, inertance=1.0, stiffness=k, damping=10.0, inerter="play", play_gap=1e-4, mesh_stiffness=2e7
        )
    return base, tmd


def _reference(base: object, tmd: object, omegas: tuple, play: bool) -> list[float]:
    from pyfmu_wrapper.models.solve import exact_amplitude, steady_state

    if not play:
        return [float(a) for a in exact_amplitude(base, tmd, np.asarray(omegas, float))]  # type: ignore[arg-type]
    return [float(steady_state(base, tmd, w).amplitude) for w in omegas]  # type: ignore[arg-type]


def run_config(M: float, k: float, omegas: tuple, play: bool) -> list[dict]:
    from pyfmu_wrapper.cosim.settings import CosimSettings
    from pyfmu_wrapper.models.base_tmd import UNIT

    sweep = UNIT.cosim().sweep

    base, tmd = _pair(M, k, play)
    ref = _reference(base, tmd, omegas, play)
    t0 = time.perf_counter()
    table = sweep(base, tmd, sorted(omegas), "up", CosimSettings())
    wall = time.perf_counter() - t0
    rows = []
    by_w = {float(w): r for w, r in zip(omegas, ref)}
    for _, r in table.iterrows():
        a, rf = float(r["amplitude"]), by_w[float(r["omega"])]
        dev = a / rf - 1.0 if math.isfinite(a) and rf != 0.0 else math.nan
        conv = bool(r["converged"])
        rows.append(
            dict(
                model="play" if play else "ideal",
                M=M,
                k=k,
                omega=float(r["omega"]),
                reference=rf,
                cosim=a,
                deviation=dev,
                converged=conv,
                flagged=not conv,
                coupling_error=float(r["coupling_error"]),
                steps_per_period=int(r["steps_per_period"]),
                periods=int(r["periods"]),
                wall_time=float(r["wall_time"]),
                reason=str(r["reason"]),
                bad=bool(conv and not (abs(dev) <= TARGET)),
            )
        )
    print(f"M={M:g} k={k:g} {'play' if play else 'ideal'}: {wall:.1f} s", file=sys.stderr, flush=True)
    return rows


def _short(reason: str) -> str:
    """A flagged point's reason in a few words (the full sentence is in the JSON)."""
    if not reason:
        return ""
    if "communication steps per forcing period" in reason:  # refused by the structure's time scale
        what = reason.split(" (")[0]
        rate = reason.split(" is ")[1].split(":")[0]
        need = reason.split("needs ")[1].split(" communication")[0]
        return f"refused: {what} = {rate} needs {need} steps/period"
    if reason.startswith("the FMUs failed"):
        return reason.split(" (status")[0][:110]
    return reason[:120]


def markdown(rows: list[dict]) -> str:
    out = [
        "| model | M [kg] | k [N/m] | omega [rad/s] | reference [m] | deviation | converged | estimate | steps/period | wall [s] | reason (flagged points) |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        dev = "-" if not math.isfinite(r["deviation"]) else f"{r['deviation']:+.2e}"
        est = "-" if not math.isfinite(r["coupling_error"]) else f"{r['coupling_error']:.1e}"
        conv = "yes" if r["converged"] else "**flagged**"
        if r["bad"]:
            conv = "**yes, off by > 0.5 %**"
        reason = _short(r["reason"])
        out.append(
            f"| {r['model']} | {r['M']:g} | {r['k']:g} | {r['omega']:g} | {r['reference']:.4g} | {dev} | {conv} "
            f"| {est} | {r['steps_per_period'] or '-'} | {r['wall_time']:.2f} | {reason} |"
        )
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="two masses, two stiffnesses, three frequencies, no play")
    p.add_argument("--out", default=str(HERE / "results" / "cosim_stress.json"))
    p.add_argument("--table", metavar="JSON", help="only print the markdown table of an earlier run's JSON")
    args = p.parse_args(argv)
    if args.table:
        print(markdown(json.loads(Path(args.table).read_text(encoding="utf-8"))["rows"]))
        return 0
    masses: tuple[float, ...] = MASSES
    stiff: tuple[float, ...] = STIFFNESSES
    omegas: tuple[float, ...] = OMEGAS
    play: tuple = PLAY
    if args.quick:
        masses, stiff, omegas, play = (1e-3, 100.0), (4e3, 1e7), (0.5, 20.0, 200.0), ()
    t0 = time.perf_counter()
    rows: list[dict] = []
    for M in masses:
        for k in stiff:
            rows += run_config(M, k, omegas, False)
    for M, k, ws in play:
        rows += run_config(M, k, ws, True)
    wall = time.perf_counter() - t0
    bad = [r for r in rows if r["bad"]]
    flagged = [r for r in rows if r["flagged"]]
    ok = [r for r in rows if r["converged"]]
    summary = dict(
        points=len(rows),
        converged=len(ok),
        flagged=len(flagged),
        converged_and_off=len(bad),
        max_abs_deviation_converged=max((abs(r["deviation"]) for r in ok), default=None),
        wall_time=wall,
    )
    print(markdown(rows))
    print(json.dumps(summary, indent=2))
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(dict(summary=summary, rows=rows), indent=2, default=float) + "\n", encoding="utf-8")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
