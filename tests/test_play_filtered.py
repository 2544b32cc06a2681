"""The rig's anti-alias filters in the time domain (``acquisition.filter_foh``, ``rig_samples``) and
the play candidate's gap read through them.

A gear with play rattles; its contact spikes reach the accelerometers through their anti-alias
filters, which shrink the spikes' covariance (the play candidate's rattle statistic) far below what
the raw spikes give. The candidate's simulated records must be read through the same declared
filters, or the fitted gap comes out several times too small."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pyfmu_wrapper.diagnose.acquisition import Chain, filter_foh


@pytest.mark.parametrize("order", [1, 2])
def test_butterworth_step_response_is_the_closed_form(order):
    """Unit step from rest (the first sample 0, then 1: linear in between) against the exact
    step responses of the first- and second-order Butterworth low-passes, shifted by the ramp."""
    fc, dt = 150.0, 1e-5
    w = 2 * math.pi * fc
    t = np.arange(0.0, 0.05, dt)
    u = np.minimum(t / dt, 1.0)  # 0 at t = 0, 1 from t = dt: the ramp of the first-order hold
    y = filter_foh(Chain("x", "butterworth", order, fc), u, dt)

    def step(s: np.ndarray) -> np.ndarray:
        s = np.maximum(s, 0.0)
        if order == 1:
            return 1.0 - np.exp(-w * s)
        wd = w / math.sqrt(2)  # poles -w/sqrt(2) (1 +- i)
        return 1.0 - np.exp(-wd * s) * (np.cos(wd * s) + np.sin(wd * s))

    # response to the ramp u = min(t/dt, 1) = (r(t) - r(t - dt)) / dt, r the response to a unit ramp
    ts = np.linspace(0.0, 1.0, 201)
    exact = np.array([np.trapezoid(step(tk - ts * dt), ts) for tk in t])  # mean of the step over the ramp
    assert np.max(np.abs(y - exact)) < 1e-9


@pytest.mark.parametrize("chain", [Chain("xdd", "bessel", 8, 190.0), Chain("xdd", "butterworth", 12, 900.0)])
def test_sine_gain_and_phase_are_the_declared_response(chain):
    """A slow sine (400 samples per period: the hold's own error ~1e-5) comes out multiplied by the
    chain's G(i w), the response the steady diagnosis divides by; order 12 stays stable."""
    f, dt = 50.0, 5e-5
    t = np.arange(0.0, 1.0, dt)
    y = filter_foh(chain, np.cos(2 * math.pi * f * t), dt)
    keep = t >= 0.5  # 25 whole periods after the filter settled
    Z = 2 * np.mean(y[keep] * np.exp(-2j * math.pi * f * t[keep]))
    assert abs(Z - chain.response(2 * math.pi * f)) < 1e-4


def test_play_gap_is_found_through_declared_accelerometer_filters(tmp_path):
    """Three records of a 0.5 mm play rattling behind third-order 180 Hz Butterworth filters on the
    accelerometers (500 Hz sampling, noise of the field suite), simulated by the benchmark's own
    writer: the candidate's gap is within 15 % of the truth (the raw-spike statistic gave 0.1 mm)."""
    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.diagnose.system.field import write_dataset
    from pyfmu_wrapper.diagnose.system.model import record_views
    from pyfmu_wrapper.diagnose.system.play import PlayFit
    from pyfmu_wrapper.diagnose.system.suite import draw_dataset
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    rng = np.random.default_rng(16)
    eps = 5e-4
    spec = draw_dataset(rng, {"play": eps}, {}, accel_only=False)
    filt = {"filter": {"type": "butterworth", "order": 3, "cutoff_hz": 180.0}}
    spec.update(fs=500.0, acquisition={"xdd": filt, "ydd": filt}, frc=[])
    spec["records"] = spec["records"][:3]
    for r in spec["records"]:
        r["periods"] = 10.4
    write_dataset(tmp_path / "ds", spec, rng)
    ds = load_dataset(tmp_path / "ds", log=lambda *a, **k: None)
    views, flagged = record_views(ds)
    assert len(views) == 3 and not flagged
    base, tmd = BaseParams(**ds.nominal["base"]), TMDParams(**ds.nominal["tmd"])
    ids = list(range(3))
    pf = PlayFit(base, tmd, views).fit(ids, [([j for j in ids if j != i], [i]) for i in ids])
    assert pf.indicated
    assert abs(pf.eps / eps - 1.0) < 0.15, pf.eps
