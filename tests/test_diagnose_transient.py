"""diagnose on transient records: swept sines, random force, free decays, hammer impulses,
simulated by an integrator independent of the project's (odeint on transient_truth's own
right-hand side) and measured as a rig does (declared anti-alias filters, white ADC noise)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.cli.diagnose import main_diagnose
from pyfmu_wrapper.diagnose.data import DataError, load_dataset
from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.run import run_diagnosis
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
FILT = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 100.0}}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}


def make(path, changes, kinds, fs=256.0, T=40.0, seed=0, accel_only=False, acq=None):
    """A transient dataset: one record per (kind, kwargs); the truth simulated at 8 fs, filtered as
    declared, sampled at fs, 1 % noise (0.5 % on the force)."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    acq = {"xdd": FILT, "ydd": FILT} if acq is None else acq
    recs = []
    for i, (kind, kw) in enumerate(kinds):
        kw = dict(kw)
        t = np.arange(0.0, T, 1.0 / (8 * fs))
        F = force_signal(kind, rng, T, kw.pop("amp", 150.0), **kw)
        z0 = np.array([0.005, 0.0, 0.01, 0.0]) if kind == "decay" else None
        sig = Truth(BASE, TMD, T, **changes).simulate(F, t, z0)
        if kind == "decay":
            sig.pop("force")
        m = measure(sig, t, 8, rng, NOISE, acq)
        if accel_only:
            m.pop("x"), m.pop("y")
        write_record(path / f"r{i}.csv", m)
        recs.append({"file": f"r{i}.csv", "kind": "decay" if kind == "decay" else "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": acq}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


SWEEP_UP = ("sweep_lin", {"f0": 1.5, "f1": 5.0})
SWEEP_DOWN = ("sweep_log", {"f0": 5.0, "f1": 1.5})
RANDOM = ("random", {"f_lo": 1.0, "f_hi": 8.0, "amp": 60.0})
DECAY = ("decay", {})


def test_clean_transient_records_no_structural_effect(tmp_path):
    """The nominal is the truth: its held-out chi-square is within the noise; nothing is named."""
    make(tmp_path / "ds", {}, [SWEEP_UP, RANDOM])
    res = run_diagnosis(tmp_path / "ds", out=tmp_path / "out")
    v = res["verdict"]
    assert v["effects"] == [] and not v["unexplained"] and not v["structural"]
    z = res["transient"]["held_out"]["by_segment"]["z_before"]
    assert abs(z) <= 5.0, z
    # the measured noise: 1 % of the x channel's rms per record sample, averaged over the block
    assert (tmp_path / "out" / "where.png").is_file()
    assert "No structural effect" in (tmp_path / "out" / "report.md").read_text()


def test_viscous_from_acceleration_only_sweeps_and_a_decay(tmp_path, capsys):
    """Extra damping dc = 10 N s/m, acceleration channels only (filtered, declared): named alone,
    dc within 2 %, explained to the noise, records agreeing, held out by record too."""
    make(tmp_path / "ds", {"dc": 10.0}, [SWEEP_UP, SWEEP_DOWN, DECAY], accel_only=True, seed=3)
    assert main_diagnose([str(tmp_path / "ds"), "--out", str(tmp_path / "out")]) == 0
    res = json.loads((tmp_path / "out" / "diagnosis.json").read_text())
    v = res["verdict"]
    assert v["effects"] == ["viscous"], v["text"]
    assert v["elements"] == ["tmd link"]
    assert abs(v["parameters"]["viscous.delta_damping"]["value"] - 10.0) < 0.2
    assert not v["unexplained"]
    h = res["transient"]["held_out"]
    assert h["by_segment"]["z_after"] <= 5.0 and h["by_segment"]["gap_closed"] > 0.99
    assert res["transient"]["agreement"]["agree"]
    assert len(h["by_record"]) == 3 and all(r["gap_closed"] > 0.9 for r in h["by_record"])
    assert "viscous damping" in capsys.readouterr().out
    # the corrected model (no steady record: one scenario file over the structure's band)
    from pyfmu_wrapper.scenario.loader import load_scenario

    (y,) = sorted((tmp_path / "out" / "corrected").glob("*.yaml"))
    c0 = load_dataset(tmp_path / "ds").nominal["tmd"]["damping"]
    assert load_scenario(y).tmd.damping == pytest.approx(c0 + v["parameters"]["viscous.delta_damping"]["value"])
    assert y.with_suffix(".ssv").is_file()


def test_search_past_its_cpu_budget_says_what_it_did_not_try(tmp_path, monkeypatch):
    """Bounded (issue 41): past the CPU budget no further candidate fit is started; the verdict names
    nothing it did not fit, is `unexplained`, and lists what was not tried (here a budget of 0 s: every
    single, the play band test)."""
    from pyfmu_wrapper.diagnose.system import transient

    make(tmp_path / "ds", {"dc": 10.0}, [SWEEP_UP, RANDOM], seed=3)
    monkeypatch.setattr(transient, "CPU_BUDGET", 0.0)
    v = run_diagnosis(tmp_path / "ds")["verdict"]
    assert v["effects"] == [] and v["unexplained"], v["text"]
    assert "the single viscous" in v["not_tried"] and "play on its band" in v["not_tried"]
    assert "CPU budget (0 s)" in v["text"]


def test_a_fit_under_way_stops_at_the_cpu_deadline(tmp_path):
    """Bounded (issue 41): past the CPU deadline a fit stops at its next Jacobian with the point it
    reached, marked cut (here from the start: the default start, 0 N s/m), where the same fit without
    a deadline finds the truth's 10 N s/m; the records' agreement under it is said not tested instead
    of judged on fits that did not converge."""
    import time

    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.diagnose.system.transient_fit import CUT, cpu_deadline, warm_start
    from pyfmu_wrapper.diagnose.system.transient_heldout import HeldOut

    make(tmp_path / "ds", {"dc": 10.0}, [SWEEP_UP, RANDOM], seed=3)
    td = TransientDiagnosis(load_dataset(tmp_path / "ds"))
    td.prepare()
    allm = td._masks(None)
    free = td._fit(("viscous",), allm, None)
    assert not free.cut and abs(free.theta[0] - 10.0) < 0.3
    with cpu_deadline(time.process_time()):
        f = td._fit(("viscous",), allm, None, init=np.array([1.0]))
        assert f.cut and f.reason == CUT and f.theta[0] == pytest.approx(1.0)
        held = HeldOut(td.views, td.p_nom, td.sc, ("viscous",), allm, free, warm_start(free, td.sc), td.noise_parts)
        a = held.agreement()
        assert held.by_record() == []  # no record's prediction from fits that were not made
    assert held.cut and a["agree"] and a["p_value"] is None and "CPU budget" in a["not_tested"]


@pytest.mark.slow
def test_out_of_vocabulary_quadratic_damping_is_unexplained(tmp_path):
    """A quadratic damping law c2 |v| v (no candidate has it): no set explains it to the noise, so
    nothing is named and the verdict says the gap is unexplained (with the closest as a hint)."""
    make(tmp_path / "ds", {"c2": 20.0}, [SWEEP_UP, RANDOM, DECAY], seed=4)
    v = run_diagnosis(tmp_path / "ds")["verdict"]
    assert v["effects"] == [] and v["unexplained"]
    assert v["hint"] is not None and "no candidate explains" in v["text"]


def test_transient_record_declaration_errors(tmp_path):
    t = np.arange(0, 10, 0.01)
    write_record(tmp_path / "r.csv", {"t": t, "force": np.sin(10 * t), "xdd": np.cos(10 * t)})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}}
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump({**doc, "records": [{"file": "r.csv", "kind": "transient", "omega": 10.0}]})
    )
    with pytest.raises(DataError, match=r"r\.csv: a transient record has no drive frequency"):
        load_dataset(tmp_path)
    write_record(tmp_path / "f.csv", {"t": t, "force": np.sin(10 * t)})
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({**doc, "records": [{"file": "f.csv", "kind": "transient"}]}))
    with pytest.raises(DataError, match=r"f\.csv, column 'x': a transient record needs at least one response"):
        load_dataset(tmp_path)


