"""Close the loop (issue 41): ``diagnose --out DIR`` writes ``DIR/corrected/``, the nominal with the
named effects, as scenario files and SSP parameter sets (pyfmu_wrapper/diagnose/corrected.py).

Checked against independent things: the corrected parameters against the effects' definitions
(docs/diagnose.md's table: c -> c + dc, I -> I + dI with m -> m - dI); the .ssv against the SSP 1.0
schema (fmpy's validating reader) and the FMUs' variable tables; the scenario files against
run-scenario's loader; and the loop itself on one small dataset of the steady benchmark generator
(hidden extra damping, three steady records): run-scenario on the corrected files reproduces the
records to chi2 / n <= 1.2 in units of their noise (the nominal misses by orders of magnitude), and
the diagnosis re-run against the corrected nominal names nothing. The 5-dataset measurement is
benchmarks/bench_corrected.py (docs/diagnose-evidence.md).
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from pyfmu_wrapper.diagnose.corrected import chi2_per_point, corrected_params, measured_points, read_curve, ssv_text
from pyfmu_wrapper.models.base_tmd.fmus.variables import BASE_OSCILLATOR, TMD_INERTER
from pyfmu_wrapper.physics.params import InerterModel

NOMINAL = {
    "base": {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0},
    "tmd": {"mass": 9.0, "stiffness": 4000.0, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"},
}
SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"


def test_corrected_parameters_follow_the_effect_definitions():
    base, tmd, notes = corrected_params(
        NOMINAL,
        {
            "viscous.delta_damping": {"value": 10.0},
            "mass_split.delta_inertance": -0.25,
            "force_error.force_gain_error": 0.1,
            "play.delta_inertance_eff": 0.3,
        },
    )
    assert tmd.damping == pytest.approx(25.0)
    assert (tmd.inertance, tmd.mass) == pytest.approx((0.75, 9.25))  # m + I fixed
    assert (base.mass, base.stiffness, base.damping, base.force_amplitude) == (100.0, 4.0e4, 100.0, 200.0)
    assert notes["force_gain"] == pytest.approx(1.1)
    assert "play.delta_inertance_eff" in notes["not_applied"]


def test_a_play_gap_switches_the_inerter_to_the_play_chain_and_friction_replaces():
    _, tmd, _ = corrected_params(
        NOMINAL, {"play.play_gap": 2e-4, "friction.friction_force": 8.0, "friction.friction_slope": 1e4}
    )
    assert tmd.inerter == InerterModel.PLAY and tmd.play_gap == 2e-4
    assert (tmd.friction_force, tmd.friction_slope) == (8.0, 1e4)


def test_ssv_is_valid_ssp_and_names_variables_of_the_fmus(tmp_path):
    from fmpy.ssp.ssd import read_ssv

    from pyfmu_wrapper.physics.params import as_dict

    base, tmd, _ = corrected_params(NOMINAL, {"cubic.cubic_stiffness": 1e5})
    p = tmp_path / "c.ssv"
    p.write_text(ssv_text("c", {"base": as_dict(base), "tmd": as_dict(tmd)}, 'a "quoted" <note> & more'))
    ET.parse(p)  # well-formed XML
    ps = read_ssv(str(p))  # validates against the SSP 1.0 schema (SystemStructureParameterValues.xsd)
    specs = {"base": BASE_OSCILLATOR, "tmd": TMD_INERTER}
    names = set()
    for par in ps.parameters:
        inst, var = par.name.split(".", 1)
        v = specs[inst].by_name(var)  # a variable of that FMU (KeyError / None otherwise)
        assert v is not None and v.causality == "parameter", par.name
        if par.type == "Real":
            assert (par.unit or None) == v.unit, par.name
        names.add(par.name)
    assert {"base.M", "base.K", "base.C", "base.F", "tmd.m", "tmd.k", "tmd.c", "tmd.I", "tmd.k3"} <= names
    vals = {q.name: float(q.value) for q in ps.parameters}
    assert vals["tmd.k3"] == 1e5 and vals["tmd.inerter"] == int(InerterModel.IDEAL)


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """One small dataset (extra TMD damping 8 N s/m, three steady records, no FRC), diagnosed with an
    output folder, the corrected scenario files run by run-scenario."""
    from pyfmu_wrapper.cli.run_scenario import main as run_scenario
    from pyfmu_wrapper.diagnose.outfolder import DIAGNOSE_MARKER, ResultFolder
    from pyfmu_wrapper.diagnose.run import run_diagnosis
    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset

    root = tmp_path_factory.mktemp("corrected")
    ds = root / "ds"
    make_system_dataset(ds, {"viscous": 8.0}, seed=5, n_records=3, frc=False)
    out = root / "out"
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        res = run_diagnosis(ds, tmp)
    curves: dict[str, dict] = {"corrected": {}, "nominal": {}}
    for y in sorted((out / "corrected").glob("*.yaml")):
        rs = root / "rs" / y.stem
        assert run_scenario([str(y), "--out", str(rs), "--quiet", "--workers", "1"]) == 0
        F = float(y.stem[len("corrected_F") : -1])
        curves["corrected"][F] = read_curve(rs / "corrected.csv")  # the first curve: the corrected model
        curves["nominal"][F] = read_curve(rs / "corrected.csv", "nominal")
    return ds, out, res, curves


def test_the_corrected_model_reproduces_the_records_within_their_noise(loop):
    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.diagnose.run import _load_model

    ds, out, res, curves = loop
    assert res["verdict"]["effects"] == ["viscous"]
    assert len(res["corrected"]) == 6  # 3 forces x (yaml, ssv)
    assert json.loads((out / "diagnosis.json").read_text())["corrected"] == res["corrected"]
    ymls = sorted((out / "corrected").glob("*.yaml"))
    pts = measured_points(load_dataset(ds, _load_model(str(ymls[0]))))
    assert len(pts) == 3
    good = chi2_per_point(pts, curves["corrected"])
    bad = chi2_per_point(pts, curves["nominal"])
    assert good["chi2_per_point"] <= 1.2, good
    assert bad["chi2_per_point"] > 100.0, bad  # the gap the correction closes
    text = ymls[0].read_text()
    assert "viscous (tmd link) named" in text
    assert "## The corrected model" in (out / "report.md").read_text()


def test_the_diagnosis_against_the_corrected_nominal_finds_nothing_left(loop):
    from pyfmu_wrapper.diagnose.run import run_diagnosis

    ds, out, _, _ = loop
    y = sorted((out / "corrected").glob("*.yaml"))[0]
    res = run_diagnosis(ds, None, str(y))
    v = res["verdict"]
    assert v["effects"] == [] and not v["structural"] and not v["unexplained"], v["text"]


def test_nothing_named_writes_the_nominal_and_says_so(tmp_path, loop):
    import yaml

    from pyfmu_wrapper.diagnose.corrected import write_corrected
    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.scenario.loader import load_scenario

    ds = load_dataset(loop[0])
    files = write_corrected(ds, {"verdict": {"effects": [], "parameters": {}}}, tmp_path / "corrected")
    y = [f for f in files if f.suffix == ".yaml"][0]
    doc = yaml.safe_load(y.read_text())
    assert "diagnose named no effect, so the corrected model is the nominal" in doc["description"]
    sc = load_scenario(y)  # run-scenario's loader
    assert sc.tmd.damping == NOMINAL["tmd"]["damping"] and sc.base.mass == NOMINAL["base"]["mass"]
    with pytest.raises(FileExistsError):  # never over an existing folder
        write_corrected(ds, {"verdict": {"effects": []}}, tmp_path / "corrected")


def test_a_file_added_to_corrected_blocks_replacing_the_result(loop):
    from pyfmu_wrapper.diagnose.outfolder import DIAGNOSE_MARKER, check_out_folder
    from pyfmu_wrapper.safeio import OutputError

    out = loop[1]
    check_out_folder(out, "diagnose", DIAGNOSE_MARKER)  # an unchanged result: may be replaced
    mine = Path(out) / "corrected" / "mine.yaml"
    mine.write_text("my own edit\n")
    try:
        with pytest.raises(OutputError, match="mine.yaml"):
            check_out_folder(out, "diagnose", DIAGNOSE_MARKER)
    finally:
        mine.unlink()


# --- the noise the FRC points are judged by (issue 41) -------------------------------------------


def _frc_dataset(folder: Path, nominal: dict, x_max, omegas) -> Path:
    import numpy as np
    import yaml

    from pyfmu_wrapper.diagnose.records import write_record

    folder.mkdir(parents=True, exist_ok=True)
    n = len(omegas)
    write_record(folder / "frc.csv", {"omega": omegas, "force_amplitude": np.full(n, 200.0), "x_max": x_max})
    meta = {"level": "system", "nominal": nominal, "records": [{"file": "frc.csv"}]}
    (folder / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return folder


def test_the_fitted_residuals_noise_is_unbiased_where_the_robust_one_inflates_chi2():
    """White noise of std s on 21 points about a model with one fitted parameter (the mean): the
    residual's estimate with its degree of freedom counted (frc.fit_noise) has E[est^2] = s^2 and
    E[s^2 / est^2] = (n - 1) / (n - 3) = 1.11 (the inverse chi-square's mean: what chi2 / n of a right
    model is inflated by); the robust second-difference estimate alone (the former noise) inflates it
    by more than a quarter; the residual's estimate stays below GUARD x the guard (frc._d2_guard) in
    >= 99 % of the draws (so the fitted estimate is used on clean data), and exceeds it with a smooth
    bump of 15 x the noise in the residual (structure is not taken for noise)."""
    import numpy as np

    from pyfmu_wrapper.diagnose.system.frc import GUARD, _d2_guard, _d2_noise, fit_noise

    rng = np.random.default_rng(7)
    s, n, draws = 0.005, 21, 4000
    w = np.linspace(15.0, 25.0, n)
    own, rob, grd = [], [], []
    for _ in range(draws):
        e = rng.normal(0.0, s, n)
        own.append(fit_noise(e - e.mean(), 1))
        rob.append(_d2_noise(e, w))
        grd.append(_d2_guard(e - e.mean(), w))
    own_a, rob_a, grd_a = np.array(own), np.array(rob), np.array(grd)
    assert np.mean(own_a**2) == pytest.approx(s**2, rel=0.03)
    assert np.mean(s**2 / own_a**2) == pytest.approx((n - 1) / (n - 3), rel=0.04)
    assert np.mean(s**2 / rob_a**2) > 1.25
    assert np.mean(own_a <= GUARD * grd_a) >= 0.99
    # a smooth structure (a resonance-like bump of 15 x the noise) is not taken for noise
    bump = 15 * s * np.exp(-(((w - 20.0) / 1.5) ** 2))
    e = rng.normal(0.0, s, n) + bump
    assert fit_noise(e - e.mean(), 1) > GUARD * _d2_guard(e - e.mean(), w)


def test_the_frc_noise_is_the_residual_the_fitted_model_leaves(tmp_path):
    """A linear nominal, x_max the exact response x (1 + 0.5 % noise): after the FRC diagnosis the
    noise of every point is the rms of the relative residual the best candidate leaves, with its one
    parameter counted (computed here from the fit's own prediction), not the robust estimate."""
    import math

    import numpy as np

    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.diagnose.system.frc import FRCDiagnosis
    from pyfmu_wrapper.models.solve import exact_amplitude
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    w = np.linspace(15.0, 25.0, 13)
    x = exact_amplitude(BaseParams(**NOMINAL["base"]), TMDParams(**NOMINAL["tmd"]), w)
    xm = x * (1 + np.random.default_rng(3).normal(0.0, 0.005, w.size))
    f = FRCDiagnosis(load_dataset(_frc_dataset(tmp_path / "ds", NOMINAL, xm, w))).run()
    r = xm / f.fits[0]["pred"] - 1.0
    want = math.sqrt(float(r @ r) / (w.size - 1))
    assert f.noise_rel == pytest.approx(want, rel=1e-6)  # x_max as written (8 digits)
    assert f.sigma == pytest.approx(np.abs(xm) * want, rel=1e-6)
    assert 0.5 * 0.005 < want < 1.5 * 0.005  # 13 points: 20 % scatter about the truth


def test_a_play_nominals_frc_candidates_match_the_solver(tmp_path):
    """A nominal with play: the FRC path computes the play chain once and a candidate's x_max as its
    change with an ideal inerter plus that offset; against the steady-state solver with the play chain
    and the candidate together (independent: the full nonlinear model), within half the FRC's 0.5 %
    noise (measured: 0.21 % at worst, next to resonance)."""
    from dataclasses import replace

    import numpy as np

    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.diagnose.system.frc import FRCDiagnosis
    from pyfmu_wrapper.models.solve import steady_state
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    nom = {"base": NOMINAL["base"], "tmd": {**NOMINAL["tmd"], "inerter": "play", "play_gap": 4e-4}}
    w = np.array([17.0, 19.0, 20.0, 21.0, 23.0])
    f = FRCDiagnosis(load_dataset(_frc_dataset(tmp_path / "ds", nom, np.full(w.size, 0.01), w)))
    b, t = f.changed({"viscous.delta_damping": 6.0})
    approx = f.amplitude(b, t)
    full = np.array([steady_state(replace(b, force_amplitude=200.0), t, float(wi)).amplitude for wi in w])
    assert t.inerter.name == "PLAY" and t.play_gap == 4e-4
    assert np.max(np.abs(approx / full - 1.0)) < 2.5e-3, (approx, full)
    assert BaseParams(**nom["base"]) == f.base and TMDParams(**nom["tmd"]) == f.tmd


def _with_nominal(ds: Path, **tmd) -> None:
    import yaml

    meta = yaml.safe_load((ds / "dataset.yaml").read_text())
    meta["nominal"]["tmd"].update(tmd)
    (ds / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))


