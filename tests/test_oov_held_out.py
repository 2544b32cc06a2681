"""The held-out out-of-vocabulary truths of the system suite (``oov.HELD_OUT``: an asymmetric TMD
spring k2 |u| u and a quadratic base drag C2 |xd| xd), held against an energy balance, and the
``make-benchmark --held-out-oov`` draw."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import trapezoid

from pyfmu_wrapper.diagnose.system.bench import nominal
from pyfmu_wrapper.diagnose.system.oov import HELD_OUT, OOV_EFFECTS, oov_model


@pytest.mark.parametrize(
    "oov", [{"asymmetric_spring": 1e5}, {"base_drag": 300.0}, {"asymmetric_spring": 5e4, "base_drag": 100.0}]
)
def test_steady_orbit_balances_the_forcing_work_with_the_dissipation(oov):
    """Over one period of the steady orbit the force's work equals what the dampers dissipate,
    C xd^2 + c (xd - yd)^2 + C2 |xd|^3; the asymmetric spring is conservative (potential k2 |u|^3 / 3)
    and does no net work. The orbit moved: the nonlinear amplitude differs from the linear one."""
    nom = nominal(2, damping=15.0)
    F, w = 200.0, 19.0
    mdl = oov_model(nom, oov, F)
    tau = np.linspace(0.0, 2 * np.pi / w, 20001)
    s, _ = mdl.dense(w, tau)
    work = trapezoid(F * np.cos(w * tau) * s["xd"], tau)
    v = s["xd"] - s["yd"]
    loss = trapezoid(mdl.C * s["xd"] ** 2 + mdl.c * v**2 + mdl.C2 * np.abs(s["xd"]) ** 3, tau)
    assert work > 0 and abs(work - loss) <= 1e-6 * work, (work, loss)
    X, _ = mdl.linear_response(w)
    assert abs(np.max(np.abs(s["x"])) - abs(X)) > 1e-3 * abs(X)


def test_held_out_kinds_are_drawn_only_when_asked(tmp_path):
    from pyfmu_wrapper.cli.diagnose import main_make_benchmark

    assert set(HELD_OUT).isdisjoint(OOV_EFFECTS)
    args = ["-n", "3", "--clean-fraction", "0", "--pair-fraction", "0", "--oov-fraction", "1", "--seed", "3"]
    assert main_make_benchmark([*args, "--held-out-oov", "--out", str(tmp_path / "h")]) == 0
    assert main_make_benchmark([*args, "--out", str(tmp_path / "t")]) == 0
    held = json.loads((tmp_path / "h" / "manifest.json").read_text())
    tuned = json.loads((tmp_path / "t" / "manifest.json").read_text())
    assert held["held_out_oov"] is True and tuned["held_out_oov"] is False
    assert {h for r in held["datasets"] for h in r["hidden"]} == set(HELD_OUT)
    assert {h for r in tuned["datasets"] for h in r["hidden"]} <= set(OOV_EFFECTS)
    # every held-out truth of the draw is visible above the noise
    assert all(r["visibility"]["visible"] for r in held["datasets"])
