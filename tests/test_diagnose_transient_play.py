"""Play in the inerter gear named from transient records on the band a model of play predicts
(:mod:`pyfmu_wrapper.diagnose.system.transient_play`, issue 41). The truths come from the suite's own
integrator (``transient_truth``: odeint, the gear's contact at the paper's 2e7 N/m), not from the
simulator the fits use."""

from __future__ import annotations

import numpy as np
import pytest
from test_diagnose_transient import RANDOM, SWEEP_UP, make

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.system import transient_play as TP
from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
from pyfmu_wrapper.diagnose.system.transient_effects import apply
from pyfmu_wrapper.diagnose.system.transient_sim import simulate, spread


def _td(path):
    td = TransientDiagnosis(load_dataset(path))
    td.prepare()
    return td


def test_spread_of_a_linear_model_is_its_response_to_the_force_noise(tmp_path):
    """Without play the contact's factors change nothing and the spread is the model's response to an
    independent realisation of the load cell's noise: by linearity, the simulation of that noise alone
    from rest (to rounding)."""
    td = _td(make(tmp_path / "ds", {}, [RANDOM], T=10.0))
    v = td.views[0]
    mdl = apply(td.p_nom, (), np.zeros(0))
    assert not isinstance(mdl, str)
    (d,) = spread(v, mdl.p, 1.0, ((0.5, 0.3),), seed=3)
    g, cache, z0 = v.force, v.fcache, v.z0.copy()
    v.force = np.random.default_rng(3).normal(0.0, v.raw_noise["force"], g.size)
    v.fcache, v.z0 = {}, np.zeros(6)
    try:
        n = simulate(v, mdl.p)
    finally:
        v.force, v.fcache, v.z0 = g, cache, z0
    assert n is not None
    # the direct term of the force in the accelerations is the measured force itself (not perturbed)
    np.testing.assert_allclose(d[:, :2] * v.sigma[:2], n[:, :2], rtol=0, atol=1e-9 * np.max(np.abs(n[:, :2])))
    assert np.std(d[:, 0]) > 0


def test_clean_records_have_the_band_at_the_noise_and_play_is_not_named(tmp_path):
    """The nominal is the truth: its band chi-square (the sensor's white share plus the spread, the
    response to the force's noise) is within 5 std of its dof, and the play test stops there."""
    td = _td(make(tmp_path / "ds", {}, [SWEEP_UP, RANDOM], T=30.0))
    mdl = apply(td.p_nom, (), np.zeros(0))
    assert not isinstance(mdl, str)
    s = TP.band_chi2(td, mdl)
    assert s is not None
    chi2, dof = s.chi2, s.dof
    assert abs(chi2 - dof) < 5 * np.sqrt(2 * dof), (chi2, dof)
    # above the band too, under its own noise: no rattle is left (z well below RATTLE_Z)
    assert s.hi_dof > 0 and abs(s.hi_excess) < 5, (s.hi_chi2, s.hi_dof)
    r = TP.play_test(td, {})
    assert not r["named"]


def test_a_model_without_play_leaves_the_rattle_above_the_band(tmp_path):
    """A 0.3 mm gap (the truth's own integrator, contact 2e7 N/m, ci 5 N s/m, a random force): above the
    band, under each model's own noise, the nominal (no play) leaves the impacts' content far beyond
    RATTLE_Z; play at the true gap makes as much in its own spread (its excess there below PLAY_SHARE of
    the nominal's): what separates play from a candidate that explains the band alone."""
    eps = 3.0e-4
    td = _td(make(tmp_path / "ds", {"eps": eps, "ci": 5.0}, [RANDOM], T=20.0))
    nom = TP._score(td, (), np.zeros(0))
    ps = TP._score(td, ("play",), np.array([eps]))
    assert nom is not None and ps is not None
    assert nom.hi_excess > TP.RATTLE_Z, nom.hi_excess
    assert ps.hi_excess <= TP.PLAY_SHARE * nom.hi_excess, (ps.hi_excess, nom.hi_excess)


def test_a_linear_change_is_not_named_play(tmp_path):
    """A TMD stiffness 6 % low (a linear effect, no gap): the band names no play -- the stiffness refitted
    on the same band predicts it better than any gap."""
    td = _td(make(tmp_path / "ds", {"dk": -240.0}, [RANDOM], T=20.0))
    r = TP.play_test(td, {"tmd_stiffness": np.array([-240.0])})
    assert not r["named"], r["why"]
    assert r["others"]["tmd_stiffness"]["chi2"] < r["play"]["chi2"]


