"""The field-like system benchmark (make-benchmark's system suite) against independent checks, and
score's classification of out-of-vocabulary results."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
import yaml
from scipy import signal

from pyfmu_wrapper.diagnose.system import score as sysscore
from pyfmu_wrapper.diagnose.system.bench import nominal
from pyfmu_wrapper.diagnose.system.field import write_dataset
from pyfmu_wrapper.diagnose.system.oov import OOVModel
from pyfmu_wrapper.diagnose.system.suite import true_parts


def linear_response(nom, omega, F):
    """(X, Y) complex amplitudes written out here from Eq. (1)-(2) with the ideal inerter:
    [[M+I, -I], [-I, m+I]] a + C v + K x = (F, 0)."""
    b, t = nom["base"], nom["tmd"]
    M, K, C = b["mass"], b["stiffness"], b["damping"]
    m, k, c, I = t["mass"], t["stiffness"], t["damping"], t["inertance"]
    w = omega
    A = np.array(
        [
            [K + k - w * w * (M + I) + 1j * w * (C + c), -k + w * w * I - 1j * w * c],
            [-k + w * w * I - 1j * w * c, k - w * w * (m + I) + 1j * w * c],
        ]
    )
    X, Y = np.linalg.solve(A, [F, 0.0])
    return X, Y


def phasor(t, s, w):
    """Least-squares complex amplitude S of s = Re(S e^{i w t}) + const, and its std per part."""
    A = np.column_stack([np.cos(w * t), -np.sin(w * t), np.ones_like(t)])
    coef, res, *_ = np.linalg.lstsq(A, s, rcond=None)
    sd = math.sqrt(res[0] / (t.size - 3)) * math.sqrt(2.0 / t.size)
    return coef[0] + 1j * coef[1], sd


def spec(
    case=2,
    c=15.0,
    fs=1000.0,
    f_hz=3.1,
    F=180.0,
    periods=9.37,
    phase=2.1,
    acq=None,
    hidden=None,
    accel_only=False,
    noise=0.01,
):
    nom = nominal(case, c)
    rec = {
        "frequency_hz": f_hz,
        "omega": 2 * math.pi * f_hz,
        "force": F,
        "periods": periods,
        "phase": phase,
        "noise": {ch: noise for ch in ("force", "x", "y", "xdd", "ydd")},
    }
    return {
        "case": case,
        "nominal": nom,
        "fs": fs,
        "accel_only": accel_only,
        "acquisition": acq,
        "records": [rec],
        "frc": [],
        "truth": true_parts(nom, hidden or {}, {}),
    }


def read(folder):
    meta = yaml.safe_load((folder / "dataset.yaml").read_text())
    return meta, pd.read_csv(folder / meta["records"][0]["file"])


def test_clean_linear_record_is_the_exact_frequency_response(tmp_path):
    sp = spec()
    write_dataset(tmp_path, sp, np.random.default_rng(1))
    meta, df = read(tmp_path)
    r = sp["records"][0]
    w, T = r["omega"], 2 * math.pi / r["omega"]
    t = df["t"].to_numpy()
    # the record: n samples at fs, not a whole number of periods, t = 0 at phase phi of the force
    assert t.size == int(r["periods"] * T * sp["fs"]) and np.allclose(np.diff(t), 1 / sp["fs"])
    assert abs(t.size / sp["fs"] / T - round(t.size / sp["fs"] / T)) > 0.1
    Fp, sdF = phasor(t, df["force"].to_numpy(), w)
    assert abs(abs(Fp) - r["force"]) < 5 * sdF and abs(np.angle(Fp) - r["phase"]) < 5 * sdF / r["force"]
    X, Y = linear_response(sp["nominal"], w, r["force"])
    rot = np.exp(1j * r["phase"])
    for ch, Z in (("x", X), ("y", Y), ("xdd", -w * w * X), ("ydd", -w * w * Y)):
        S, sd = phasor(t, df[ch].to_numpy(), w)
        assert abs(S - Z * rot) < 5 * sd + 1e-9 * abs(Z), ch  # to noise level, amplitude and phase
        assert sd < 0.1 * abs(Z)


@pytest.mark.parametrize("typ,order,frac", [("butterworth", 4, 0.4), ("bessel", 6, 0.25), ("butterworth", 8, 0.3)])
def test_declared_filter_gives_H_at_the_forcing_frequency(tmp_path, typ, order, frac):
    fs = 256.0
    filt = {"type": typ, "order": order, "cutoff_hz": round(frac * fs, 1)}
    acq = {"xdd": {"filter": filt}, "force": {"filter": filt, "delay_s": 8e-4}}
    sp = spec(fs=fs, f_hz=3.4, acq=acq, noise=0.002)
    write_dataset(tmp_path, sp, np.random.default_rng(2))
    meta, df = read(tmp_path)
    assert meta["acquisition"] == acq
    r = sp["records"][0]
    w = r["omega"]
    t = df["t"].to_numpy()
    wc = 2 * math.pi * filt["cutoff_hz"]  # the analog prototype, in transfer-function form
    b, a = (
        signal.butter(order, wc, analog=True)
        if typ == "butterworth"
        else signal.bessel(order, wc, analog=True, norm="mag")
    )
    H = signal.freqs(b, a, [w])[1][0]
    X, _ = linear_response(sp["nominal"], w, r["force"])
    rot = np.exp(1j * r["phase"])
    S, sd = phasor(t, df["xdd"].to_numpy(), w)
    resid = df["xdd"].to_numpy() - np.real(S * np.exp(1j * w * t))
    resid -= resid.mean()
    # the filter starts on the steady state: no transient at the record's start
    assert np.sqrt(np.mean(resid[:10] ** 2)) < 3 * np.sqrt(np.mean(resid**2))
    ratio = S / (-w * w * X * rot)
    assert abs(abs(ratio) - abs(H)) < 5 * sd / abs(w * w * X) + 1e-6
    assert abs(np.angle(ratio) - np.angle(H)) < 5 * sd / abs(w * w * X) + 1e-6
    assert abs(np.angle(H)) > 0.02  # the lag is there to see (> 1 degree)
    Fp, sdF = phasor(t, df["force"].to_numpy(), w)
    ratio = Fp / (r["force"] * rot)
    assert abs(np.angle(ratio) - np.angle(H * np.exp(-1j * w * 8e-4))) < 5 * sdF / r["force"] + 1e-6
    assert abs(abs(ratio) - abs(H)) < 5 * sdF / r["force"] + 1e-6
    S, sd = phasor(t, df["x"].to_numpy(), w)  # an undeclared channel is not filtered
    assert abs(S - X * rot) < 5 * sd + 1e-9


def test_acceleration_only_record_has_no_displacement(tmp_path):
    write_dataset(tmp_path, spec(accel_only=True), np.random.default_rng(3))
    _, df = read(tmp_path)
    assert list(df.columns) == ["t", "force", "xdd", "ydd"]


def test_oov_integrator_matches_the_project_with_the_effect_off():
    from pyfmu_wrapper.models.solve import exact_response
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    nom = nominal(3, 10.0)
    w, F = 19.0, 220.0
    mod = OOVModel(nom["base"], nom["tmd"], F)
    T = 2 * math.pi / w
    tau = np.linspace(0.3, 0.3 + 2 * T, 257)
    d, _ = mod.dense(w, tau)
    Z = exact_response(BaseParams(**{**nom["base"], "force_amplitude": F}), TMDParams(**nom["tmd"]), [w])[0]
    e = np.exp(1j * w * tau)
    for k, i, s in (("x", 0, 1), ("y", 2, 1), ("xdd", 0, -w * w), ("ydd", 2, -w * w)):
        ref = np.real(s * Z[i] * e)
        assert np.max(np.abs(d[k] - ref)) < 1e-7 * np.max(np.abs(ref)), k


def test_oov_integrator_follows_the_project_integrator_from_a_transient_start():
    """Off the orbit (a transient from an arbitrary state): the two integrators agree."""
    from pyfmu_wrapper.models.solve import simulate
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    nom = nominal(2, 15.0)
    w, F = 17.0, 150.0
    mod = OOVModel(nom["base"], nom["tmd"], F)
    z0 = np.array([0.01, -0.2, -0.02, 0.3])
    tau = np.linspace(0.0, 3 * 2 * math.pi / w, 301)
    from scipy.integrate import solve_ivp

    mine = solve_ivp(mod.rhs(w), (0.0, tau[-1]), z0, method="DOP853", rtol=1e-11, atol=1e-13, t_eval=tau).y
    _, zp = simulate(
        BaseParams(**{**nom["base"], "force_amplitude": F}),
        TMDParams(**nom["tmd"]),
        w,
        float(tau[-1]),
        z0=np.r_[z0, 0.0, 0.0],
        sample_times=tau,
        rtol=1e-11,
    )
    for i in range(4):
        assert np.max(np.abs(mine[i] - zp[:, i])) < 1e-6 * np.max(np.abs(zp[:, i])), i


@pytest.mark.parametrize("kw", [{"c2": 15.0}, {"mu": 6.0}, {"K3": 3e5}])
def test_oov_integrator_energy_balance_on_the_orbit(kw):
    """On a periodic orbit the work of the force over a period equals the energy dissipated by
    C, c, c2 |v|^3 and the base friction (the springs and masses return theirs)."""
    nom = nominal(1, 15.0)
    w, F = 21.0, 200.0
    mod = OOVModel(nom["base"], nom["tmd"], F, **kw)
    T = 2 * math.pi / w
    tau = np.linspace(0.0, T, 4001)
    d, zs = mod.dense(w, tau)
    v = d["xd"] - d["yd"]
    p_in = F * np.cos(w * tau) * d["xd"]
    p_out = mod.C * d["xd"] ** 2 + mod.c * v**2 + mod.c2 * np.abs(v) ** 3 + mod.mu * np.tanh(d["xd"] / 1e-3) * d["xd"]
    W_in, W_out = np.trapezoid(p_in, tau), np.trapezoid(p_out, tau)
    assert abs(W_in - W_out) < 1e-4 * W_in
    assert np.max(np.abs(mod.period_map(zs, w) - zs) / mod._scale(w)) < 1e-8  # periodic


def test_score_classifies_oov_results():
    m = {"dataset": "d", "class": "oov", "hidden": ["x_gain"], "truth": {}, "visibility": {"visible": True}}

    def res(effects, unexplained=None, text="x"):
        v = {"effects": effects, "text": text, "parameters": {}}
        if unexplained is not None:
            v["unexplained"] = unexplained
        return {"verdict": v}

    row = sysscore.score_row
    assert (
        row(m, res(["viscous"], True, "a structural gap remains that none of the candidates explains"))["oov_outcome"]
        == "honest"
    )
    assert row(m, res([], True, "unexplained"))["oov_outcome"] == "honest"
    assert row(m, res(["viscous"], False))["oov_outcome"] == "confidently_wrong"
    assert row(m, res(["viscous"]))["oov_outcome"] == "confidently_wrong"  # a missing key is false
    assert row(m, res([], False, "No structural effect"))["oov_outcome"] == "missed"
    inv = dict(m, visibility={"visible": False})
    assert row(inv, res([], False, "No structural effect"))["oov_outcome"] == "right"
    assert row(inv, res(["cubic"], False))["oov_outcome"] == "confidently_wrong"
    assert row(m, None, "bad data")["oov_outcome"] == "error"
    r = row(m, res([], False, "a structural gap remains that none of the candidates explains"))
    assert r["text_flag_disagree"] and r["oov_outcome"] == "missed"
    # in-vocabulary rows: parameter error only for named hidden effects
    s = {"dataset": "s", "class": "single", "hidden": ["base_mass"], "truth": {"base_mass.delta_mass": 4.0}}
    r = row(
        s, {"verdict": {"effects": ["base_mass"], "text": "t", "parameters": {"base_mass.delta_mass": {"value": 4.2}}}}
    )
    assert r["correct"] and abs(r["param_rel_error"]["base_mass.delta_mass"] - 0.05) < 1e-12
    rows = [
        dict(r, seconds=1.0),
        dict(row(m, res(["viscous"], False)), seconds=1.0),
        dict(row(m, res([], True)), seconds=1.0),
    ]
    summ = sysscore.summarise(rows)
    assert summ["singles_top1"] == 1.0 and summ["oov_honest_or_right"] == 0.5
    assert summ["oov_confidently_wrong"] == 0.5 and summ["unexplained_on_invocab_or_clean"] == 0.0


def test_make_benchmark_never_prints_labels(tmp_path, capsys):
    import json

    from pyfmu_wrapper.cli.diagnose import main_make_benchmark
    from pyfmu_wrapper.diagnose.system.oov import OOV_EFFECTS
    from pyfmu_wrapper.diagnose.system.suite import RANGES, TRUTH_KEY

    assert main_make_benchmark(["--out", str(tmp_path), "-n", "4", "--seed", "4"]) == 0
    out = capsys.readouterr().out
    assert not [e for e in list(RANGES) + list(OOV_EFFECTS) if e in out]
    man = json.loads((tmp_path / "manifest.json").read_text())
    rows = man["datasets"]
    assert sorted(r["class"] for r in rows) == ["clean", "oov", "pair", "single"]
    for r in rows:
        meta = yaml.safe_load((tmp_path / r["dataset"] / "dataset.yaml").read_text())
        assert meta.get("acquisition") == r["acquisition"]
        assert set(r["truth"]) == {TRUTH_KEY[e] for e in r["hidden"] if e in TRUTH_KEY}
        assert (r["visibility"]["chi2"] == 0.0) == (r["class"] == "clean")
        assert r["visibility"]["visible"] == (r["visibility"]["chi2"] > man["visible_chi2"])


def test_make_benchmark_refuses_to_overwrite_foreign_files(tmp_path, capsys):
    from pyfmu_wrapper.cli.diagnose import main_make_benchmark

    def status(main, args):  # bad input: exit status 2, whether returned or raised by argparse
        try:
            return main(args)
        except SystemExit as e:
            return e.code

    (tmp_path / "notes.txt").write_text("mine")
    assert status(main_make_benchmark, ["--out", str(tmp_path), "-n", "3"]) == 2
    assert "non-empty folder that is not a result of make-benchmark" in capsys.readouterr().err and sorted(
        p.name for p in tmp_path.iterdir()
    ) == ["notes.txt"]
    assert status(main_make_benchmark, ["--out", str(tmp_path / "b"), "-n", "0"]) == 2
    assert not (tmp_path / "b").exists()


def test_score_system_on_given_results(tmp_path):
    import json

    man = {
        "suite": "system",
        "visible_chi2": 100.0,
        "datasets": [
            {"dataset": "a", "class": "clean", "hidden": [], "truth": {}},
            {
                "dataset": "b",
                "class": "pair",
                "hidden": ["viscous", "base_mass"],
                "truth": {"viscous.delta_damping": 5.0, "base_mass.delta_mass": -4.0},
            },
            {
                "dataset": "c",
                "class": "oov",
                "hidden": ["quadratic_damping"],
                "truth": {},
                "visibility": {"chi2": 1e5, "visible": True},
            },
        ],
    }
    (tmp_path / "manifest.json").write_text(json.dumps(man))
    res = {
        "a": {"verdict": {"effects": [], "text": "No structural effect"}},
        "b": {
            "verdict": {
                "effects": ["base_mass", "viscous"],
                "text": "t",
                "parameters": {"viscous.delta_damping": {"value": 5.5}, "base_mass.delta_mass": {"value": -4.0}},
            }
        },
        "c": {
            "verdict": {
                "effects": ["viscous"],
                "unexplained": True,
                "text": "a structural gap remains that none of the candidates explains; hint: viscous",
            }
        },
    }
    out = sysscore.score_system(tmp_path, results=res)
    s = out["summary"]
    assert s["clean_false_positive_rate"] == 0.0 and s["pairs_both_named"] == 1.0
    assert s["oov_honest_or_right"] == 1.0 and s["oov_confidently_wrong"] == 0.0
    assert s["text_flag_disagreements"] == 0 and s["param_rel_error_median"] == pytest.approx(0.05)
    assert s["per_effect"]["viscous"]["param_rel_error_median"] == pytest.approx(0.1)
    assert sysscore.score_summary(out) == sysscore.table(s)
    assert sysscore.score_line(dict(out["rows"][2])).startswith("c [oov]: hidden ['quadratic_damping'] found")
    tab = sysscore.table(s)
    assert "| pairs: both effects named | 1/1 (100 %) |" in tab
    assert "| quadratic_damping | 1 | 1 | 0 | 0 | 0 | 0 |" in tab


def test_frc_record_carries_the_declared_chain_gain(tmp_path):
    """x_max = |H_x(i w)| |X(w)| (to its noise) and the reported force amplitude = |H_force(i w)| F,
    with |X| written out here; the sweep's direction as declared."""
    fs = 256.0
    filt = {"type": "bessel", "order": 8, "cutoff_hz": 48.0}
    sp = spec(fs=fs, acq={"all": {"filter": filt}})
    om = np.arange(25.0, 14.9, -0.5)
    sp["frc"] = [{"force": 150.0, "direction": "down", "omegas": om.tolist(), "noise": 1e-4}]
    write_dataset(tmp_path, sp, np.random.default_rng(4))
    meta = yaml.safe_load((tmp_path / "dataset.yaml").read_text())
    df = pd.read_csv(tmp_path / meta["records"][-1]["file"])
    assert list(df["direction"].unique()) == ["down"] and np.all(np.diff(df["omega"]) < 0)
    b, a = signal.bessel(8, 2 * math.pi * 48.0, analog=True, norm="mag")
    H = np.abs(signal.freqs(b, a, om)[1])
    X = np.array([abs(linear_response(sp["nominal"], w, 150.0)[0]) for w in om])
    assert np.allclose(df["force_amplitude"], 150.0 * H, rtol=1e-8, atol=0)
    assert np.all(np.abs(df["x_max"] / (H * X) - 1) < 5e-4)
    assert np.max(1 - H) > 1.5e-3  # the gain is there to see: 3x the tolerance above, 15x the 0.01 % noise