def test_link_level_transient_record_has_no_drive_frequency(tmp_path):
    """At link level a transient record is a link record whose frequency is never estimated."""
    t = np.arange(0, 20, 0.002)
    d = 0.01 * np.sin(2 * np.pi * (0.5 + 0.05 * t) * t)
    write_record(tmp_path / "r.csv", {"t": t, "displacement": d, "force": 4000 * d})
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump(
            {"level": "link", "nominal": {"stiffness": 4e3}, "records": [{"file": "r.csv", "kind": "transient"}]}
        )
    )
    r = load_dataset(tmp_path).records[0]
    assert r.kind == "link" and r.omega is None and r.meta["transient"]


@pytest.mark.slow
def test_mixed_transient_and_steady_records(tmp_path):
    """A dataset with steady-state records (project's solver, system.bench) and transient ones
    (independent truth), both with 10 N s/m of extra damping: the transient verdict names viscous,
    the steady result is kept beside it, and where the steady records name more (measured: viscous
    + a 1.5 % base stiffness from three close steady records) the verdict says so."""
    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset

    ds = tmp_path / "ds"
    make_system_dataset(ds, {"viscous": 10.0}, seed=1, case=1, n_records=3, frc=False)
    steady = yaml.safe_load((ds / "dataset.yaml").read_text())
    make(tmp_path / "tr", {"dc": 10.0}, [SWEEP_UP, DECAY], seed=5)
    tr = yaml.safe_load((tmp_path / "tr" / "dataset.yaml").read_text())
    for r in tr["records"]:
        (ds / r["file"]).write_bytes((tmp_path / "tr" / r["file"]).read_bytes())
    steady["records"] += tr["records"]
    steady["acquisition"] = tr["acquisition"]
    (ds / "dataset.yaml").write_text(yaml.safe_dump(steady))
    res = run_diagnosis(ds)
    v = res["verdict"]
    assert v["effects"] == ["viscous"] and not v["unexplained"], v["text"]
    assert abs(v["parameters"]["viscous.delta_damping"]["value"] - 10.0) < 0.2
    se = res["steady"]["verdict"]["effects"]
    assert "viscous" in se
    assert bool(v["disagreements"]) == (sorted(se) != ["viscous"])
    assert v["sources"]["transient_records"] == ["r0.csv", "r1.csv"] and len(v["sources"]["steady_records"]) == 3


