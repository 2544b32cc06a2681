"""Both engines against each other on the paper's configurations.

The slow test sweeps 41 frequencies (15..25 rad/s) up with both engines, with continuation as
``run-scenario`` does, and holds the co-simulated amplitude within 0.5 % of the monolithic one at
every point. Its numbers are written to ``benchmarks/results/cosim_agreement.json`` (git-ignored)
and recorded in docs/cosimulation.md.

One exception, stated and measured: where the monolithic engine itself reports the response
irregular (the play model at and next to its antiresonance, 19.75-20.25 rad/s: the base amplitude,
1.6e-5 m in Case 1, is set by a chaotic gear rattle, and the maxima of consecutive 20-period
windows scatter by 4-50 %), there is no amplitude to 0.5 %. Each engine then reports the range of
its window maxima, [A (1 - scatter), A]; the point passes when the two ranges overlap (the engines
cannot be told apart by the response's own variation) or the maxima agree to 0.5 %. The monolithic
engine's own reproducibility there (rtol 1e-8..1e-10, another start) is 1.5-1.9e-5 m in Case 1.

The fast tests hold a few points, among them the ones that were 0.8-1.5 % off before the
interface Jacobian (full model Case 2 at 24 and 25 rad/s, play Case 1 at 19.5 rad/s), and show
that without it the full model of Case 2 is off by more than 0.5 % (the cause: docs/cosimulation.md).

Run the slow one with ``nice python -m pytest tests/test_cosim_agreement.py -m slow``.
"""

from __future__ import annotations

import json
import os
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pyfmu_wrapper.cosim import settings as cs
from pyfmu_wrapper.models.base_tmd import UNIT
from pyfmu_wrapper.models.solve import sweep
from pyfmu_wrapper.physics.params import BaseParams, paper_case
from pyfmu_wrapper.solvers.monolithic import SolverSettings

PAIR = UNIT.cosim()  # the pair's co-simulation, as run-scenario calls it

BASE = BaseParams()
OMEGAS = np.linspace(15.0, 25.0, 41)
C_OPT = {1: 56.38, 2: 31.73, 3: 6.45}
DF_OPT = {1: 45.78, 2: 37.65, 3: 15.44}
FULL = {1: (10.0, 10.0), 2: (10.0, 10.0), 3: (5.0, 5.0)}  # (c, df) of the paper's full model per case


def paper_configurations() -> dict:
    cfg = {}
    for case in (1, 2, 3):
        cfg[f"viscous_case{case}"] = paper_case(case, damping=C_OPT[case])
        cfg[f"friction_case{case}"] = paper_case(case, friction_force=DF_OPT[case])
        cfg[f"play_case{case}"] = paper_case(case, inerter="play", play_gap=1e-4)
        c, df = FULL[case]
        cfg[f"full_case{case}"] = paper_case(case, inerter="play", play_gap=1e-4, damping=c, friction_force=df)
    return cfg


CONFIGS = paper_configurations()
TOL = 5e-3


def _passes(mono, co, rel) -> np.ndarray:
    """Per point: within 0.5 %, or (where either engine reports the response irregular) the ranges of
    window maxima [A (1 - scatter), A] of both engines overlap. Either engine: a rattling response
    flagged irregular by the co-simulation alone (play Case 3 at 25 rad/s: window scatter 0.53 %,
    0.507 % above a monolithic window that settled to 5e-6) is a maximum over irregular motion too."""
    irregular = mono["irregular"].astype(bool).to_numpy() | co["irregular"].astype(bool).to_numpy()
    am, sm = mono["amplitude"].to_numpy(), mono["change"].to_numpy()
    ac, sc = co["amplitude"].to_numpy(), np.where(co["irregular"].astype(bool).to_numpy(), co["change"].to_numpy(), 0.0)
    overlap = (ac * (1.0 - sc) <= am) & (am * (1.0 - sm) <= ac)
    return (np.abs(rel) <= TOL) | (irregular & overlap)


