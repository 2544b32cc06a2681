"""diagnose on transient records: the window fits that rule a candidate out before its full fit
(:mod:`pyfmu_wrapper.diagnose.system.transient_window`). Records synthesised by transient_truth's
own integrator (odeint), independent of the project's simulation."""

from __future__ import annotations

import numpy as np
import pytest

# the datasets of test_diagnose_transient (the same truth, chain, noise and record kinds)
from test_diagnose_transient import DECAY, RANDOM, SWEEP_DOWN, SWEEP_UP, make

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.system import transient, transient_window
from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
from pyfmu_wrapper.diagnose.system.transient_effects import apply
from pyfmu_wrapper.diagnose.system.transient_sim import simulate
from pyfmu_wrapper.diagnose.system.transient_window import window_unusable, window_views


def _prepared(path):
    d = TransientDiagnosis(load_dataset(path))
    d.prepare()
    return d


def test_window_simulation_is_the_start_of_the_whole_records_simulation(tmp_path):
    """A window's simulation (its own grid force, chains and caches) equals the first samples of
    the whole record's simulation of the same model (causal dynamics, so the rest of the record
    cannot change them), to 1e-3 of the noise std, but for the last WINDOW_GUARD samples (the
    chains' non-causal corrections), which the window's fit leaves out; its measured samples are
    the record's."""
    make(tmp_path / "ds", {"dc": 10.0}, [SWEEP_UP, RANDOM], seed=1)
    d = _prepared(tmp_path / "ds")
    mdl = apply(d.p_nom, ("viscous",), np.array([10.0]))
    assert not isinstance(mdl, str)
    for v, w in zip(d.views, window_views(d.views)):
        assert w.n_out == int(v.n_out * transient_window.WINDOW_SHARE)
        assert np.array_equal(w.meas, v.meas[: w.n_out], equal_nan=True)
        y_full, y_win = simulate(v, mdl.p), simulate(w, mdl.p)
        assert y_full is not None and y_win is not None
        err = np.abs(y_win - y_full[: w.n_out])[:, v.has] / v.sigma[v.has]
        g = transient_window.WINDOW_GUARD
        assert float(err[w.skip : -g].max()) < 1e-3, float(err[:-g].max())
        assert float(err[-1].max()) > 1e-2  # the guard is needed: the window's end differs
        assert w.fcache is not v.fcache and w.z0 is not v.z0


def test_short_record_window_rules_nothing_out(tmp_path, monkeypatch):
    """A 6 s record's window (1.5 s) holds too few fit samples, and too few periods of the slowest
    mode (about 0.43 s here: 2.3 Hz) at a lower WINDOW_MIN: the window is not used; a 40 s record's
    is."""
    make(tmp_path / "ds", {}, [SWEEP_UP], T=6.0)
    d = _prepared(tmp_path / "ds")
    why = window_unusable(d.views, d.p_nom)
    assert why is not None and "fit samples" in why
    monkeypatch.setattr(transient_window, "WINDOW_MIN", 10)
    why = window_unusable(d.views, d.p_nom)
    assert why is not None and "periods" in why
    make(tmp_path / "long", {}, [SWEEP_UP], T=40.0)
    assert window_unusable(_prepared(tmp_path / "long").views, d.p_nom) is None
    period = transient_window.slowest_period(d.p_nom)
    # the two-mass system's lower natural frequency from the 2x2 eigenproblem (independent of the code)
    M, K, m, k, inert = 100.0, 4.0e4, 9.0, 4.0e3, 1.0
    Mt = np.array([[M + inert, -inert], [-inert, m + inert]])
    Kt = np.array([[K + k, -k], [-k, k]])
    w_low = float(np.sqrt(np.min(np.linalg.eigvals(np.linalg.solve(Mt, Kt)).real)))
    assert period == pytest.approx(2 * np.pi / w_low, rel=0.02)


@pytest.mark.slow
def test_window_rules_out_only_what_cannot_explain_and_keeps_the_verdict(tmp_path, monkeypatch):
    """Extra viscous damping dc = 10 N s/m: the truth's window z lies in the noise band (|z| <= 5),
    it is fitted on everything and named; every candidate ruled out on its window fit is one whose
    full fit (the unpruned run, PRUNE_Z infinite) leaves a held-out z far above EXPLAINS_Z; the
    named effects and parameters equal the unpruned run's."""
    make(tmp_path / "ds", {"dc": 10.0}, [SWEEP_UP, SWEEP_DOWN, RANDOM, DECAY], seed=3, T=60.0)
    pruned = TransientDiagnosis(load_dataset(tmp_path / "ds")).run()
    monkeypatch.setattr(transient, "PRUNE_Z", np.inf)
    full = TransientDiagnosis(load_dataset(tmp_path / "ds")).run()
    assert pruned["window"]["used"]
    rows = {tuple(r["effects"]): r for r in pruned["candidates"]}
    assert abs(rows[("viscous",)]["window_z"]) <= 5.0
    ruled = [e for e, r in rows.items() if "ruled out on a window fit" in (r.get("reason") or "")]
    assert ruled
    z_full = {tuple(r["effects"]): r.get("z") for r in full["candidates"] if r.get("ok")}
    for e in ruled:
        assert z_full[e] > 100 * transient.EXPLAINS_Z, (e, z_full[e])
    assert pruned["verdict"]["effects"] == full["verdict"]["effects"] == ["viscous"]
    a, b = pruned["verdict"]["parameters"], full["verdict"]["parameters"]
    for k in b:
        assert abs(a[k]["value"] - b[k]["value"]) <= 0.1 * b[k]["std"], (k, a[k], b[k])
