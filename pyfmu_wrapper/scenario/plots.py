"""Drawing of computed results (computing lives in :mod:`pyfmu_wrapper.scenario.runner`).

Each ``*_plot`` function takes a data object and returns a :class:`matplotlib.figure.Figure`
built without pyplot (Agg canvas), so it works headless and never touches global state.
:func:`save_figure` writes a PNG.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from .frcmarks import coincident_labels, valley_inset

if TYPE_CHECKING:
    from pathlib import Path

    from matplotlib.axes import Axes
    from pandas import DataFrame

    from .runner import FRCData, MapData, PhaseData
    from .schema import FRCStudy, PhasePortraitStudy

_STYLE = {"up": "-", "down": "--"}
#: per curve: line style and marker, so that curves lying on top of each other stay visible
_LINESTYLES = ("-", "--", "-.", ":", (0, (5, 1, 1, 1, 1, 1)), (0, (1, 1)))
_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "<", ">")
#: units of the TMD parameters that curve labels name (legend title)
_UNITS = (
    ("c", "damping", "N s/m"),
    ("df", "friction_force", "N"),
    ("eps", "play_gap", "m"),
    ("k", "stiffness", "N/m"),
    ("m", "mass", "kg"),
    ("I", "inertance", "kg"),
    ("ki", "mesh_stiffness", "N/m"),
    ("ci", "mesh_damping", "N s/m"),
    ("Iratio", "inertance_ratio", "-"),
)
NOTE_NOT_CONVERGED = "not converged"
NOTE_IRREGULAR = "irregular (non-periodic): max over its windows"


def _figure(width: float = 7.0, height: float = 4.5, ncols: int = 1) -> tuple[Figure, list]:
    fig = Figure(figsize=(width * (1 if ncols == 1 else 0.75 * ncols), height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    return fig, list(axes)


def _units_title(study: PhasePortraitStudy | FRCStudy) -> str | None:
    """Legend title giving the units of the parameters the curve labels name or the curves differ in
    (e.g. "units: c [N s/m], df [N], eps [m]")."""
    import re

    curves = getattr(study, "curves", ())
    found = []
    for short, name, unit in _UNITS:
        named = any(re.search(rf"(?<![A-Za-z_]){short}\s*=", c.label) for c in curves)
        differs = len({getattr(c.tmd, name, None) for c in curves}) > 1 and name != "mass" and name != "inertance"
        if named or differs:
            found.append(f"{short} [{unit}]")
    return "units: " + ", ".join(found) if found else None


def _frc_words(data: FRCData) -> tuple[dict[str, str], str | None, str]:
    """What the legend of an FRC plot says of each curve and its heading, and the y-label's body.

    Each curve with a TMD: its attachment on a structure with several places for it (a frame:
    "storey 5, inerter to the ground") and the value of every TMD parameter that differs between the
    study's curves or that a label names ("c = 56.38"); the heading gives the units of exactly those
    symbols, so heading and entries match. The y-label names the body whose displacement is the
    amplitude (the base, the top storey)."""
    import re

    from ..models import MODELS
    from .summary import attachment, response_body

    study = data.study
    structs = getattr(data, "structures", {}) or {}
    first = next(iter(structs.values()), None)
    body = response_body(first) if first is not None else "the base"
    takes = [MODELS.of(s).takes_tmd for s in structs.values()] if structs else [True]
    tmd_curves = [c for c in study.curves if not c.without_tmd]
    shown = []
    for short, name, unit in _UNITS:
        if short == "Iratio" or not all(takes):
            continue
        differs = len({getattr(c.tmd, name, None) for c in tmd_curves}) > 1
        if differs:
            shown.append((short, name, unit))
    words: dict[str, str] = {}
    for c in study.curves:
        parts = []
        att = attachment(structs.get(c.label)) if (structs.get(c.label) is not None and not c.without_tmd) else None
        if att is not None:
            parts.append(str(att["text"]))
        if not c.without_tmd and all(takes):
            vals = [f"{short} = {float(getattr(c.tmd, name)):.4g}" for short, name, _ in shown]
            if vals:
                parts.append(", ".join(vals))
        words[c.label] = f"{c.label}\n  ({'; '.join(parts)})" if parts else c.label
    symbols = {s for s, _, _ in shown}
    named = [
        f"{short} [{unit}]"
        for short, _, unit in _UNITS
        if short in symbols or any(re.search(rf"(?<![A-Za-z_]){short}\s*=", c.label) for c in study.curves)
    ]
    return words, ("units: " + ", ".join(named) if named else None), body


def _with_peaks(omega: Any, amp: Any, peak: dict | None) -> tuple[Any, Any]:
    """The curve's points with its refined maxima put in (the summary's peak between grid points),
    so the drawn maximum is the reported one."""
    if not peak or not peak.get("local_maxima"):
        return omega, amp
    w = np.asarray(omega, float)
    a = np.asarray(amp, float)
    extra = [(p["omega"], p["amplitude"]) for p in peak["local_maxima"] if not np.any(w == p["omega"])]
    if not extra:
        return w, a
    w2 = np.concatenate([w, [e[0] for e in extra]])
    a2 = np.concatenate([a, [e[1] for e in extra]])
    order = np.argsort(w2, kind="stable")
    return w2[order], a2[order]


def _curve_style(k: int, n_points: int, one_direction: bool) -> dict:
    """Line style, marker and width of curve k: each curve differs from the others in all three,
    the earlier ones wider (drawn underneath), so identical curves still show both."""
    every = max(1, n_points // 8)
    return dict(
        ls=_LINESTYLES[k % len(_LINESTYLES)] if one_direction else None,
        marker=_MARKERS[k % len(_MARKERS)],
        ms=4.5,
        markevery=(k % every, every) if every > 1 else None,
        lw=max(1.0, 2.6 - 0.3 * k),
        zorder=2 + 0.01 * k,
    )


def frc_plot(data: FRCData, ax: Axes | None = None) -> Figure:
    """Frequency-response curves: base amplitude max|x| [m] against omega [rad/s].

    Every curve has its own colour, line style and marker (a curve lying exactly on another stays
    visible); with sweeps up and down, up is solid and down dashed. The base alone (no TMD) is
    black. The legend sits outside the axes, with the parameters' units as its title and the
    markers of points not converged (x) and irregular (open circle).
    """
    tab = data.table
    has_ref = "reference" in tab and np.isfinite(tab["reference"].to_numpy(float)).any()
    embedded = ax is not None  # a panel of someone else's figure: the legend stays inside it
    dax = None
    if ax is None and has_ref:  # engine 'both': FRCs on top, relative difference below
        fig = Figure(figsize=(9.5, 6.5), layout="constrained")
        FigureCanvasAgg(fig)
        ax, dax = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1])
    elif ax is None:
        fig, (ax,) = _figure(width=9.5)
    else:
        fig = ax.figure  # type: ignore[assignment]  # an Axes of the caller's figure (a SubFigure's is a Figure's too)
    one_direction = tab["direction"].nunique() == 1
    any_bad = any_irr = False
    for k, (label, t) in enumerate(tab.groupby("curve", sort=False)):
        color = "black" if _without(data.study, label) else None  # the base alone: black, as in the paper
        style = _curve_style(k, t["omega"].nunique(), one_direction)
        line = None
        for d, td in t.groupby("direction", sort=False):
            kw: dict[str, Any] = (
                dict(color=line.get_color()) if line is not None else (dict(color=color) if color else {})
            )
            lab = label if line is None else f"{label} ({d})"
            ls = style["ls"] if one_direction else _STYLE.get(d, "-")
            pw, pa = _with_peaks(td["omega"], td["amplitude"], (data.peaks.get(label) or {}).get(d))
            if style["markevery"] is not None and len(pw) != len(td):  # the markers stay on the grid points
                style = dict(
                    style,
                    markevery=[int(i) for i in np.flatnonzero(np.isin(pw, td["omega"]))][
                        style["markevery"][0] :: style["markevery"][1]
                    ],
                )
            (line,) = ax.plot(
                pw,
                pa,
                ls=ls,
                marker=style["marker"],
                ms=style["ms"],
                markevery=style["markevery"],
                mfc="white" if d == "down" else None,
                label=lab,
                lw=style["lw"],
                zorder=style["zorder"],
                **kw,
            )
            if has_ref:
                ax.plot(td["omega"], td["reference"], ":", color=line.get_color(), lw=0.8, alpha=0.8)
            irr = td["irregular"].fillna(False).astype(bool) if "irregular" in td else pd.Series(False, index=td.index)
            bad = td[~td["converged"].astype(bool)]  # an irregular point may be not converged too: both marks
            if len(bad):
                any_bad = True
                ax.plot(
                    bad["omega"], bad["amplitude"], "x", color=line.get_color(), ms=7, mew=1.5, zorder=5, clip_on=False
                )
            if irr.any():  # irregular (rattling, non-periodic): the maximum over its windows, marked
                any_irr = True
                ax.plot(
                    td["omega"][irr],
                    td["amplitude"][irr],
                    "o",
                    mfc="none",
                    color=line.get_color(),
                    ms=8,
                    mew=1.3,
                    zorder=5,
                    clip_on=False,
                )
            if dax is not None:
                diff = 100.0 * td["difference"].to_numpy(float)
                irr_both = irr.to_numpy() | (
                    td["reference_irregular"].to_numpy(float) == 1.0 if "reference_irregular" in td else False
                )
                dax.plot(
                    td["omega"],
                    np.where(irr_both, np.nan, diff),
                    ls=ls,
                    color=line.get_color(),
                    lw=1.2,
                    marker=".",
                    ms=3,
                )
                if irr_both.any():  # clipped to the regular points' range below: drawn on its edge
                    dax.plot(
                        td["omega"][irr_both],
                        diff[irr_both],
                        "o",
                        mfc="none",
                        color=line.get_color(),
                        ms=6,
                        gid="irregular",
                    )
    words, heading, body = _frc_words(data)
    ax.set_ylabel(f"max |x| of {body} [m]")
    if dax is not None:
        _difference_axes(dax, tab)
    else:
        ax.set_xlabel(r"$\omega$ [rad/s]")
    ax.set_title(data.study.title)
    lo, hi = float(np.min(data.study.omegas)), float(np.max(data.study.omegas))
    if hi > lo:  # one frequency (e.g. a corrected model at one steady record): matplotlib's own margins
        ax.set_xlim(lo, hi)
    if getattr(data.study, "yscale", "linear") == "log":
        pos = tab["amplitude"].to_numpy(float)
        pos = pos[np.isfinite(pos) & (pos > 0)]
        ax.set_yscale("log")
        if pos.size:
            ax.set_ylim(0.7 * float(pos.min()), 1.4 * float(pos.max()))
    else:
        top = ax.get_ylim()[1]
        ax.set_ylim(-0.03 * top, top)  # a mark at zero amplitude stays whole above the axis
    ax.grid(alpha=0.3)
    if not embedded:
        valley_inset(ax, tab)
    handles, labels = ax.get_legend_handles_labels()
    labels = coincident_labels(tab, labels)
    labels = [_worded(lb, words) for lb in labels]
    if has_ref:
        handles.append(Line2D([], [], ls=":", color="0.3"))
        labels.append("monolithic (thin dotted)")
    notes = [
        (Line2D([], [], ls="none", marker="x", color="0.3", ms=7, mew=1.5), NOTE_NOT_CONVERGED, any_bad),
        (Line2D([], [], ls="none", marker="o", mfc="none", color="0.3", ms=8), NOTE_IRREGULAR, any_irr),
    ]
    for h, text, present in notes:
        if present or not embedded:
            handles.append(h)
            labels.append(text + ("" if present else " (none)"))
    if embedded:
        ax.legend(handles, labels, fontsize=6, title=heading, title_fontsize=6)
    else:
        ax.legend(
            handles,
            labels,
            fontsize=8,
            title=heading,
            title_fontsize=8,
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            borderaxespad=0.0,
            frameon=False,
        )
    return fig


def _worded(label: str, words: dict[str, str]) -> str:
    """A legend entry with its curve's attachment and parameters (:func:`_frc_words`): the entry is the
    curve's label, possibly with " (down)" or a coincidence note after it."""
    for name in sorted(words, key=len, reverse=True):
        if label == name or label.startswith(name + " "):
            extra = words[name][len(name) :]
            return name + label[len(name) :] + extra
    return label


