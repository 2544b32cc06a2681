"""The claims of Section 5 of the paper (Fig. 4: dry friction in the TMD link), in report order."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .. import claim_data as cd
from ..claim_data import PAPER_DFOPT
from .table import CASES, FIG3, FIG4, Check, ClaimResult, Context, claim, nc_note

# --- Sect. 5, Fig. 4 --------------------------------------------------------------------------------


@claim("5 / Fig. 4", "Optimised df (Cases 1-3)", " / ".join(f"{PAPER_DFOPT[c]}" for c in CASES), FIG4)
def _dfopt(ctx: Context) -> ClaimResult:
    rowh2 = [cd.row_h2(ctx.data(n, "friction_map")) for n in FIG4]
    if ctx.quick:
        best, how = rowh2, "H2 from the map rows (parabola through the grid minimum; --quick: optimiser skipped)"
    else:
        best = [
            cd.h2_optimum(
                ctx.runs[n].scenario.base,
                replace(ctx.data(n, "friction_map").study.tmds[0], friction_force=0.0),
                "tmd.friction_force",
                ctx.runs[n].scenario.solver.settings(),
            )
            for n in FIG4
        ]
        how = "H2 optimum over 15-25 rad/s (pyfmu_wrapper.paper.optimise, 101 frequencies)"
    ctx.shared["dfopt"] = best
    dev = max(abs(h - PAPER_DFOPT[c]) / PAPER_DFOPT[c] for h, c in zip(best, CASES))
    nc = sum(cd.not_converged(ctx.data(n, "friction_map")) for n in FIG4)
    return (
        f"{how}: "
        + " / ".join(f"{h:.2f}" for h in best)
        + " N; from the map rows: "
        + " / ".join(f"{h:.1f}" for h in rowh2)
        + " N"
        + nc_note(nc),
        (Check("max relative deviation", dev, "<=", 0.05),),
        "Objective of the paper not stated; H2 as for c.",
    )


@claim("5 / Fig. 4", "The optimum df is smaller the bigger the inertance", "45.78 > 37.65 > 15.44", FIG4)
def _dfopt_order(ctx: Context) -> ClaimResult:
    best = ctx.shared.get("dfopt") or [cd.row_h2(ctx.data(n, "friction_map")) for n in FIG4]
    return (
        "H2 optimum: " + " > ".join(f"{h:.1f}" for h in best) + " N",
        (Check("largest step from one Case to the next", float(np.diff(best).max()), "<", 0.0, "N"),),
        "",
    )


@claim("5 / Fig. 4", "The range of good df shrinks as Iratio grows", "qualitative", FIG4)
def _df_width(ctx: Context) -> ClaimResult:
    widths = [cd.row_opt(ctx.data(n, "friction_map"))[2] for n in FIG4]
    return (
        "width of the df range whose peak is within 10 % of the best: " + " / ".join(f"{w:.0f}" for w in widths) + " N",
        (
            Check("Case 1 - Case 3", widths[0] - widths[2], ">", 0.0, "N"),
            Check("largest increase from one Case to the next", float(np.diff(widths).max()), "<=", 0.0, "N"),
        ),
        "",
    )


@claim("5", "A properly chosen dry friction widens the range of effectiveness", "qualitative", FIG4)
def _df_widens(ctx: Context) -> ClaimResult:
    cells, gains, steps = [], [], []
    for c in CASES:
        frc = ctx.data(f"fig4_case{c}", "friction_frc")
        w0, a0 = cd.curve(frc, "df = 0")
        wo, ao = cd.curve(frc, f"df = {PAPER_DFOPT[c]:g}")
        _, ab = cd.curve(frc, "no TMD")
        level = 0.5 * ab.max()
        r0, ro = cd.effective_width(w0, a0, level), cd.effective_width(wo, ao, level)
        gains.append(ro - r0)
        steps.append(2.0 * float(np.diff(w0).max()))
        cells.append(f"Case {c}: {r0:.2f} -> {ro:.2f} rad/s")
    return (
        "width of the band where max|x| <= half the base-alone peak, df = 0 -> df_opt: " + "; ".join(cells),
        tuple(Check(f"Case {c}: widening", g, ">", s, "rad/s") for c, g, s in zip(CASES, gains, steps)),
        "Widening counted when larger than two frequency steps of the grid.",
    )


@claim("5", "Dry friction changes the FRC more suddenly than viscous damping", "qualitative", FIG3 + FIG4)
def _sudden(ctx: Context) -> ClaimResult:
    cells, checks = [], []
    for c in CASES:
        fm = ctx.data(f"fig4_case{c}", "friction_map")
        vm = ctx.data(f"fig3_case{c}", "damping_map")
        vals = np.asarray(fm.study.values, float)
        sf = cd.map_suddenness(fm)
        sv = cd.map_suddenness(_on_omegas(vm, fm.study.omegas), vals)
        cells.append(f"Case {c}: friction {sf:.2f}, viscous {sv:.2f}")
        checks.append(Check(f"Case {c}: friction / viscous", sf / sv, ">", 1.0))
    return (
        "largest change of max|x| between neighbouring parameter values, per range of the parameter (0-100), "
        "relative to the map's maximum: " + "; ".join(cells),
        tuple(checks),
        "Both maps on the friction map's parameter values and frequencies.",
    )


def _on_omegas(mapdata: Any, omegas: Sequence[float] | NDArray[np.float64]) -> Any:
    """A copy of a map's data resampled on other frequencies (linear interpolation along omega)."""
    w = np.asarray(mapdata.study.omegas, float)
    amp = np.array([np.interp(omegas, w, row) for row in mapdata.amplitude])
    return replace(mapdata, amplitude=amp, study=replace(mapdata.study, omegas=np.asarray(omegas, float)))