def test_score_reports_transient_and_steady_apart():
    from pyfmu_wrapper.diagnose.system.score import summarise, tables

    rows = []
    for kind, found in (("transient", ["viscous"]), ("transient", []), ("steady", ["viscous"])):
        rows.append(
            {
                "dataset": kind,
                "class": "single",
                "hidden": ["viscous"],
                "found": found,
                "correct": found == ["viscous"],
                "both_named": False,
                "unexplained": False,
                "text_flag_disagree": False,
                "param_rel_error": {},
                "error": None,
                "seconds": 1.0,
                "record_kind": kind,
            }
        )
    s = summarise(rows)
    s["by_record_kind"] = {k: summarise([r for r in rows if r["record_kind"] == k]) for k in ("steady", "transient")}
    assert s["by_record_kind"]["transient"]["singles_top1"] == 0.5
    assert s["by_record_kind"]["steady"]["singles_top1"] == 1.0
    out = tables(s)
    assert "### steady records" in out and "### transient records" in out


@pytest.mark.parametrize(("fs", "used"), [(256.0, False), (2000.0, False), (8000.0, True)])
def test_hammer_force_sampled_too_slowly_is_not_used(tmp_path, fs, used):
    """A 4 ms hammer impulse sampled at 256 Hz without an anti-alias filter on the load cell spans one
    sample: its area is not in the record (the half-sine's spectrum reaches 375 Hz, its first zero,
    far above Nyquist), so the record is set aside with a stated reason. At 2 kHz (8 samples per
    impulse, < 0.1 % of the power above 0.8 x Nyquist) it was used, but its area is known only to
    about +-1 % (the samples' phase against the impulse), which left chi2/n 3.7 in x at the truth
    (test_diagnose_transient_hammer): set aside too. At 8 kHz it is used."""
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis

    make(tmp_path, {}, [SWEEP_UP, ("hammer", {"n_hits": 5, "amp": 500.0})], fs=fs, T=10.0)
    d = TransientDiagnosis(load_dataset(tmp_path))
    assert [v.name for v in d.views] == (["r0.csv", "r1.csv"] if used else ["r0.csv"])
    assert bool(d.skipped) is not used
    if not used:
        assert d.skipped[0].startswith("r1.csv: not used") and (
            "anti-alias" in d.skipped[0] or "too few" in d.skipped[0]
        )


