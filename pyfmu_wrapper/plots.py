"""Drawing of computed results (computing lives in :mod:`pyfmu_wrapper.scenario.runner`).

Each ``*_plot`` function takes a data object and returns a :class:`matplotlib.figure.Figure`
built without pyplot (Agg canvas), so it works headless and never touches global state.
:func:`save_figure` writes a PNG.
"""
from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

_STYLE = {"up": "-", "down": "--"}


def _figure(width=7.0, height=4.5, ncols=1) -> tuple[Figure, list]:
    fig = Figure(figsize=(width * (1 if ncols == 1 else 0.75 * ncols), height), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, ncols, squeeze=False)[0]
    return fig, list(axes)


def frc_plot(data, ax=None) -> Figure:
    """Frequency-response curves: base amplitude max|x| [m] against omega [rad/s].

    Down-sweeps of nonlinear curves are dashed; the base alone (no TMD) is black.
    """
    tab = data.table
    has_ref = "reference" in tab and np.isfinite(tab["reference"].to_numpy(float)).any()
    dax = None
    if ax is None and has_ref:  # engine 'both': FRCs on top, relative difference below
        fig = Figure(figsize=(7.0, 6.5), layout="constrained")
        FigureCanvasAgg(fig)
        ax, dax = fig.subplots(2, 1, sharex=True, height_ratios=[2.2, 1])
    elif ax is None:
        fig, (ax,) = _figure()
    else:
        fig = ax.figure
    for label, t in data.table.groupby("curve", sort=False):
        color = "black" if _without(data.study, label) else None  # the base alone: black, as in the paper
        line = None
        for d, td in t.groupby("direction", sort=False):
            kw = dict(color=line.get_color()) if line is not None else (dict(color=color) if color else {})
            lab = label if line is None else f"{label} ({d})"
            (line,) = ax.plot(td["omega"], td["amplitude"], _STYLE.get(d, "-"), label=lab,
                              lw=1.0 if color else 1.4, zorder=3 if color else 2, **kw)
            if has_ref:
                ax.plot(td["omega"], td["reference"], ":", color=line.get_color(), lw=1.0)
                if dax is not None:
                    dax.plot(td["omega"], 100.0 * td["difference"], _STYLE.get(d, "-"), color=line.get_color(),
                             lw=1.2, marker=".", ms=3)
            irr = td["irregular"].fillna(False).astype(bool) if "irregular" in td else np.zeros(len(td), bool)
            bad = td[~td["converged"].astype(bool) & ~irr]
            if len(bad):
                ax.plot(bad["omega"], bad["amplitude"], "x", color=line.get_color(), ms=6)
            if irr.any():  # irregular (rattling, non-periodic): the maximum over its windows, marked
                ax.plot(td["omega"][irr], td["amplitude"][irr], "o", mfc="none", color=line.get_color(), ms=5)
    ax.set_xlabel(r"$\omega$ [rad/s]")
    ax.set_ylabel("max |x| [m]")
    ax.text(0.01, 0.01, "x: not converged   o: irregular (non-periodic; max over its windows)",
            transform=ax.transAxes, fontsize=7, color="0.4", va="bottom")
    if dax is not None:
        dmax = float(np.nanmax(np.abs(tab["difference"].to_numpy(float))))
        dax.set_xlabel(r"$\omega$ [rad/s]")
        dax.set_ylabel("cosim / monolithic - 1 [%]")
        dax.set_title(f"co-simulation (solid) against monolithic (dotted): max |difference| = {100 * dmax:.3g} %",
                      fontsize=9)
        dax.grid(alpha=0.3)
    ax.set_title(data.study.title)
    ax.set_xlim(float(np.min(data.study.omegas)), float(np.max(data.study.omegas)))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _without(study, label) -> bool:
    return any(c.label == label and c.without_tmd for c in study.curves)


_PARAM_LABELS = {
    "damping": "c [N s/m]", "friction_force": "df [N]", "play_gap": r"$\varepsilon$ [m]",
    "inertance_ratio": r"$I_{ratio}$ [-]", "inertance": "I [kg]", "mass": "m [kg]", "stiffness": "k [N/m]",
    "friction_slope": "friction slope [s/m]", "mesh_stiffness": "ki [N/m]", "mesh_damping": "ci [N s/m]",
}


def map_plot(data, ax=None) -> Figure:
    """Two-parameter diagram: colour = max|x| [m] over (omega, parameter value)."""
    if ax is None:
        fig, (ax,) = _figure()
    else:
        fig = ax.figure
    st = data.study
    w, v = np.asarray(st.omegas, float), np.asarray(st.values, float)
    if len(w) > 1 and len(v) > 1:
        mesh = ax.pcolormesh(w, v, data.amplitude, shading="nearest", cmap="viridis")
    else:
        mesh = ax.imshow(data.amplitude, aspect="auto", origin="lower", cmap="viridis",
                         extent=(w[0] - 0.5, w[-1] + 0.5, v[0] - 0.5, v[-1] + 0.5))
    fig.colorbar(mesh, ax=ax, label="max |x| [m]")
    ax.set_xlabel(r"$\omega$ [rad/s]")
    ax.set_ylabel(_PARAM_LABELS.get(st.parameter, st.parameter))
    ax.set_title(st.title)
    return fig


def phase_portrait_plot(data) -> Figure:
    """Steady-state phase portraits (x, xd) of the base, one panel per omega, one line per curve."""
    st = data.study
    fig, axes = _figure(width=5.0, height=4.5, ncols=len(st.omegas))
    for ax, w in zip(axes, st.omegas):
        for c in st.curves:
            ts = data.series[(w, c.label)]
            ax.plot(ts.states[:, 0], ts.states[:, 1], lw=0.9, label=c.label)
        ax.set_xlabel("x [m]")
        ax.set_ylabel(r"$\dot x$ [m/s]")
        ax.set_title(rf"{st.title}: $\omega$ = {w:g} rad/s", fontsize=9)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    return fig


def plot_study(data) -> Figure:
    """The figure for any study data object."""
    kind = data.study.kind
    if kind == "frc":
        return frc_plot(data)
    if kind == "map":
        return map_plot(data)
    return phase_portrait_plot(data)


def save_figure(fig: Figure, path, dpi: int = 120) -> None:
    fig.savefig(path, dpi=dpi)
