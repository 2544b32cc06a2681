"""Marks that help read a frequency-response plot: a curve lying on an earlier one says so in the
legend, and a valley where curves bunch gets a zoom of its own."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from pandas import DataFrame


def _curves(tab: DataFrame) -> dict[str, pd.Series]:
    """Amplitude against omega per curve (the first direction of each)."""
    out = {}
    for label, t in tab.groupby("curve", sort=False):
        first = t[t["direction"] == t["direction"].iloc[0]]
        out[str(label)] = first.set_index("omega")["amplitude"].astype(float)
    return out


def coincident_labels(tab: DataFrame, labels: list[str]) -> list[str]:
    """A curve that lies on an earlier one (within 1 % of the larger peak everywhere) says so in the
    legend, with its largest difference: otherwise one of the two is simply not seen."""
    curves = _curves(tab)
    names = list(curves)
    out = list(labels)
    for k, name in enumerate(names):
        for j in range(k):
            a, b = curves[names[j]], curves[name]
            common = a.index.intersection(b.index)
            if len(common) < 3:
                continue
            peak = float(np.nanmax(np.abs(np.r_[a[common].to_numpy(), b[common].to_numpy()])))
            diff = float(np.nanmax(np.abs(a[common].to_numpy() - b[common].to_numpy())))
            if peak > 0 and diff < 0.01 * peak and name in out:
                i = out.index(name)
                out[i] = f"{name}\n  (on curve {names[j].split(':')[0]}: differs by at most {diff:.2g} m)"
                break
    return out


def valley_inset(ax: Axes, tab: DataFrame) -> None:
    """Where several curves bunch in a valley between two peaks (the TMD's antiresonance), a zoom of
    that valley on its own scale, in the free space above it."""
    curves = _curves(tab)
    if len(curves) < 2:
        return
    omegas = np.array(sorted(set().union(*(c.index for c in curves.values()))))
    upper = np.array([max(float(c.get(w, np.nan)) for c in curves.values()) for w in omegas])
    if not np.isfinite(upper).all() or len(omegas) < 7:
        return
    i0 = i1 = int(np.argmin(upper))  # the valley: around the lowest point, below 15 % of the peak
    limit = 0.15 * np.nanmax(upper)
    while i0 > 0 and upper[i0 - 1] < limit:
        i0 -= 1
    while i1 < len(omegas) - 1 and upper[i1 + 1] < limit:
        i1 += 1
    if i1 - i0 < 2 or i0 == 0 or i1 == len(omegas) - 1:
        return  # no interior valley
    idx = np.arange(i0, i1 + 1)
    w0, w1 = omegas[idx[0]], omegas[idx[-1]]
    x0, x1 = ax.get_xlim()
    left = max(0.02, min(0.6, ((w0 + w1) / 2 - x0) / (x1 - x0) - 0.19))
    ins = ax.inset_axes((left, 0.5, 0.38, 0.42))
    for line in ax.get_lines():
        xd = np.asarray(line.get_xdata(), float)
        yd = np.asarray(line.get_ydata(), float)
        keep = (xd >= w0) & (xd <= w1)
        if keep.sum() >= 1 and not str(line.get_label()).startswith("_child"):
            ins.plot(
                xd[keep],
                yd[keep],
                ls=line.get_linestyle(),
                marker=line.get_marker(),
                ms=3,
                mfc=line.get_markerfacecolor(),
                color=line.get_color(),
                lw=1.0,
            )
    ins.set_title(f"zoom {w0:g}-{w1:g} rad/s", fontsize=7)
    ins.tick_params(labelsize=6)
    ins.grid(alpha=0.3)