def test_forced_record_at_rest_is_simulated_from_rest_under_a_nonlinear_candidate(tmp_path):
    """Start rule: a random-force record starting at rest under a dry-friction truth. The
    nominal's start-state estimate absorbs what the linear nominal misses (it is far from rest); the
    friction candidate at the true parameters is simulated from rest, which fits its training
    samples better, and its residual is then at the noise (chi2/n < 1.5, from > 10 from the estimate)."""
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.diagnose.system.transient_fit import _rest_or_estimate, residual

    make(tmp_path, {"df": 5.0}, [RANDOM], fs=512.0, T=20.0, acq={})
    d = TransientDiagnosis(load_dataset(tmp_path))
    d.prepare()
    v, m = d.views[0], d._masks(None)[0]
    mdl = apply(d.p_nom, ("friction",), np.array([5.0, 1e5]))  # the truth sticks: a steep slope
    assert not isinstance(mdl, str)

    def chi2n() -> float:
        e = residual(v, mdl, m)
        assert e is not None
        return float(np.mean(e[m][:, v.has] ** 2))

    assert np.abs(v.z0[:4]).max() > 1e-4  # the nominal's estimate: far from rest (m, m/s)
    before = chi2n()
    _rest_or_estimate([v], mdl, [m], [])
    assert np.all(v.z0 == 0.0)
    after = chi2n()
    assert after < 1.5 < before, (before, after)


def test_transient_suite_parts_are_the_whole_run(tmp_path):
    """make_transient_benchmark(part=(k, K)) writes the datasets i with i % K == k, the same ones the
    whole run writes (same draws, same files), and its manifest is complete after the last one."""
    from pyfmu_wrapper.diagnose.system.transient_suite import make_transient_benchmark

    kw = {"n": 3, "seed": 5, "n_clean": 1, "n_pair": 0, "n_oov": 1, "seconds": 2.0}
    whole = make_transient_benchmark(tmp_path / "all", **kw)
    parts = [make_transient_benchmark(tmp_path / f"p{k}", part=(k, 2), **kw) for k in (0, 1)]
    assert [r["dataset"] for r in parts[0]] == ["tr000", "tr002"] and [r["dataset"] for r in parts[1]] == ["tr001"]
    strip = [{k: v for k, v in r.items() if k != "seconds"} for r in whole]
    assert sorted(({k: v for k, v in r.items() if k != "seconds"} for p in parts for r in p), key=str) == sorted(
        strip, key=str
    )
    for name, k in (("tr001", 1), ("tr002", 0)):
        for f in sorted((tmp_path / "all" / name).iterdir()):
            assert f.read_bytes() == (tmp_path / f"p{k}" / name / f.name).read_bytes()
    man = json.loads((tmp_path / "p0" / "manifest.json").read_text())
    assert man["complete"] and [r["dataset"] for r in man["datasets"]] == ["tr000", "tr002"]