@pytest.mark.slow
@pytest.mark.parametrize("eps", [2.0e-4, 6.0e-4])
def test_play_truth_is_named_play_with_its_gap_or_unexplained(tmp_path, eps):
    """A gear with play simulated by the truth's own integrator (contact 2e7 N/m, ci 5 N s/m): every
    candidate leaves the records unexplained sample by sample (the rattle). What the diagnosis promises
    (issue 41, play named on 5 of 9 dev datasets, not yet on all): no effect but play is named, and
    when play is named its gap is within 35 % of the truth (the band test's contact is the truth's 2e7
    N/m; the likelihood is rough in the gap: seed 9494's ten singles came out -29 % to +8 %). Where play is not named
    the verdict is `unexplained`."""
    from pyfmu_wrapper.diagnose.run import run_diagnosis

    make(tmp_path / "ds", {"eps": eps, "ci": 5.0}, [SWEEP_UP, RANDOM], T=30.0)
    res = run_diagnosis(tmp_path / "ds", out=tmp_path / "out")
    v = res["verdict"]
    assert v["effects"] in ([], ["play"]), v["text"]
    if v["effects"]:
        gap = v["parameters"]["play.play_gap"]["value"]
        assert abs(gap - eps) < 0.35 * eps, gap
    else:
        assert v["unexplained"], v["text"]


def test_floor_is_the_flat_excess_the_spread_does_not_make():
    """Above the band the residual holds white noise of variance w + a per channel (a: the flat content a
    sampling without an anti-alias filter folds of the impacts) and a few strong harmonics, the spread b:
    the floor is a - b, at least 0, to the median's statistical error (std = mean / sqrt(bins) of an
    exponential's sample median)."""
    from types import SimpleNamespace

    rng = np.random.default_rng(5)
    n, fs, f_top = 3840, 128.0, 10.0
    w = np.array([0.9, 0.9, 0.9, 0.9])
    a = np.array([0.0, 3.0, 50.0, 400.0])
    b = np.array([0.0, 1.0, 10.0, 500.0])
    u = rng.normal(size=(n, 4)) * np.sqrt(w + a)
    t = np.arange(n) / fs
    u[:, 2] += 30.0 * np.sin(2 * np.pi * 13.0 * t) + 30.0 * np.sin(2 * np.pi * 17.0 * t)  # harmonics above the band
    F = np.fft.rfft(u - u.mean(axis=0), axis=0)
    fr = np.fft.rfftfreq(n, 1.0 / fs)
    sp = np.broadcast_to(b, (fr.size, 4)).copy()
    got = TP.floor(F, sp, w, SimpleNamespace(fs=fs), f_top, n)
    bins = int(np.sum((fr > f_top) & (fr <= TP.FLOOR_TOP * fs / 2))) // TP.FLOOR_SPLIT
    want = np.maximum(a - b, 0.0)
    std = (w + a) / np.sqrt(bins)
    assert np.all(got >= 0.0)
    assert np.all(np.abs(got - want) < 4 * std + 1e-12), (got, want, std)


@pytest.mark.slow
def test_play_without_an_anti_alias_filter_is_named_with_its_gap(tmp_path):
    """A 0.3 mm play sampled at 256 Hz with no anti-alias filter (the truth's own integrator, contact 2e7
    N/m, ci 5 N s/m, point samples): the impacts fold into the accelerations' band, which the floor
    (:func:`floor`) carries as noise; play is named on its band and its gap is within 35 % of the
    truth's, as the full diagnosis's (the likelihood is rough in the gap: -26 % here; seed 9494's
    tr013, the same sampling, gave a gap of 1.6 mm on a 0.13 mm truth, not named, without the floor)."""
    eps = 3.0e-4
    td = _td(make(tmp_path / "ds", {"eps": eps, "ci": 5.0}, [SWEEP_UP, RANDOM], T=30.0, acq={}))
    r = TP.play_test(td, {})
    assert r["named"], r["why"]
    assert abs(r["play"]["gap"] / eps - 1.0) < 0.35, r["play"]["gap"]
    assert any(np.max(f) > 10.0 for f in r["play"]["floor"]), r["play"]["floor"]