def _relative_differences(tmd, omegas, cosim=None):
    cosim = cs.CosimSettings() if cosim is None else cosim
    mono = sweep(BASE, tmd, omegas, "up", SolverSettings()).table
    co = PAIR.sweep(BASE, tmd, omegas, "up", cosim)
    a, b = mono["amplitude"].to_numpy(), co["amplitude"].to_numpy()
    return b / a - 1.0, mono, co


@pytest.mark.slow
@pytest.mark.timeout(3600)
@pytest.mark.parametrize("name", list(CONFIGS))
def test_cosim_within_half_percent_of_monolithic_41_points(name):
    rel, mono, co = _relative_differences(CONFIGS[name], OMEGAS)
    out = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
    out.mkdir(parents=True, exist_ok=True)
    path = out / "cosim_agreement.json"
    data = json.loads(path.read_text()) if path.exists() else {}
    ok = _passes(mono, co, rel)
    worst = int(np.argmax(np.where(ok, 0.0, np.abs(rel)))) if not ok.all() else int(np.argmax(np.abs(rel)))
    data[name] = dict(
        max_abs_rel=float(np.max(np.abs(rel))),
        at_omega=float(OMEGAS[int(np.argmax(np.abs(rel)))]),
        above_tol=int(np.sum(np.abs(rel) > TOL)),
        failing=int(np.sum(~ok)),
        irregular_mono=[float(w) for w in OMEGAS[mono["irregular"].astype(bool).to_numpy()]],
        mono_not_converged=int((~mono["converged"].astype(bool)).sum()),
        cosim_not_converged=int((~co["converged"].astype(bool)).sum()),
        rel=[float(r) for r in rel],
        pid=os.getpid(),
        amplitude=dict(mono=mono["amplitude"].tolist(), cosim=co["amplitude"].tolist()),
        scatter=dict(mono=mono["change"].tolist(), cosim=co["change"].tolist()),
        irregular_cosim=[float(w) for w in OMEGAS[co["irregular"].astype(bool).to_numpy()]],
    )
    path.write_text(json.dumps(data, indent=1))
    assert ok.all(), f"{name}: {rel[worst]:.3e} at {OMEGAS[worst]} rad/s ({int(np.sum(~ok))} points fail)"


@pytest.mark.timeout(600)
@pytest.mark.parametrize(
    "name,omegas",
    [
        ("viscous_case2", [17.0, 22.0]),
        ("friction_case3", [18.0, 21.0]),
        ("full_case2", [24.0, 25.0]),
        ("play_case1", [19.5]),
    ],
)
def test_cosim_agrees_on_a_few_points(name, omegas):
    """A few points within 0.5 % (their 41-point sweeps: docs/cosimulation.md). The full model of
    Case 2 at 24/25 rad/s and play Case 1 at 19.5 rad/s were 0.8-1.5 % off before the interface
    Jacobian."""
    rel, mono, _ = _relative_differences(CONFIGS[name], omegas)
    assert not mono["irregular"].any()
    assert np.max(np.abs(rel)) <= TOL, rel


@pytest.mark.timeout(600)
def test_without_the_interface_jacobian_the_rattling_full_model_drifts():
    """The cause, shown at the same step (N = 96): with the plain impulse coupling (the TMD takes
    the base's acceleration as a given input within a step, the base's reaction to the gear force
    arrives a step late) the full model of Case 2 at 25 rad/s is more than 0.5 % too large
    (measured +1.5 %); with the interface Jacobian it is within 0.5 % (measured 1e-6)."""
    n96 = replace(cs.CosimSettings(), steps_per_period=96)
    plain, _, _ = _relative_differences(CONFIGS["full_case2"], [25.0], replace(n96, interface_jacobian=False))
    assert plain[0] > TOL, plain
    jac, _, _ = _relative_differences(CONFIGS["full_case2"], [25.0], n96)
    assert abs(jac[0]) <= TOL, jac
