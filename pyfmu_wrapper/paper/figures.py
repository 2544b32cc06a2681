"""The paper's Figs. 2-6, drawn from the runs of :func:`.reproduce.run_all` (PNG files).

Each figure is assembled from the scenario runner's own study plots (:mod:`pyfmu_wrapper.scenario.plots`)
recoloured as in the paper, plus the panels the paper adds (phase portraits, full vs simplified model).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ..models.solve import exact_amplitude
from ..scenario import plots
from .claim_data import PAPER_SIMPLIFIED, curve
from .reproduce import CASES, Run


def _fig(nrows: int, ncols: int, w: float = 4.6, h: float = 3.3) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=(w * ncols, h * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def _letter(ax: Any, k: int) -> None:
    ax.set_title(f"({'abcdefghi'[k]}) " + ax.get_title(), fontsize=9)


def _maps_and_frcs(
    runs: dict[str, Run], names: Sequence[str], map_name: str, frc_name: str, path: Path, dpi: int
) -> None:
    fig, axes = _fig(len(names), 2)
    for i, n in enumerate(names):
        r = runs[n]
        plots.map_plot(r.datas[map_name], ax=axes[i, 0])
        plots.frc_plot(r.datas[frc_name], ax=axes[i, 1])
        order = [cv.label for cv in r.datas[frc_name].study.curves]
        colors = ["black", "gold", "red", "green", "blue"]  # the paper's: no TMD, 0, 10, optimum, 90
        for line in axes[i, 1].get_lines():
            lab = str(line.get_label()).split(" (up)")[0].split(" (down)")[0]
            if lab in order and order.index(lab) < len(colors):
                line.set_color(colors[order.index(lab)])
        axes[i, 1].legend(fontsize=6)
        for j in range(2):
            axes[i, j].set_title(axes[i, j].get_title(), fontsize=9)
        _letter(axes[i, 0], 2 * i)
        _letter(axes[i, 1], 2 * i + 1)
    fig.savefig(path, dpi=dpi)


#: the figures draw_figures can write (figures/<name>.png)
FIGURES = ["fig2", "fig3", "fig4", "fig5", "fig6"]


def draw_figures(runs: dict, figdir: Path, dpi: int = 80) -> dict:
    figdir.mkdir(parents=True, exist_ok=True)
    out = {}
    if "fig2_iratio" in runs:
        fig, axes = _fig(1, 2)
        plots.map_plot(runs["fig2_iratio"].datas["iratio_map"], ax=axes[0, 0])
        plots.frc_plot(runs["fig2_iratio"].datas["iratio_frc"], ax=axes[0, 1])
        axes[0, 1].legend(fontsize=6)
        _letter(axes[0, 0], 0)
        _letter(axes[0, 1], 1)
        fig.savefig(figdir / "fig2.png", dpi=dpi)
        out["fig2"] = "fig2.png"
    for f, mp, fr in ((3, "damping_map", "damping_frc"), (4, "friction_map", "friction_frc")):
        names = [f"fig{f}_case{c}" for c in CASES if f"fig{f}_case{c}" in runs]
        if names:
            _maps_and_frcs(runs, names, mp, fr, figdir / f"fig{f}.png", dpi)
            out[f"fig{f}"] = f"fig{f}.png"
    names = [f"fig5_case{c}" for c in CASES if f"fig5_case{c}" in runs]
    if names:
        fig, axes = _fig(3, len(names))
        colors = ["black", "green", "red", "blue"]
        for j, n in enumerate(names):
            plots.map_plot(runs[n].datas["play_map"], ax=axes[0, j])
            axes[0, j].set_title(axes[0, j].get_title(), fontsize=9)
            _letter(axes[0, j], j)
            ph = runs[n].datas["play_phase"]
            for i, w_phase in enumerate((21.0, 19.0)):
                ax = axes[1 + i, j]
                for col, cv in zip(colors, ph.study.curves):
                    ts = ph.series.get((w_phase, cv.label))
                    if ts is not None:
                        ax.plot(ts.states[:, 0], ts.states[:, 1], lw=0.7, color=col, label=cv.label)
                ax.set_xlabel("x [m]")
                ax.set_ylabel(r"$\dot x$ [m/s]")
                ax.set_title(f"Case {n[-1]}: phase portrait, w = {w_phase:g} rad/s", fontsize=9)
                ax.legend(fontsize=6)
                ax.grid(alpha=0.3)
                _letter(ax, 3 * (1 + i) + j)
        fig.savefig(figdir / "fig5.png", dpi=dpi)
        out["fig5"] = "fig5.png"
    names = [f"fig6_case{c}" for c in CASES if f"fig6_case{c}" in runs]
    if names:
        fits = runs.get("_fits", {})
        fig, axes = _fig(len(names), 2)
        for i, n in enumerate(names):
            c = int(n[-1])
            d6 = runs[n].datas["full_frc"]
            plots.frc_plot(d6, ax=axes[i, 0])
            paper_colors = {"1:": "black", "2:": "gold", "3:": "blue", "4:": "red", "5:": "green", "6:": "orange"}
            for line in axes[i, 0].get_lines():
                color = paper_colors.get(str(line.get_label())[:2])
                if color:
                    line.set_color(color)
                    if str(line.get_label()).startswith("2:"):
                        line.set_linestyle("--")  # overlapped by curve 1, as in the paper
            axes[i, 0].legend(fontsize=6)
            axes[i, 0].set_title(f"Case {c}: the full model and its parts", fontsize=9)
            ax = axes[i, 1]
            w, full = curve(d6, "5:")
            ws, simp = curve(d6, "6:")
            ax.plot(w, full, color="green", lw=1.3, label="5: full model")
            ax.plot(ws, simp, color="orange", lw=1.3, label=f"6: simplified, c = {PAPER_SIMPLIFIED[c]:g} (+50 %)")
            ax.fill_between(w, full, np.interp(w, ws, simp), color="0.6", alpha=0.5, lw=0)
            if c in fits:
                tmd = next(cv.tmd for cv in d6.study.curves if cv.label.startswith("6:"))
                cb = fits[c]["area"]["c"]
                wd = np.linspace(w.min(), w.max(), 1001)
                ax.plot(
                    wd,
                    exact_amplitude(runs[n].scenario.base, replace(tmd, damping=cb), wd),
                    ":",
                    color="purple",
                    lw=1.2,
                    label=f"best fit (area), c = {cb:.2f}",
                )
            ax.set_xlim(w.min(), w.max())
            ax.set_ylim(bottom=0)
            ax.set_xlabel(r"$\omega$ [rad/s]")
            ax.set_ylabel("max |x| [m]")
            ax.set_title(f"Case {c}: full vs simplified (grey: area between)", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=6)
            _letter(axes[i, 0], 2 * i)
            _letter(ax, 2 * i + 1)
        fig.savefig(figdir / "fig6.png", dpi=dpi)
        out["fig6"] = "fig6.png"
    return out