def test_long_record_keeps_its_anti_alias_cutoff_after_averaging_on_reading(tmp_path):
    """A 60 s record at 2 kHz (120 000 rows) is averaged in pairs on reading (1 kHz, Nyquist 500 Hz);
    its declared anti-alias filter at 785 Hz acted before the ADC, below the rig's 1 kHz Nyquist: the
    dataset is valid (it was refused: 'cutoff above the Nyquist frequency fs/2 = 500 Hz'); a cut-off
    above the rig's own Nyquist is still refused."""
    t = np.arange(120_000) / 2000.0
    write_record(tmp_path / "r.csv", {"t": t, "force": np.sin(10 * t), "xdd": np.cos(10 * t), "ydd": np.cos(9 * t)})
    for cut, ok in ((785.0, True), (1100.0, False)):
        doc = {
            "level": "system",
            "nominal": {"base": {"mass": 100.0, "stiffness": 4e4, "damping": 100.0, "force_amplitude": 200.0}},
            "records": [{"file": "r.csv", "kind": "transient"}],
            "acquisition": {"xdd": {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": cut}}},
        }
        doc["nominal"]["tmd"] = {"mass": 9.0, "stiffness": 4e3, "damping": 15.0, "inertance": 1.0}
        (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(doc))
        if ok:
            assert load_dataset(tmp_path).records[0].meta["reduced"]["block"] == 2
        else:
            with pytest.raises(DataError, match=r"above the Nyquist frequency fs/2 = 1000 Hz"):
                load_dataset(tmp_path)


@pytest.mark.parametrize(
    ("changes", "effect", "theta", "fs", "T"),
    [
        ({"df": 5.0}, "friction", [5.0, 1e5], 1024.0, 20.0),  # a stick-slip truth: the law near Coulomb's
        ({"k3": 3e5}, "cubic", [3e5], 1024.0, 20.0),
        ({"dc": 10.0}, "viscous", [10.0], 4096.0, 10.0),
    ],
    ids=["friction", "cubic", "viscous"],
)
def test_nonlinear_truth_at_its_true_parameters_is_at_the_noise_behind_an_anti_alias_filter(
    tmp_path, changes, effect, theta, fs, T
):
    """A random-force record at 1024 Hz behind a declared 400 Hz Butterworth on every channel, its
    fit samples 10 record samples wide (~100 Hz): the candidate at the truth's own parameters leaves
    chi2/n in [0.8, 1.2] on every channel. Stick-slip puts content far above the fit rate; the
    filter ran at the fit rate after the block means aliased it (ydd chi2/n 3.6 for friction); it
    now runs on the integration grid before them (exact first-order-hold steps), on a grid of at least
    FILTER_SUB intervals per fit block (its input is linear between grid points: with 4, a smooth
    viscous truth at 4096 Hz, fit blocks of 42 samples, left chi2/n 1.35 in x and 1.31 in xdd)."""
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.diagnose.system.transient_fit import residual

    filt = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 400.0}}
    make(tmp_path, changes, [RANDOM], fs=fs, T=T, acq={"all": filt})
    d = TransientDiagnosis(load_dataset(tmp_path))
    d.prepare()
    v, m = d.views[0], d._masks(None)[0]
    assert v.q >= 8  # the fit rate is far below the record's: the case that aliased
    mdl = apply(d.p_nom, (effect,), np.array(theta))
    assert not isinstance(mdl, str)
    v.z0[:] = 0.0  # the truth starts at rest
    e = residual(v, mdl, m)
    assert e is not None
    chi2n = np.mean(e[m] ** 2, axis=0)
    assert np.all((chi2n > 0.8) & (chi2n < 1.2)), chi2n


@pytest.mark.parametrize("r", [0.0, 0.95])
def test_chi_square_spread_of_correlated_noise_is_the_exact_one(r):
    """The held-out chi-square's std under the noise, sqrt(2 n f): white sensor noise plus a response
    to the force's noise correlated in time (an AR(1) of coefficient r, in two channels fully
    correlated). Exact: tr(S^2) / n = sum_k (a_k^2 + 2 a_k b_k) + (b_1 + b_2)^2 (1 + r^2) / (1 - r^2)
    over 2 channels. The estimate is within 10 % of it (it was 1, the white-noise value: the
    chi-square of a correlated residual spreads 5x wider, and z = 6 was noise)."""
    from pyfmu_wrapper.diagnose.system.transient_sim import chi2_variance_factor

    rng = np.random.default_rng(1)
    e = rng.normal(size=21000)
    y = np.zeros_like(e)
    for t in range(1, e.size):
        y[t] = r * y[t - 1] + e[t]
    y = y[1000:] * math.sqrt(1 - r * r)
    Y = np.column_stack([y, 2 * y])
    white = np.array([0.5, 0.5])
    var = np.array([1.0, 4.0])
    a, b = white**2 / (white**2 + var), var / (white**2 + var)
    exact = (np.sum(a**2 + 2 * a * b) + (b[0] + b[1]) ** 2 * (1 + r * r) / (1 - r * r)) / 2
    assert chi2_variance_factor(white, Y) == pytest.approx(exact, rel=0.1)
    assert chi2_variance_factor(white, None) == 1.0


