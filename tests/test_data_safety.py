"""Nothing lost while a tool runs, and bounded input.

Each test is a case that lost data, crashed or ran out of memory on the code before this issue:
files added to a results folder during a run (a real concurrent writer), an edited result file, a
user's files in reproduce's --out, a result of another scenario file with the same name, an edited
checkpoint, `--out /`, `--cache` at a file, an unwritable --out, and inputs that exhaust memory.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from _scenario_support import LINEAR, MONO, snapshot, write_scenario
from _scenario_support import SLOW as SLOW4

from pyfmu_wrapper.cli.reproduce import main as reproduce_main
from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.codeversion import numbers_hash

#: two friction curves (integrated, not closed form) of 41 points: a run long enough for a writer to act
SLOW = "\n".join(SLOW4.replace("count: 81", "count: 41").splitlines()[:-2]) + "\n"


def _cli(args: list[str], cwd: Path, **kw) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "pyfmu_wrapper.cli.run_scenario", *args],
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        **kw,
    )


def test_files_added_to_the_results_folder_during_a_run_are_kept(tmp_path):
    """A real concurrent writer: while run-scenario computes, the user adds a file and a folder with a
    file to the results folder. They survive; the new result goes beside the folder, said so, exit 2."""
    scn = write_scenario(tmp_path, SLOW)
    out = tmp_path / "out"
    first = _cli([str(scn), "--out", str(out), *MONO], tmp_path)
    assert first.wait(timeout=600) == 0, first.stderr.read()
    run = _cli([str(scn), "--out", str(out), "--no-resume", *MONO], tmp_path)
    deadline = time.monotonic() + 300
    while not list(tmp_path.glob(".out.partial-*")) and time.monotonic() < deadline:  # computing has begun
        time.sleep(0.05)
    assert run.poll() is None, "the run ended before the writer could act: make SLOW slower"
    (out / "notes.txt").write_text("notes\n")
    (out / "mydata").mkdir()
    (out / "mydata" / "data.txt").write_text("important\n")
    _, err = run.communicate(timeout=600)
    assert run.returncode == 2, err
    assert (out / "notes.txt").read_text() == "notes\n"
    assert (out / "mydata" / "data.txt").read_text() == "important\n"
    beside = sorted(tmp_path.glob("out.new-*"))
    assert len(beside) == 1 and str(beside[0]) in err and "notes.txt" in err
    new = pd.read_csv(beside[0] / "frc.csv")
    old = pd.read_csv(out / "frc.csv")
    assert len(new) == len(old) == 2 * 41  # both complete; the old one exactly as it was
    assert not list(tmp_path.glob(".out.*")), "a partial or old folder was left behind"


def test_an_edited_result_file_is_never_overwritten(tmp_path, capsys):
    scn = write_scenario(tmp_path)
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out), *MONO]) == 0
    with open(out / "frc.csv", "a") as fh:
        fh.write("my own line\n")
    before = snapshot(tmp_path)
    capsys.readouterr()
    assert main([str(scn), "--out", str(out), *MONO]) == 2
    assert "frc.csv (changed since run-scenario wrote it)" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_a_result_of_another_scenario_file_with_the_same_name_is_not_replaced(tmp_path, capsys, no_computing):
    a = tmp_path / "a"
    b = tmp_path / "b"
    a.mkdir()
    b.mkdir()
    out = tmp_path / "results" / "tiny"
    out.mkdir(parents=True)
    (out / "frc.csv").write_text("x\n")
    from pyfmu_wrapper.safeio.tree import inventory, write_marker

    write_marker(
        out,
        ".run-scenario.json",
        "run-scenario",
        kind="result",
        scenario_file=str(write_scenario(a)),
        **inventory(out, ".run-scenario.json"),
    )
    other = write_scenario(b)
    before = snapshot(tmp_path)
    assert main([str(other), "--out", str(out), *MONO]) == 2
    err = capsys.readouterr().err
    assert "another scenario file" in err and str(a / "scn.yaml") in err
    assert snapshot(tmp_path) == before


def test_reproduce_never_overwrites_a_users_files(tmp_path, capsys, monkeypatch):
    import pyfmu_wrapper.paper.reproduce as rp  # the CLI imports run_all from here when it runs

    monkeypatch.setattr(rp, "run_all", lambda *a, **k: (_ for _ in ()).throw(AssertionError("computed")))
    for name in ("reproduction.md", "reproduction.json", "figures/fig6.png"):
        out = tmp_path / name.replace("/", "_")
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        (out / name).write_text("mine\n")
        assert reproduce_main(["--quick", "--out", str(out), "--results", str(tmp_path / "r")]) == 2
        assert name in capsys.readouterr().err
        assert (out / name).read_text() == "mine\n"


def test_an_edited_checkpoint_is_computed_again_not_read_back(tmp_path, capsys):
    scn = write_scenario(tmp_path, SLOW.replace("count: 41", "count: 5"))
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out), *MONO]) == 0
    truth = pd.read_csv(out / "frc.csv")
    cks = sorted((tmp_path / "out.checkpoints" / "frc").glob("*.csv"))
    assert len(cks) == 2
    for ck in cks:
        t = pd.read_csv(ck)
        t["amplitude"] *= 2
        t.to_csv(ck, index=False, float_format="%.17g")
    (out / ".run-scenario.json").unlink()  # replace the result: move it away first
    shutil.rmtree(out)
    capsys.readouterr()
    assert main([str(scn), "--out", str(out), *MONO]) == 0
    text = capsys.readouterr().out
    assert text.count("checkpoint not used, computed again") == 2
    again = pd.read_csv(out / "frc.csv")
    assert (again["amplitude"] - truth["amplitude"]).abs().max() == 0.0


def test_the_checkpoint_key_covers_the_c_sources(tmp_path):
    import pyfmu_wrapper

    root = Path(pyfmu_wrapper.__file__).parent
    copy = tmp_path / "src" / "pyfmu_wrapper"
    shutil.copytree(root, copy, ignore=shutil.ignore_patterns("__pycache__"))
    (tmp_path / "src" / "fmu" / "src").mkdir(parents=True)
    stub = tmp_path / "src" / "fmu" / "src" / "fmi_api.c"
    stub.write_text("int a;\n")
    h0 = numbers_hash(copy)
    stub.write_text("int b;\n")
    h1 = numbers_hash.__wrapped__(copy)
    (copy / "master" / "cloop.c").write_text((copy / "master" / "cloop.c").read_text() + "\n/* */\n")
    h2 = numbers_hash.__wrapped__(copy)
    assert len({h0, h1, h2}) == 3


@pytest.mark.parametrize("out", ["/", "//", "/tmp/.."])
def test_out_at_the_root_is_refused_without_a_traceback(tmp_path, capsys, out, no_computing):
    assert main([str(write_scenario(tmp_path)), "--out", out, *MONO]) == 2
    err = capsys.readouterr().err
    assert "root folder" in err and "Traceback" not in err


def test_cache_at_a_file_is_refused_before_computing(tmp_path, capsys, no_computing):
    f = tmp_path / "cachefile"
    f.write_text("x")
    assert main([str(write_scenario(tmp_path)), "--out", str(tmp_path / "o"), "--cache", str(f), *MONO]) == 2
    assert "--cache" in capsys.readouterr().err and f.read_text() == "x"


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which("chattr") is None, reason="needs root and chattr")
def test_an_immutable_output_folder_is_refused_before_computing(tmp_path, capsys, no_computing):
    out = tmp_path / "out"
    out.mkdir()
    if subprocess.run(["chattr", "+i", str(out)], capture_output=True).returncode != 0:
        pytest.skip("the file system does not support chattr +i")
    try:
        assert main([str(write_scenario(tmp_path)), "--out", str(out), *MONO]) == 2
        assert "cannot write into" in capsys.readouterr().err
    finally:
        subprocess.run(["chattr", "-i", str(out)])


_PEAK = (
    "import resource, subprocess, sys; r = subprocess.run(sys.argv[2:]); "
    "open(sys.argv[1], 'w').write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)); sys.exit(r.returncode)"
)


def _peak_of(cmd: list[str], cwd: Path, env: dict[str, str] | None = None) -> tuple[int, str, float]:
    """Exit status, stderr and peak memory (MB) of one child process.

    The peak is read by a fresh parent that waits for this one child only: the test process's own
    RUSAGE_CHILDREN is the largest of every child it ever waited for (an FMU build of an earlier test
    reached 589 MB)."""
    peak_file = cwd / "peak.txt"
    p = subprocess.run(
        [sys.executable, "-c", _PEAK, str(peak_file), *cmd],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )
    return p.returncode, p.stderr, int(peak_file.read_text()) / 1024


def _bounded(args: list[str], cwd: Path) -> tuple[int, str, float]:
    """Exit status, stderr and peak memory (MB) of a run-scenario process."""
    return _peak_of([sys.executable, "-m", "pyfmu_wrapper.cli.run_scenario", *args], cwd)


BOMB = (
    "schema_version: 2\nname: bomb\na: &a ["
    + ",".join(['"lol"'] * 9)
    + "]\n"
    + "".join(f"{c}: &{c} [" + ",".join([f"*{p}"] * 9) + "]\n" for p, c in zip("abcdefgh", "bcdefghi"))
    + "base: {mass: *i}\n"
)


@pytest.mark.parametrize(
    "case",
    ["alias bomb", "2 GB sparse file", "/dev/zero", "50 MB description", "long frequency list"],
)
def test_inputs_that_exhausted_memory_are_refused_in_bounded_memory(tmp_path, case):
    if case == "alias bomb":
        path = tmp_path / "bomb.yaml"
        path.write_text(BOMB)
        assert len(BOMB) < 1024
    elif case == "2 GB sparse file":
        path = tmp_path / "big.yaml"
        with open(path, "wb") as fh:
            fh.truncate(2 * 2**30)
    elif case == "/dev/zero":
        path = Path("/dev/zero")
    elif case == "50 MB description":
        path = tmp_path / "d.yaml"
        path.write_text(LINEAR.replace("name: tiny", "name: tiny\ndescription: " + "x" * (50 * 2**20)))
    else:
        path = tmp_path / "f.yaml"
        path.write_text(
            LINEAR.replace("{start: 17.0, stop: 23.0, count: 5}", "[" + ", ".join(["20.0"] * 100_001) + "]")
        )
    code, err, peak = _bounded([str(path), "--out", str(tmp_path / "o"), "--quiet"], tmp_path)
    assert code == 2, err
    assert "Traceback" not in err and len(err.splitlines()) == 1 and len(err) < 600
    assert peak < 500, f"{peak:.0f} MB"
    assert not (tmp_path / "o").exists()


def test_a_description_and_values_in_messages_are_cut_short(tmp_path, capsys):
    p = tmp_path / "s.yaml"
    p.write_text(LINEAR.replace("mass: 100.0", "mass: '" + "9" * 5000 + "'", 1))
    assert main([str(p), "--out", str(tmp_path / "o"), *MONO]) == 2
    err = capsys.readouterr().err
    assert "base.mass" in err and len(err) < 600


def test_optimise_json_replaces_only_its_own_unchanged_file(tmp_path, capsys):
    from pyfmu_wrapper.cli.optimise import main as optimise_main

    out = tmp_path / "opt.json"
    args = ["--case", "1", "--parameter", "damping", "--quiet", "--scan", "3", "--json", str(out)]
    assert optimise_main(args) == 0
    first = json.loads(out.read_text())
    assert first["parameter"] == "tmd.damping"
    assert optimise_main(args) == 0  # its own, unchanged: replaced
    out.write_text(out.read_text() + " ")  # edited by the user: refused before optimising, kept
    before = out.read_bytes()
    assert optimise_main(args) == 2
    assert "changed since optimise wrote it" in capsys.readouterr().err
    assert out.read_bytes() == before


def test_a_rerun_served_from_checkpoints_says_so(tmp_path, capsys):
    scn = write_scenario(tmp_path, SLOW.replace("count: 41", "count: 5"))
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out), *MONO]) == 0
    assert "read from the checkpoints" not in capsys.readouterr().out
    first = pd.read_csv(out / "frc.csv")
    assert main([str(scn), "--out", str(out), *MONO]) == 0
    said = capsys.readouterr().out
    assert "2 of 2 sweeps were read from the checkpoints" in said and "--no-resume" in said
    pd.testing.assert_frame_equal(
        pd.read_csv(out / "frc.csv").drop(columns="wall_time"), first.drop(columns="wall_time")
    )


def _diagnose_bounded(dataset: Path, out: Path) -> tuple[int, str, float]:
    """Exit status, stderr and peak memory (MB) of a diagnose process."""
    return _peak_of(
        [sys.executable, "-c", "import sys; from pyfmu_wrapper.cli.diagnose import main_diagnose as m; sys.exit(m())"]
        + [str(dataset), "--out", str(out)],
        dataset.parent,
        env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])},
    )


@pytest.mark.parametrize("case", ["alias bomb in dataset.yaml", "2 GB sparse record", "a record of NUL bytes"])
def test_diagnose_refuses_inputs_that_exhausted_memory(tmp_path, case):
    ds = tmp_path / "ds"
    shutil.copytree(Path(__file__).resolve().parents[1] / "data" / "brfd_link", ds)
    rec = sorted(ds.glob("*.csv"))[0]
    if case == "alias bomb in dataset.yaml":
        text = (ds / "dataset.yaml").read_text()
        (ds / "dataset.yaml").write_text(BOMB.split("base:")[0].replace("schema_version: 2\nname: bomb\n", "") + text)
    elif case == "2 GB sparse record":
        with open(rec, "r+b") as fh:
            fh.truncate(2 * 2**30)
    else:
        rec.write_bytes(b"\0" * (8 * 2**20))
    code, err, peak = _diagnose_bounded(ds, tmp_path / "out")
    assert code == 2, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert peak < 500, f"{peak:.0f} MB"
    assert not (tmp_path / "out").exists()


def test_build_fmus_keeps_a_file_that_appears_at_its_target_while_it_builds(tmp_path, monkeypatch):
    """The FMU is written beside its target and put in place only if what is there then is an FMU of
    build-fmus: a user's file that appeared meanwhile is kept, the new FMU goes beside it (exit 2)."""
    from pyfmu_wrapper.fmubuild import build
    from pyfmu_wrapper.models.catalog import FMUS
    from pyfmu_wrapper.safeio import Diverted

    out = tmp_path / "fmus"
    real = build._write_archive

    def write_then_user_file(part, fmu, *a, **k):
        real(part, fmu, *a, **k)
        (out / f"{fmu.spec.model_identifier}.fmu").write_text("my own file\n")  # the user, during the build

    monkeypatch.setattr(build, "_write_archive", write_then_user_file)
    with pytest.raises(Diverted) as err:
        build.build_fmu(FMUS["BaseOscillator"], out)
    assert (out / "BaseOscillator.fmu").read_text() == "my own file\n"
    assert err.value.path.exists() and build.fmu_source_hash(err.value.path) is not None