def _difference_axes(dax: Axes, tab: DataFrame) -> None:
    """Engine 'both': the headline is the largest |difference| over the regular points; irregular
    points (open circles) have no single amplitude and are shown apart with their own scatter."""
    d = tab["difference"].to_numpy(float)
    irr = tab["irregular"].fillna(False).astype(bool).to_numpy() if "irregular" in tab else np.zeros(len(d), bool)
    if "reference_irregular" in tab:
        irr = irr | (tab["reference_irregular"].to_numpy(float) == 1.0)
    conv = tab["converged"].fillna(False).astype(bool).to_numpy() if "converged" in tab else np.ones(len(d), bool)
    reg = np.abs(
        d[~irr & conv & np.isfinite(d)]
    )  # the points both engines call regular (sweeptable.engine_differences)
    head = (
        f"max |difference| over {reg.size} points both engines call regular = {100 * reg.max():.3g} %"
        if reg.size
        else "no point both engines call regular"
    )
    if reg.size and irr.any():  # the scale of the regular points; an irregular point outside sits on the edge
        lim = max(1.3 * 100 * float(reg.max()), 0.05)
        dax.set_ylim(-lim, lim)
        for ln in dax.get_lines():
            if ln.get_gid() == "irregular":
                ln.set_ydata(np.clip(np.asarray(ln.get_ydata(), float), -lim, lim))
                ln.set_clip_on(False)
    if irr.any():
        parts = []
        for _, r in tab[irr].iterrows():
            sc = r.get("change", np.nan)
            parts.append(f"{r['omega']:g} rad/s: {100 * r['difference']:.3g} % (window scatter {100 * sc:.2g} %)")
        shown = "; ".join(parts[:3]) + (f"; +{len(parts) - 3} more" if len(parts) > 3 else "")
        head += f"\nirregular (o, not in the maximum; on the edge when outside the scale): {shown}"
    dax.set_xlabel(r"$\omega$ [rad/s]")
    dax.set_ylabel("cosim / monolithic - 1 [%]")
    dax.set_title(f"co-simulation against monolithic (thin dotted): {head}", fontsize=8)
    dax.grid(alpha=0.3)


