"""The claims of Sections 6-7 of the paper (Figs. 5-6: play in the inerter gear, the simplified model),
in report order."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .. import claim_data as cd
from ..claim_data import FULL_C
from .table import CASES, FIG4, FIG5, FIG6, Check, ClaimResult, Context, claim, fmt, nc_note, not_run

# --- Sect. 6, Fig. 5 --------------------------------------------------------------------------------


@claim("6 / Fig. 5a-c", "No overall macroscopic influence of play on max|x| for eps up to 2e-3 m", "qualitative", FIG5)
def _play_macro(ctx: Context) -> ClaimResult:
    cells, checks, pts = [], [], {}
    for c in CASES:
        m = ctx.data(f"fig5_case{c}", "play_map")
        A = m.amplitude
        d = float(np.abs(A - A[0][None, :]).max() / A[0].max())
        rel_peak = float(np.abs(A.max(axis=1) - A[0].max()).max() / A[0].max())
        pts[c] = d
        cells.append(
            f"Case {c}: max |A(eps) - A(0)| = {d:.1%} of the peak, row peaks within {rel_peak:.2%}"
            + nc_note(cd.not_converged(m))
        )
        checks += [Check(f"Case {c}: row peaks", rel_peak, "<=", 0.02), Check(f"Case {c}: any point", d, "<=", 0.05)]
    ctx.shared["play_influence"] = pts
    return ("; ".join(cells), tuple(checks), "Map points are independent steady states.")


@claim("6", "With the TMD active the base amplitude is at least 100 x the gap (eps = 1e-4 m)", ">= 1e-2 m", FIG6[:1])
def _hundred_gap(ctx: Context) -> ClaimResult:
    cells, checks = [], []
    for c in CASES:
        if f"fig6_case{c}" not in ctx.runs:
            continue
        d6 = ctx.data(f"fig6_case{c}", "full_frc")
        w, a = cd.curve(d6, "2:")
        k = int(np.argmin(a))
        cells.append(
            f"Case {c}: min {a[k]:.2e} m at {w[k]:.1f} rad/s ({a[k] / 1e-4:.2f} x eps)" + nc_note(cd.not_converged(d6))
        )
        checks.append(Check(f"Case {c}: min amplitude / eps", a[k] / 1e-4, ">=", 100.0))
    return (
        "; ".join(cells) + not_run(ctx, "fig6_case"),
        tuple(checks),
        "Near w = 20 rad/s (antiresonance, c = 0) the base amplitude is smaller than the gap itself.",
    )


@claim(
    "6 / Fig. 5d-i",
    "Phase portraits get less smooth, with more and larger fluctuations, as the gap grows (eps = 0, 5e-5, 1e-4, 1e-3)",
    "qualitative",
    FIG5,
)
def _rough(ctx: Context) -> ClaimResult:
    cells, checks, spread = [], [], {}
    for c in CASES:
        ph = ctx.data(f"fig5_case{c}", "play_phase")
        labels = [cv.label for cv in ph.study.curves]
        mean = [
            float(np.mean([cd.roughness(ph.series[(w, lab)], ph.study.n_periods) for w in ph.study.omegas]))
            for lab in labels
        ]
        spread[c] = mean[-1]
        cells.append(f"Case {c}: " + ", ".join(fmt(x, 2) for x in mean))
        checks += [
            Check(f"Case {c}: distortion at eps = 1e-3 minus at eps = 0", mean[-1] - mean[0], ">", 1e-3),
            Check(f"Case {c}: eps = 1e-3 / largest of the smaller gaps", mean[-1] / max(mean[:-1]), ">=", 1.0),
        ]
    ctx.shared["roughness"] = spread
    return (
        "distortion of xd (RMS of the non-forcing harmonics / forcing harmonic, mean of w = 19, 21), "
        "eps = 0, 5e-5, 1e-4, 1e-3: " + " | ".join(cells),
        tuple(checks),
        "Less smooth read as: a distortion larger by more than 1e-3 at eps = 1e-3 than at eps = 0, and the largest "
        "at the largest gap.",
    )


@claim("6 / Fig. 5", "The effects of play do not depend on Iratio", "qualitative", FIG5)
def _play_iratio(ctx: Context) -> ClaimResult:
    if "roughness" not in ctx.shared:
        _rough(ctx)
    if "play_influence" not in ctx.shared:
        _play_macro(ctx)
    sp, pts = ctx.shared["roughness"], ctx.shared["play_influence"]
    rs = max(sp.values()) / max(min(sp.values()), 1e-12)
    ra = max(pts.values()) / max(min(pts.values()), 1e-12)
    return (
        "distortion of xd at eps = 1e-3, Cases 1-3: "
        + " / ".join(fmt(sp[c], 2) for c in CASES)
        + "; largest change of max|x| by the gap: "
        + " / ".join(f"{pts[c]:.1%}" for c in CASES),
        (
            Check("largest / smallest distortion", rs, "<", 3.0),
            Check("largest / smallest change of max|x|", ra, "<", 3.0),
        ),
        "Independence read as: both measures within a factor 3 between Cases.",
    )


# --- Sect. 7, Fig. 6 --------------------------------------------------------------------------------


@claim(
    "7 / Fig. 6",
    "Play alone causes no macroscopic change of the FRC (curve 2 overlapped by curve 1)",
    "overlapped",
    FIG6[:1],
)
def _play_alone(ctx: Context) -> ClaimResult:
    cells, checks = [], []
    for c in CASES:
        if f"fig6_case{c}" not in ctx.runs:
            continue
        d6 = ctx.data(f"fig6_case{c}", "full_frc")
        _, a1 = cd.curve(d6, "1:")
        _, a2 = cd.curve(d6, "2:")
        d = float(np.abs(a2 - a1).max() / a1.max())
        cells.append(f"Case {c}: {d:.2%}" + nc_note(cd.not_converged(d6)))
        checks.append(Check(f"Case {c}: max |A2 - A1| / max A1", d, "<=", 0.02))
    return (
        "; ".join(cells) + not_run(ctx, "fig6_case"),
        tuple(checks),
        "'Overlapped' read as within 2 % of the peak.",
    )


@claim(
    "7 / Fig. 6b, d, f",
    "Simplified model (viscous c raised by 50 %: 15 / 15 / 7.5 N s/m) matches the full model "
    "with only slight disagreement",
    "15 / 15 / 7.5",
    FIG6[:1],
)
def _simplified(ctx: Context) -> ClaimResult:
    fits = ctx.fits()
    return (
        "; ".join(
            f"Case {c}: max error {f['paper']['max']:.2e} m ({f['paper']['rel_max']:.1%} of the peak), area "
            f"{f['paper']['rel_area']:.1%}; best-fit c (area) {f['area']['c']:.2f}"
            for c, f in fits.items()
        )
        + not_run(ctx, "fig6_case"),
        tuple(Check(f"Case {c}: max error / peak", f["paper"]["rel_max"], "<", 0.10) for c, f in fits.items()),
        "'Slight' read as a maximum error below 10 % of the full model's peak. Best fits: table below.",
    )


@claim("7", "The agreement of the simplified model is the greater, the bigger Iratio", "Case 3 best", FIG6)
def _simplified_order(ctx: Context) -> ClaimResult:
    fits = ctx.fits()
    ra = [fits[c]["paper"]["rel_area"] for c in CASES]
    return (
        "relative area between the curves, paper's c: " + " / ".join(f"{x:.1%}" for x in ra),
        (Check("largest step of the error from one Case to the next", float(np.diff(ra).max()), "<", 0.0),),
        "",
    )


@claim("7 / Sect. 8", "The simplified model holds only for relatively small c and df", "qualitative", FIG4)
def _simplified_small(ctx: Context) -> ClaimResult:
    from ...scenario.engines import RunSettings

    scales = (1.0, 9.0)  # the paper's c = df = 10 (5 for Case 3) and its 'large' 90 (45)
    w = np.linspace(15.0, 25.0, 21 if ctx.quick else 101)
    cells, checks = [], []
    for c in CASES:
        r = ctx.runs[f"fig4_case{c}"]
        tmd = r.datas["friction_map"].study.tmds[0]
        res = cd.simplified_error_by_size(
            r.scenario.base,
            replace(tmd, friction_force=0.0),
            w,
            RunSettings(solver=r.scenario.solver),
            FULL_C[c],
            scales,
        )
        small, large = res[0], res[-1]
        cells.append(
            f"Case {c}: c = df = {small['c']:g}: {small['rule']['rel_max']:.1%} (best fit {small['best']['rel_max']:.1%}); "
            f"c = df = {large['c']:g}: {large['rule']['rel_max']:.1%} (best fit {large['best']['rel_max']:.1%})"
            + nc_note(small["not_converged"] + large["not_converged"])
        )
        checks += [
            Check(
                f"Case {c}: best-fit error, large / small",
                large["best"]["rel_max"] / small["best"]["rel_max"],
                ">",
                2.0,
            ),
            Check(f"Case {c}: best-fit error at c = df = {large['c']:g}", large["best"]["rel_max"], ">=", 0.10),
        ]
    return (
        "max error / peak of the simplified model (+50 % rule, and the best-fit c) against the model with c and df "
        "(ideal inerter): " + "; ".join(cells),
        tuple(checks),
        "Play left out (it alone changes no FRC macroscopically). 'Holds only for small' read as: at nine times the "
        "paper's c and df (90 N s/m and 90 N, the paper's 'large' values; 45 for Case 3) even the best viscous c "
        "misses by >= 10 % of the peak, more than twice the error at the paper's values.",
    )