@claim(
    "5 / Fig. 4",
    "For large df (90 N) no significant resonance peak; near resonance the amplitude falls "
    "roughly linearly with w (Cases 1, 2)",
    "qualitative (Cases 1, 2)",
    FIG4[:2],
)
def _large_df(ctx: Context) -> ClaimResult:
    cells, checks = [], []
    for c in (1, 2):
        w, a = cd.curve(ctx.data(f"fig4_case{c}", "friction_frc"), "df = 90")
        sel = (w >= 18) & (w <= 22)
        p = np.polyfit(w[sel], a[sel], 1)
        res = a[sel] - np.polyval(p, w[sel])
        r2 = 1 - res.var() / a[sel].var()
        cells.append(f"Case {c}: slope 18-22 rad/s {p[0]:.4f} m/(rad/s), R^2 {r2:.2f}")
        checks += [
            Check(f"Case {c}: slope", p[0], "<", 0.0, "m/(rad/s)"),
            Check(f"Case {c}: R^2 of the line", r2, ">=", 0.85),
        ]
    return (
        "; ".join(cells),
        tuple(checks),
        "The text points to Fig. 3 (d, f) here; it means Fig. 4. 'Roughly linear' read as R^2 >= 0.85.",
    )


@claim(
    "5 (notes)",
    "The TMD sticks to the base for part of each cycle above df ~ 20-30 N (Case 1)",
    "physics notes, not the paper",
    ["fig4_case1"],
)
def _sticking(ctx: Context) -> ClaimResult:
    from ...scenario.engines import RunSettings

    r = ctx.runs["fig4_case1"]
    tmd = r.datas["friction_map"].study.tmds[0]
    settings = RunSettings(solver=r.scenario.solver)
    dfs = [10.0, 20.0, 30.0, 40.0, 60.0, 90.0]
    wst = (15.0, 17.0, 19.0, 20.0, 21.0, 23.0, 25.0)
    fr = {
        df: max(cd.stuck_fraction(r.scenario.base, replace(tmd, friction_force=df), w, settings) for w in wst)
        for df in dfs
    }
    first = next((df for df in dfs if fr[df] > 0.01), float("nan"))
    return (
        "largest stuck fraction of the period (|xd - yd| < 1e-4 m/s) over w = 15..25 rad/s: "
        + ", ".join(f"{df:g} N: {fr[df]:.0%}" for df in dfs),
        (
            Check("first df with sticking", first, ">=", 15.0, "N"),
            Check("first df with sticking", first, "<=", 40.0, "N"),
        ),
        "Monolithic time series (1 period, 2000 samples).",
    )
