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