@pytest.mark.parametrize(
    ("fs", "filt", "used"),
    [(500.0, ("bessel", 3, 170.0), False), (500.0, ("butterworth", 8, 125.0), True)],
    ids=["weak-filter", "steep-filter"],
)
def test_hammer_force_aliased_through_a_declared_filter_is_not_used(tmp_path, fs, filt, used):
    """A declared anti-alias filter does not by itself make a sampled impulse whole: at 500 Hz a
    Bessel of order 3 at 170 Hz (0.34 fs) passes much of the 4 ms impulse's power beyond Nyquist,
    which folds back (field tr036: the impulse's direct feed-through, delayed 0.78 ms on the load
    cell, left xdd chi2/n 23 at the truth and the true single unexplained); a Butterworth of order 8
    at 125 Hz removes it and the record is used. The estimate: the measured power above 0.8 x
    Nyquist through the filter's gain at the mirror frequencies (it was only checked without a
    filter)."""
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis

    typ, order, cut = filt
    acq = {"all": {"filter": {"type": typ, "order": order, "cutoff_hz": cut}}, "force": {"delay_s": 0.00078}}
    make(tmp_path, {}, [SWEEP_UP, ("hammer", {"n_hits": 5, "amp": 500.0})], fs=fs, T=10.0, acq=acq)
    d = TransientDiagnosis(load_dataset(tmp_path))
    assert [v.name for v in d.views] == (["r0.csv", "r1.csv"] if used else ["r0.csv"])
    if not used:
        assert d.skipped[0].startswith("r1.csv: not used") and "declared anti-alias filter" in d.skipped[0]


def test_grid_filter_transfer_is_the_sampled_straight_line_hold():
    """The grid filter's transfer (:func:`hold_response`, from the exact first-order-hold step) equals
    what sampling theory gives for the analog filter driven by the grid samples joined by straight
    lines and sampled on the grid: sum_k G(w_k) sinc^2(w_k h / 2), w_k = w + 2 pi k / h (the hold's
    triangle kernel, its aliases folded back by the sampling). It is not G(w): the difference is
    what :func:`hold_correct` divides out."""
    from pyfmu_wrapper.diagnose.acquisition import Chain
    from pyfmu_wrapper.diagnose.system.transient_sim import hold_response

    c = Chain("xdd", type="butterworth", order=4, cutoff_hz=400.0)
    h = 1.0 / (61.5 * 8)
    w = 2 * math.pi * np.linspace(0.1, 30.0, 40)
    got = hold_response(c, h, w)
    k = np.arange(-4000, 4001)[:, None]
    wk = w[None, :] + 2 * math.pi * k / h
    ref = np.sum(c.response(wk) * np.sinc(wk * h / (2 * math.pi)) ** 2, axis=0)
    assert np.max(np.abs(got - ref) / np.abs(ref)) < 1e-6
    assert np.max(np.abs(got / c.response(w) - 1)) > 1e-3  # the hold's own error, corrected below


def test_smooth_model_on_the_coarse_filter_grid_matches_a_fine_grid(tmp_path, monkeypatch):
    """A viscous model behind a 400 Hz Butterworth on every channel, simulated on 12 grid intervals per
    fit block with the hold corrected: its block means are those of a 64-interval grid
    within 0.01 noise std rms on every channel (0.003; without the hold's correction 0.01-0.06, more
    the fewer the intervals). The linear model's RK4 step as matrices gives the numbers of its
    right-hand side to rounding."""
    import pyfmu_wrapper.diagnose.system.transient_sim as S
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.diagnose.system.transient_effects import apply

    filt = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 400.0}}
    make(tmp_path, {"dc": 10.0}, [SWEEP_UP], fs=1024.0, T=20.0, acq={"all": filt})
    d = TransientDiagnosis(load_dataset(tmp_path))
    v = d.views[0]
    mdl = apply(d.p_nom, ("viscous",), np.array([10.0]))
    assert not isinstance(mdl, str)
    monkeypatch.setattr(S, "FILTER_SUB_SMOOTH", 12)  # coarser than the default 16: the correction's case
    assert S.refinement(v, mdl.p) == 12
    y = S.simulate(v, mdl.p)
    monkeypatch.setattr(S, "LINEAR_STEP", False)  # the right-hand side itself: the same numbers
    y_rhs = S.simulate(v, mdl.p)
    assert y is not None and y_rhs is not None
    assert np.max(np.abs(y - y_rhs) / np.max(np.abs(y_rhs), axis=0)) < 1e-11
    monkeypatch.setattr(S, "FILTER_SUB_SMOOTH", 64)
    ref = S.simulate(v, mdl.p)
    assert y is not None and ref is not None
    sig = np.array([v.raw_noise[c] / math.sqrt(v.q) for c in S.CHANNELS])
    rms = np.sqrt(np.mean(((y - ref)[v.skip :] / sig) ** 2, axis=0))
    assert np.all(rms < 0.01), rms


