"""make-benchmark's transient truths: a truth that leaves the physical range (a softening spring past
its force maximum, a non-finite state) is drawn again weaker, never written (seed 5252 wrote two
asymmetric-spring datasets whose x held NaN)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.system.transient_suite import ESCAPE_SCALE, write_dataset
from pyfmu_wrapper.diagnose.system.transient_truth import MIN_TANGENT, Truth, TruthEscaped, force_signal

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}


def test_softening_spring_past_its_force_maximum_is_refused():
    """k u + k2 u |u| with k2 < 0 has its force maximum at |u| = k / (2 |k2|): a resonant sweep that
    drives the stroke past the point where the tangent k + 2 k2 |u| is MIN_TANGENT k is refused; the
    same sweep on a weak k2 passes and stays inside it."""
    T = 20.0
    t = np.arange(0.0, T, 1e-3)
    F = force_signal("sweep_lin", np.random.default_rng(0), T, 150.0, f0=1.5, f1=5.0)
    with pytest.raises(TruthEscaped, match="escapes"):
        Truth(BASE, TMD, T, k2=-2e5).simulate(F, t)
    sig = Truth(BASE, TMD, T, k2=-2e3).simulate(F, t)
    u = np.max(np.abs(sig["x"] - sig["y"]))
    assert np.all(np.isfinite(sig["x"])) and 4.0e3 + 2 * (-2e3) * u > MIN_TANGENT * 4.0e3


def test_escaping_truth_is_drawn_weaker_and_the_manifest_says_so(tmp_path):
    """write_dataset with an asymmetric spring that escapes: the records are finite, the truth written
    is k2 x ESCAPE_SCALE^n (n >= 1), stated in 'truth_redrawn', and the recorded stroke keeps the
    written spring's tangent stiffness above MIN_TANGENT k (noise of a few % of the stroke aside)."""
    oov = {"asymmetric_spring": -2e5}
    spec = write_dataset(tmp_path / "ds", np.random.default_rng(3), {}, oov, 20.0)
    n = round(np.log(oov["asymmetric_spring"] / -2e5) / np.log(ESCAPE_SCALE))
    assert n >= 1 and oov["asymmetric_spring"] == pytest.approx(-2e5 * ESCAPE_SCALE**n, rel=1e-12)
    assert "weaker" in spec["truth_redrawn"]
    k = yaml.safe_load((tmp_path / "ds" / "dataset.yaml").read_text())["nominal"]["tmd"]["stiffness"]
    files = sorted((tmp_path / "ds").glob("*.csv"))
    assert len(files) == 3
    for f in files:
        rec = np.genfromtxt(f, delimiter=",", names=True, comments="#")
        for name in rec.dtype.names:
            assert np.all(np.isfinite(rec[name])), (f.name, name)
        if "x" in rec.dtype.names:
            u = np.max(np.abs(rec["x"] - rec["y"]))
            assert k + 2 * oov["asymmetric_spring"] * u > 0.5 * MIN_TANGENT * k
