"""Both engines against each other on the paper's configurations (issue 13, item 2).

The slow test sweeps 41 frequencies (15..25 rad/s) up with both engines, with continuation as
``run-scenario`` does, and holds the co-simulated amplitude within 0.5 % of the monolithic one at
every point. Its numbers are written to ``benchmarks/results/cosim_agreement.json`` (git-ignored)
and recorded in docs/cosimulation.md. The fast test holds a few points of two configurations.

Known to fail: the full model of Case 2 at 22.75-25 rad/s (co-simulation +0.5 to +1.5 %), see
"Known limits" in docs/cosimulation.md: the explicit coupling pumps energy into the nearly
undamped gear-mesh mode when the TMD sticks to the base and the chain rattles.

Run the slow one with ``nice python -m pytest tests/test_cosim_agreement.py -m slow``.
"""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from pyfmu_wrapper.cosim import steady as cs
from pyfmu_wrapper.physics.params import BaseParams, paper_case
from pyfmu_wrapper.solvers.monolithic import SolverSettings
from pyfmu_wrapper.solvers.sweep import sweep

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


def _relative_differences(tmd, omegas, cosim=cs.CosimSettings()):
    mono = sweep(BASE, tmd, omegas, "up", SolverSettings()).table
    co = cs.sweep(BASE, tmd, omegas, "up", cosim)
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
    worst = int(np.argmax(np.abs(rel)))
    data[name] = dict(max_abs_rel=float(np.max(np.abs(rel))), at_omega=float(OMEGAS[worst]),
                      above_tol=int(np.sum(np.abs(rel) > TOL)),
                      mono_not_converged=int((~mono["converged"].astype(bool)).sum()),
                      cosim_not_converged=int((~co["converged"].astype(bool)).sum()),
                      rel=[float(r) for r in rel], pid=os.getpid())
    path.write_text(json.dumps(data, indent=1))
    assert np.max(np.abs(rel)) <= TOL, f"{name}: {np.max(np.abs(rel)):.3e} at {OMEGAS[worst]} rad/s"


@pytest.mark.timeout(300)
@pytest.mark.parametrize("name,omegas", [("viscous_case2", [17.0, 22.0]), ("friction_case3", [18.0, 21.0])])
def test_cosim_agrees_on_a_few_points(name, omegas):
    """A few points of two configurations within 0.5 % (their 41-point sweeps: docs/cosimulation.md)."""
    rel, _, _ = _relative_differences(CONFIGS[name], omegas)
    assert np.max(np.abs(rel)) <= TOL, rel
