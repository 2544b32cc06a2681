"""What the results' plots say matches the data."""

from __future__ import annotations

import numpy as np
import pandas as pd

from pyfmu_wrapper.scenario import plots
from pyfmu_wrapper.scenario.loader import parse_scenario
from pyfmu_wrapper.scenario.runner import FRCData

SCN = """\
schema_version: 2
name: p
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: ideal, stiffness: 4000.0, damping: 10.0}
frequencies: {start: 15.0, stop: 25.0, count: 41}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "1: a"}
      - {label: "2: b", tmd: {damping: 10.001}}
      - {label: "3: c", tmd: {damping: 30.0}}
"""


def _table() -> pd.DataFrame:
    """Three two-peak curves: 2 lies on 1 (0.1 % of the peak), 3 apart; 3 has one point at the
    antiresonance that is irregular and not converged, at zero amplitude."""
    w = np.linspace(15.0, 25.0, 41)
    shape = 0.1 / (1 + ((w - 17.2) / 0.3) ** 2) + 0.08 / (1 + ((w - 23.0) / 0.3) ** 2)
    rows = []
    for label, amp in (("1: a", shape), ("2: b", shape * 1.001), ("3: c", 0.5 * shape + 0.004)):
        for wi, a in zip(w, amp):
            irr = label == "3: c" and wi == 20.0
            rows.append(
                dict(
                    curve=label, direction="up", omega=wi, amplitude=0.0 if irr else a, converged=not irr, irregular=irr
                )
            )
    return pd.DataFrame(rows)


def _plot():
    scn = parse_scenario(SCN)
    fig = plots.frc_plot(FRCData(scn.studies[0], _table(), {}))
    ax = fig.axes[0]
    return fig, ax, [t.get_text() for t in ax.get_legend().get_texts()]


def test_a_point_irregular_and_not_converged_is_marked_both_ways():
    _, ax, labels = _plot()
    assert "not converged" in labels and "not converged (none)" not in labels
    crosses = [ln for ln in ax.get_lines() if ln.get_marker() == "x" and len(ln.get_xdata()) == 1]
    assert crosses and float(crosses[0].get_xdata()[0]) == 20.0


def test_a_mark_at_zero_amplitude_is_not_cut_by_the_axis():
    _, ax, _ = _plot()
    bottom, top = ax.get_ylim()
    assert bottom < 0 and -bottom >= 0.02 * top


def test_a_curve_on_another_says_so_and_the_valley_is_zoomed():
    fig, ax, labels = _plot()
    on = [t for t in labels if t.startswith("2: b")]
    assert on and "on curve 1" in on[0]
    assert not any("on curve" in t for t in labels if t.startswith("3: c"))
    assert len(ax.child_axes) == 1  # the inset of the valley between the peaks
    x0, x1 = ax.child_axes[0].get_xlim()
    assert 17.2 < x0 < 20.0 < x1 < 23.0