def test_linear_model_step_is_rk4_of_the_mass_stiffness_damping_matrices():
    """A linear model's RK4 step as matrices (:func:`rk4_affine`): its state block is the degree-4
    Taylor polynomial of exp(h A), A built from the inerter's mass matrix [[M + I, -I], [-I, m + I]]
    and the stiffness and damping matrices (not from the kernels), and the force's midpoint and end
    columns and the accelerations row follow from the same A and the base's unit force. Friction, play and
    cubic stiffness get no matrices (their right-hand side runs)."""
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.diagnose.system.transient_sim import rk4_affine
    from pyfmu_wrapper.physics.params import P_C, P_I, P_K, P_M, BaseParams, P_c, P_k, P_m, TMDParams, pack

    p0 = pack(BaseParams(**BASE), TMDParams(**TMD))
    mdl = apply(p0, ("viscous",), np.array([10.0]))
    assert not isinstance(mdl, str)
    p, h = mdl.p, 2e-3
    M, K, C, m, k, c, I = (p[i] for i in (P_M, P_K, P_C, P_m, P_k, P_c, P_I))
    Mt = np.array([[M + I, -I], [-I, m + I]])
    Mi = np.linalg.inv(Mt)
    A = np.block(
        [
            [np.zeros((2, 2)), np.eye(2)],
            [-Mi @ np.array([[K + k, -k], [-k, k]]), -Mi @ np.array([[C + c, -c], [-c, c]])],
        ]
    )
    b = np.concatenate([[0.0, 0.0], Mi @ [1.0, 0.0]])  # unit force on the base
    ha = h * A
    taylor = np.eye(4) + ha + ha @ ha / 2 + ha @ ha @ ha / 6 + ha @ ha @ ha @ ha / 24
    lin = rk4_affine(p, h)
    idx = [0, 2, 1, 3]  # the kernels' states x, xd, y, yd in the order x, y, xd, yd of A
    assert np.allclose(lin[np.ix_(idx, idx)], taylor, rtol=1e-10, atol=1e-12)
    # RK4's force weights: k1 at the step's start, k2 and k3 at its midpoint, k4 at its end
    start = h * (np.eye(4) / 6 + ha / 6 + ha @ ha / 12 + ha @ ha @ ha / 24) @ b
    mid = h * (2 / 3 * np.eye(4) + ha / 3 + ha @ ha / 12) @ b
    end = h * (np.eye(4) / 6) @ b
    for col, want in ((6, start), (7, mid), (8, end)):
        assert np.allclose(lin[idx, col], want, rtol=1e-10, atol=1e-14)
    acc = np.concatenate([A[[2, 3]], b[[2, 3]][:, None]], axis=1)
    assert np.allclose(lin[6:, [*idx, 9]], acc, rtol=1e-12)
    for eff, th in (("friction", [5.0, 1000.0]), ("cubic", [3e5]), ("play", [1e-4])):
        m2 = apply(p0, (eff,), np.array(th))
        assert not isinstance(m2, str)
        assert rk4_affine(m2.p, h).shape[0] == 0


def test_a_candidate_needing_an_unbounded_grid_is_not_simulated(tmp_path):
    """A fitted TMD mass near 0 (1e-9 kg, no inertance) makes its mode's rate sqrt(k / m) ~ 2e6 1/s, and the RK4
    grid with it: the simulation would need ~1e7 grid points, gigabytes of grid force per record and
    thread. Beyond MAX_GRID points the candidate is not simulated (None, as for a blow-up), without
    allocating the grid; the nominal still simulates."""
    import tracemalloc

    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.diagnose.system.transient_sim import MAX_GRID, refinement, simulate
    from pyfmu_wrapper.physics.params import P_I, P_m

    make(tmp_path, {}, [RANDOM], fs=512.0, T=20.0, acq={})
    d = TransientDiagnosis(load_dataset(tmp_path))
    d.prepare()
    v = d.views[0]
    assert simulate(v, d.p_nom) is not None
    p = d.p_nom.copy()
    p[P_m], p[P_I] = 1e-9, 0.0
    assert refinement(v, p) * v.n_out > MAX_GRID
    tracemalloc.start()
    try:
        assert simulate(v, p) is None
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 20e6, peak
