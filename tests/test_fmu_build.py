"""Building: generated XML agrees with the variable table; ensure_fmus rebuilds only stale FMUs."""

from __future__ import annotations

import zipfile

import fmpy

from pyfmu_wrapper.fmubuild import build
from pyfmu_wrapper.models.base_tmd.fmus.variables import BASE_OSCILLATOR, TMD_INERTER
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick


def test_ensure_fmus_builds_missing_and_stale_only(tmp_path, monkeypatch):
    pair = pick(PROJECT_FMUS)
    paths = build.ensure_fmus(pair, out_dir=tmp_path)
    assert set(paths) == {"BaseOscillator", "TMDInerter"}
    mtimes = {n: p.stat().st_mtime_ns for n, p in paths.items()}
    build.ensure_fmus(pair, out_dir=tmp_path)
    assert {n: p.stat().st_mtime_ns for n, p in paths.items()} == mtimes  # up to date: untouched
    # the FMUs of a model carry one bundle whichever FMUs are built with them: never stale by company
    build.ensure_fmus(pick(("TMDInerter", "ShearFrame", "Trivial")), out_dir=tmp_path)
    assert paths["TMDInerter"].stat().st_mtime_ns == mtimes["TMDInerter"]
    monkeypatch.setattr(build, "source_hash", lambda fmus: "0123456789abcdef01234567")
    build.ensure_fmus(pair, out_dir=tmp_path)
    assert all(build.fmu_source_hash(p) == "0123456789abcdef01234567" for p in paths.values())
    with zipfile.ZipFile(paths["TMDInerter"]) as z:
        names = set(z.namelist())
        cfg = z.read("resources/pyfmu.cfg").decode()
    assert {
        "modelDescription.xml",
        "binaries/linux64/TMDInerter.so",
        "resources/pyfmu.cfg",
        "resources/variables.tsv",
        "resources/model.py",
    } <= names
    assert "python=" in cfg and "bundle_hash=" in cfg and "path=" not in cfg and "libpython=" not in cfg


def test_xml_matches_variable_table(tmp_path):
    (fmu,) = build.build_fmus(pick("BaseOscillator"), tmp_path)
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


# ---- bad input: a clear message, exit status 2, no traceback, nothing deleted or written --------


def _user_files(root):
    return {p: p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def _build_cli(*args, cwd):
    import subprocess
    import sys

    return subprocess.run(
        [sys.executable, "-m", "pyfmu_wrapper.cli.build_fmus", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
    )


def test_build_fmus_bad_input_is_refused_with_exit_2_and_nothing_lost(tmp_path):
    import pytest

    (tmp_path / "notes.txt").write_text("my notes\n")
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "BaseOscillator.fmu").write_text("not an FMU: a file of the user\n")
    other = tmp_path / "other"
    (other / "TMDInerter.fmu").mkdir(parents=True)
    (other / "TMDInerter.fmu" / "keep.txt").write_text("keep\n")
    before = _user_files(tmp_path)
    cases = [  # (arguments, what the message must say)
        (["--out", str(tmp_path / "notes.txt")], "is a file, not a folder"),
        (["--out", str(mine)], "BaseOscillator.fmu exists and was not written by build-fmus"),
        (["--force", "--out", str(mine)], "BaseOscillator.fmu exists and was not written by build-fmus"),
        (["TMDInerter", "--out", str(other)], "TMDInerter.fmu exists and was not written by build-fmus"),
        (["--out", str(tmp_path / "notes.txt" / "sub")], "cannot write into --out"),
        (["--out", "/sys/pyfmu-build-test"], "cannot write into --out"),
        (["NoSuchModel", "--out", str(tmp_path / "new")], "unknown FMU(s) ['NoSuchModel']"),
        (["Trivial", "--out", str(tmp_path / "new")], "Trivial has no native variant"),  # native: the default
        (["--native", "--python", "--out", str(tmp_path / "new")], "--native excludes --python"),
        (["--native", "--standalone", "--out", str(tmp_path / "new")], "--native excludes --standalone"),
        (["--bogus"], "unrecognized arguments: --bogus"),
        (["--out"], "expected one argument"),
    ]
    for args, msg in cases:
        r = _build_cli(*args, cwd=tmp_path)
        assert r.returncode == 2, (args, r.returncode, r.stderr)
        assert msg in r.stderr, (args, r.stderr)
        assert "Traceback" not in r.stderr, (args, r.stderr)
        assert _user_files(tmp_path) == before, args  # nothing deleted, changed or added
    assert not (tmp_path / "new").exists()
    # its own FMUs it replaces (a rebuild), and only those
    r = _build_cli("Trivial", "--python", "--force", "--out", str(tmp_path / "new"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = _build_cli("Trivial", "--python", "--force", "--out", str(tmp_path / "new"), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in (tmp_path / "new").iterdir()) == ["Trivial.fmu"]
    with pytest.raises(build.OutputError):
        build.build_fmus(pick("BaseOscillator"), mine)
    assert _user_files(tmp_path / "mine") == {p: b for p, b in before.items() if p.parent == mine}