def _without(study: FRCStudy, label: str) -> bool:
    return any(c.label == label and c.without_tmd for c in study.curves)


_PARAM_LABELS = {
    "damping": "c [N s/m]",
    "friction_force": "df [N]",
    "play_gap": r"$\varepsilon$ [m]",
    "inertance_ratio": r"$I_{ratio}$ [-]",
    "inertance": "I [kg]",
    "mass": "m [kg]",
    "stiffness": "k [N/m]",
    "friction_slope": "friction slope [s/m]",
    "mesh_stiffness": "ki [N/m]",
    "mesh_damping": "ci [N s/m]",
}


def map_plot(data: MapData, ax: Axes | None = None) -> Figure:
    """Two-parameter diagram: colour = max|x| [m] over (omega, parameter value)."""
    if ax is None:
        fig, (ax,) = _figure()
    else:
        fig = ax.figure  # type: ignore[assignment]  # an Axes of the caller's figure (a SubFigure's is a Figure's too)
    st = data.study
    w, v = np.asarray(st.omegas, float), np.asarray(st.values, float)
    if len(w) > 1 and len(v) > 1:
        mesh = ax.pcolormesh(w, v, data.amplitude, shading="nearest", cmap="viridis")
    else:
        mesh = ax.imshow(
            data.amplitude,
            aspect="auto",
            origin="lower",
            cmap="viridis",
            extent=(w[0] - 0.5, w[-1] + 0.5, v[0] - 0.5, v[-1] + 0.5),
        )
    fig.colorbar(mesh, ax=ax, label="max |x| [m]")
    ax.set_xlabel(r"$\omega$ [rad/s]")
    ax.set_ylabel(_PARAM_LABELS.get(st.parameter, st.parameter))
    ax.set_title(st.title)
    return fig