def test_a_friction_nominal_leaves_only_noise_on_its_own_records(tmp_path):
    """Records simulated with dry friction (12 N, the generator's hard law) and white noise, against a
    nominal with that friction: the steady path's nominal residual is the noise (whitened chi2 / n of
    each record within 1.5 of its expectation 1), not the truncated stick-slip of the friction law
    evaluated along the records' harmonic series."""
    from pyfmu_wrapper.diagnose.data import load_dataset
    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset
    from pyfmu_wrapper.diagnose.system.model import SystemModel, record_views

    ds = tmp_path / "ds"
    make_system_dataset(ds, {"friction": 12.0}, seed=11, n_records=3, frc=False)
    _with_nominal(ds, friction_force=12.0)
    d = load_dataset(ds)
    views, _ = record_views(d)
    m = SystemModel(d, views)
    assert m.friction_nominal
    for v in views:
        assert float(v.r @ v.r) / v.r.size < 1.5, v.name


@pytest.mark.slow
def test_a_nominal_with_the_records_play_gap_is_not_named_play_again(tmp_path):
    """Records of the play chain (gap 4e-4 m, three records) against the ideal inerter name play; against
    a nominal with the gap so found (the corrected nominal) play is part of the model: nothing is named
    and no gap is left; against a nominal with three times that gap, play is named again with the
    records' gap (a gap that differs is a finding)."""
    from pyfmu_wrapper.diagnose.run import run_diagnosis
    from pyfmu_wrapper.diagnose.system.bench import make_system_dataset

    ds = tmp_path / "ds"
    make_system_dataset(ds, {"play": 4e-4}, seed=12, n_records=3, frc=False)
    first = run_diagnosis(ds)["verdict"]
    assert first["effects"] == ["play"]
    g = first["parameters"]["play.play_gap"]["value"]
    assert 0.5 * 4e-4 < g < 2 * 4e-4
    _with_nominal(ds, inerter="play", play_gap=g)
    v = run_diagnosis(ds)["verdict"]
    assert v["effects"] == [] and not v["structural"] and not v["unexplained"], v["text"]
    _with_nominal(ds, inerter="play", play_gap=3 * g)
    v = run_diagnosis(ds)["verdict"]
    assert v["effects"] == ["play"], v["text"]
    assert v["parameters"]["play.play_gap"]["value"] == pytest.approx(g, rel=0.3)
