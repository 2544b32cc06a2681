"""Building: generated XML agrees with the variable table; ensure_fmus rebuilds only stale FMUs."""
from __future__ import annotations

import zipfile

import fmpy

from pyfmu_wrapper.fmi import build
from pyfmu_wrapper.fmi.variables import BASE_OSCILLATOR, TMD_INERTER


def test_ensure_fmus_builds_missing_and_stale_only(tmp_path, monkeypatch):
    paths = build.ensure_fmus(out_dir=tmp_path)
    assert set(paths) == {"BaseOscillator", "TMDInerter"}
    mtimes = {n: p.stat().st_mtime_ns for n, p in paths.items()}
    build.ensure_fmus(out_dir=tmp_path)
    assert {n: p.stat().st_mtime_ns for n, p in paths.items()} == mtimes  # up to date: untouched
    monkeypatch.setattr(build, "source_hash", lambda: "0123456789abcdef01234567")
    build.ensure_fmus(out_dir=tmp_path)
    assert all(build.fmu_source_hash(p) == "0123456789abcdef01234567" for p in paths.values())
    with zipfile.ZipFile(paths["TMDInerter"]) as z:
        names = set(z.namelist())
        cfg = z.read("resources/pyfmu.cfg").decode()
    assert {"modelDescription.xml", "binaries/linux64/TMDInerter.so", "resources/pyfmu.cfg",
            "resources/variables.tsv", "resources/model.py"} <= names
    assert "python=" in cfg and "bundle_hash=" in cfg and "path=" not in cfg and "libpython=" not in cfg


def test_xml_matches_variable_table(tmp_path):
    (fmu,) = build.build_fmus(["BaseOscillator"], tmp_path)
    md = fmpy.read_model_description(str(fmu))
    for spec_var in BASE_OSCILLATOR.variables:
        v = next(x for x in md.modelVariables if x.name == spec_var.name)
        assert (v.valueReference, v.causality, v.variability) == (spec_var.vr, spec_var.causality, spec_var.variability)
        assert v.unit == spec_var.unit
        if spec_var.start is not None:
            assert float(v.start) == float(spec_var.start)
    xdd = next(u for u in md.outputs if u.variable.name == "xdd")
    assert [d.name for d in xdd.dependencies] == ["f_link"]
    assert TMD_INERTER.by_name("force").depends_on == ("x", "xd", "xdd")