def phase_portrait_plot(data: PhaseData) -> Figure:
    """Steady-state phase portraits (x, xd) of the base, one panel per omega, one line per curve."""
    st = data.study
    fig, axes = _figure(width=5.0, height=4.8, ncols=len(st.omegas))
    for ax, w in zip(axes, st.omegas):
        for k, c in enumerate(st.curves):
            ts = data.series[(w, c.label)]
            # earlier curves wider underneath, the last one thin and solid on top (its rattle kinks visible)
            last = k == len(st.curves) - 1
            ax.plot(
                ts.states[:, 0],
                ts.states[:, 1],
                ls="-" if last or k % 2 == 0 else "--",
                lw=max(0.8, 3.0 - 0.7 * k),
                label=c.label,
                zorder=2 + k,
            )
        ax.set_xlabel("x [m]")
        ax.set_ylabel(r"$\dot x$ [m/s]")
        ax.set_title(rf"{st.title}: $\omega$ = {w:g} rad/s", fontsize=9)
        ax.xaxis.set_major_locator(MaxNLocator(nbins=4, symmetric=True))  # readable ticks on narrow panels
        ax.yaxis.set_major_locator(MaxNLocator(nbins=6, symmetric=True))
        ax.ticklabel_format(axis="both", style="sci", scilimits=(-2, 3), useMathText=True)
        ax.grid(alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(
        handles,
        labels,
        fontsize=8,
        loc="outside lower center",
        ncols=min(len(labels), 4),
        title=_units_title(st),
        title_fontsize=8,
        frameon=False,
    )
    return fig


def plot_study(data: Any) -> Figure:
    """The figure for any study data object."""
    kind = data.study.kind
    if kind == "frc":
        return frc_plot(data)
    if kind == "map":
        return map_plot(data)
    return phase_portrait_plot(data)


def save_figure(fig: Figure, path: Path, dpi: int = 120) -> None:
    fig.savefig(path, dpi=dpi)
