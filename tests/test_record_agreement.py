"""The records agree on a named cause's parameters, or the verdict says they do not
(``diagnose.system.agreement``): each record fitted alone, a chi-square across records."""

from __future__ import annotations

import numpy as np
import pytest

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.system.agreement import LEVEL, record_agreement
from pyfmu_wrapper.diagnose.system.field import write_dataset
from pyfmu_wrapper.diagnose.system.model import SystemModel, record_views
from pyfmu_wrapper.diagnose.system.suite import draw_dataset


def _model(tmp_path, hidden: dict, oov: dict, seed: int) -> SystemModel:
    """Five steady records at 16-22 rad/s, 200-280 N, of the field suite's writer (its own
    integrator for the out-of-vocabulary truth), no acquisition filter, no FRC."""
    rng = np.random.default_rng(seed)
    spec = draw_dataset(rng, dict(hidden), dict(oov), accel_only=False)
    spec.update(fs=1000.0, acquisition=None, frc=[])
    r0 = spec["records"][0]  # the draw's noise and phase, five frequencies and forces of ours
    spec["records"] = [
        dict(r0, frequency_hz=f, omega=2 * np.pi * f, force=200.0 + 20.0 * k, periods=10.3)
        for k, f in enumerate((2.55, 2.8, 3.05, 3.3, 3.55))
    ]
    write_dataset(tmp_path / "ds", spec, rng)
    ds = load_dataset(tmp_path / "ds", log=lambda *a, **k: None)
    views, flagged = record_views(ds)
    assert not flagged
    return SystemModel(ds, views)


def test_a_true_cubic_spring_agrees_across_amplitudes(tmp_path):
    """A cubic TMD spring, fitted record by record at five amplitudes: one k3 within the errors."""
    a = record_agreement(_model(tmp_path, {"cubic": 2e5}, {}, seed=7), ("cubic",), {})
    assert a is not None and a["agree"], a and a["worst"]
    w = a["params"]["cubic.cubic_stiffness"]
    assert abs(w["weighted_mean"] / 2e5 - 1) < 0.05 and w["p_value"] > LEVEL


@pytest.mark.parametrize("seed", [7, 11])
def test_a_pair_standing_in_for_an_odd_quadratic_spring_disagrees(tmp_path, seed):
    """The truth's TMD spring is k u + k2 |u| u (out of the vocabulary); a linear spring error plus a
    cubic spring fits each record, but with k3 and dk that change with the amplitude: refused."""
    a = record_agreement(_model(tmp_path, {}, {"asymmetric_spring": 8e4}, seed), ("cubic", "tmd_stiffness"), {})
    assert a is not None and not a["agree"]
    assert a["worst"]["p_value"] < LEVEL / 2
