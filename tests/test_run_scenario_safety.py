"""run-scenario never deletes or overwrites what it did not write.

One test per case of the issue: --out an existing file, a folder of user files, '.', a parent of
the current folder; SIGTERM/SIGHUP (and SIGKILL) leave no partial folder and no orphan worker; a
stale partial folder of a killed run is cleaned (ours) or reported (not provably ours) on the next
start; checkpoints live in <out>.checkpoints/, one per output folder, never in a shared
<parent>/.cache/. Every refusal happens before anything is computed (run_studies is replaced by a
function that fails the test if called).
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from _scenario_support import LINEAR, MONO, SLOW, snapshot, write_scenario

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.scenario import outdir


def test_out_is_an_existing_file(tmp_path, capsys, no_computing):
    scn = write_scenario(tmp_path)
    f = tmp_path / "existing.txt"
    f.write_text("my notes\n")
    before = snapshot(tmp_path)
    assert main([str(scn), "--out", str(f)] + MONO) == 2
    err = capsys.readouterr().err
    assert "existing.txt" in err and "not a folder" in err and "Traceback" not in err
    assert snapshot(tmp_path) == before  # the file and nothing else: no partial folder, no checkpoints


def test_out_is_a_folder_of_user_files(tmp_path, capsys, no_computing):
    scn = write_scenario(tmp_path)
    thesis = tmp_path / "thesis"
    thesis.mkdir()
    (thesis / "chapter1.tex").write_text("\\chapter{One}\n")
    (thesis / "measurements.csv").write_text("t,x\n0,1\n")
    before = snapshot(tmp_path)
    assert main([str(scn), "--out", str(thesis)] + MONO) == 2
    err = capsys.readouterr().err
    assert "chapter1.tex" in err and "measurements.csv" in err and "not a result of run-scenario" in err
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("out", [".", "..", "sub/.."])
def test_out_is_the_current_folder_or_a_parent(tmp_path, monkeypatch, capsys, no_computing, out):
    work = tmp_path / "work"
    (work / "sub").mkdir(parents=True)
    write_scenario(work)
    monkeypatch.chdir(work)
    before = snapshot(tmp_path)
    assert main(["scn.yaml", "--out", out] + MONO) == 2
    err = capsys.readouterr().err
    assert "refusing to replace" in err and "current folder" in err
    assert snapshot(tmp_path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["work"]  # no ..old-* or .partial-* beside it


def test_out_is_the_folder_of_the_scenario_file(tmp_path, capsys, no_computing):
    (tmp_path / "scenarios").mkdir()
    scn = write_scenario(tmp_path / "scenarios")
    before = snapshot(tmp_path)
    assert main([str(scn), "--out", str(scn.parent)] + MONO) == 2
    assert "scenario file" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_own_result_is_replaced_atomically_and_user_files_in_it_are_kept(tmp_path, capsys):
    scn = write_scenario(tmp_path)
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out)] + MONO) == 0
    first = json.loads((out / ".run-scenario.json").read_text())
    assert first["tool"] == "run-scenario" and first["kind"] == "result" and first["scenario"] == "tiny"
    assert first["version"] and sorted(first["files"]) == ["frc.csv", "frc.png", "summary.json", "summary.md"]
    time.sleep(1.1)  # a new 'created' second
    assert main([str(scn), "--out", str(out)] + MONO) == 0  # an earlier result of ours: replaced
    second = json.loads((out / ".run-scenario.json").read_text())
    assert second["created"] != first["created"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out", "scn.yaml"]  # no .old-*, no .partial-*
    # a file the user put into the result folder makes it no longer ours alone: refused, kept
    (out / "my_notes.txt").write_text("keep me\n")
    before = snapshot(tmp_path)
    capsys.readouterr()
    assert main([str(scn), "--out", str(out)] + MONO) == 2
    assert "my_notes.txt" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def test_result_without_its_marker_is_no_longer_provably_ours(tmp_path, capsys):
    """A folder of result files without run-scenario's marker (or with an old marker that records no
    content hashes) cannot be told from files a user put there: refused, untouched."""
    scn = write_scenario(tmp_path)
    out = tmp_path / "out"
    assert main([str(scn), "--out", str(out)] + MONO) == 0
    (out / ".run-scenario.json").unlink()
    before = snapshot(tmp_path)
    assert main([str(scn), "--out", str(out)] + MONO) == 2
    assert "not a result of run-scenario" in capsys.readouterr().err
    assert snapshot(tmp_path) == before


def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_stale_partial_folder_is_cleaned_or_reported(tmp_path, capsys):
    scn = write_scenario(tmp_path)
    out = tmp_path / "out"
    ours = tmp_path / ".out.partial-123-abcd"
    ours.mkdir()
    (ours / "frc.csv").write_text("half written\n")
    (ours / ".run-scenario.json").write_text(
        json.dumps(
            dict(
                tool="run-scenario",
                kind="partial",
                out=str(out),
                pid=_dead_pid(),
                host=os.uname().nodename,
                started="2026-01-01T00:00:00+00:00",
            )
        )
    )
    unproven = tmp_path / ".out.partial-x7y8z9"  # the old naming, no marker: not provably ours
    unproven.mkdir()
    (unproven / "data.csv").write_text("1\n")
    assert main([str(scn), "--out", str(out)] + MONO) == 0
    err = capsys.readouterr().err
    assert not ours.exists() and f"removed {ours}" in err
    assert (unproven / "data.csv").read_text() == "1\n" and f"found {unproven}" in err and "left alone" in err


def test_live_partial_folder_of_another_run_is_refused(tmp_path, capsys, no_computing):
    scn = write_scenario(tmp_path)
    out = tmp_path / "out"
    other = tmp_path / ".out.partial-1-abcd"
    other.mkdir()
    sleeper = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        (other / ".run-scenario.json").write_text(
            json.dumps(
                dict(
                    tool="run-scenario",
                    kind="partial",
                    out=str(out),
                    pid=sleeper.pid,
                    host=os.uname().nodename,
                    started="now",
                )
            )
        )
        assert main([str(scn), "--out", str(out)] + MONO) == 2
        assert "another run-scenario" in capsys.readouterr().err and other.is_dir()
    finally:
        sleeper.kill()
        sleeper.wait()


def test_checkpoints_live_beside_their_own_output_folder(tmp_path, capsys):
    """<out>.checkpoints/<study>/ with a marker; two outputs in one parent never share checkpoints;
    nothing goes to <parent>/.cache/; a foreign folder of that name is refused."""
    scn = write_scenario(
        tmp_path,
        LINEAR.replace(
            '      - {label: "c = 10"}', '      - {label: "df = 10", tmd: {damping: 0.0, friction_force: 10.0}}'
        ),
    )
    for name in ("a", "b"):
        out = tmp_path / name
        assert (
            main(
                [
                    str(scn),
                    "--out",
                    str(out),
                    "--quiet",
                    "--engine",
                    "monolithic",
                    "--executor",
                    "sequential",
                    "--cache",
                    str(outdir.default_checkpoint_dir(out)),
                ]
            )
            == 0
        )
        ck = tmp_path / f"{name}.checkpoints"
        assert len(list((ck / "frc").glob("*.csv"))) == 1
        m = json.loads((ck / ".run-scenario.json").read_text())
        assert m["kind"] == "checkpoints" and m["out"] == str(out)
    assert not (tmp_path / ".cache").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "a.checkpoints", "b", "b.checkpoints", "scn.yaml"]
    # the default (no --cache) is the same place
    assert main([str(scn), "--out", str(tmp_path / "a")] + MONO) == 0
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["executor"]["checkpoint_dir"] == str(tmp_path / "a.checkpoints")
    assert s["executor"]["tasks"]["frc"]["cached"] == 1  # resumed from its own checkpoints
    # a folder of that name that run-scenario did not write
    (tmp_path / "c.checkpoints").mkdir()
    (tmp_path / "c.checkpoints" / "photo.jpg").write_bytes(b"\xff\xd8")
    capsys.readouterr()
    assert main([str(scn), "--out", str(tmp_path / "c")] + MONO) == 2
    assert "c.checkpoints" in capsys.readouterr().err and not (tmp_path / "c").exists()


# --- signals ---------------------------------------------------------------------------------------


def _children(pid: int) -> set[int]:
    out = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            if int(stat.read_text().rsplit(")", 1)[1].split()[1]) == pid:
                out.add(int(stat.parent.name))
        except (OSError, ValueError, IndexError):
            pass
    return out


def _cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().decode(errors="replace")
    except OSError:
        return ""


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def _env() -> dict:
    """The subprocess imports this checkout's package (not whatever else is installed)."""
    root = str(Path(__file__).resolve().parents[1])
    return dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")])))


def _start_slow_run(tmp_path):
    scn = write_scenario(tmp_path, SLOW)
    out = tmp_path / "out"
    log = open(tmp_path / "stderr.txt", "w")  # noqa: SIM115 - the child's stderr; the caller closes it
    cmd = [sys.executable, "-m", "pyfmu_wrapper.cli.run_scenario", str(scn), "--out", str(out), "--workers", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=log, cwd=tmp_path, env=_env())
    deadline = time.monotonic() + 240
    workers: set[int] = set()
    while time.monotonic() < deadline:  # wait until the pool's two workers compute
        workers = {c for c in _children(proc.pid) if "run_scenario" in _cmdline(c)} if proc.poll() is None else set()
        if len(workers) >= 2 and list(tmp_path.glob(".out.partial-*")):
            break
        assert proc.poll() is None, (tmp_path / "stderr.txt").read_text()
        time.sleep(0.2)
    assert len(workers) >= 2, "the run never started its workers"
    time.sleep(1.0)
    return proc, out, workers, log


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs Linux /proc to find worker processes")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_end_workers_and_leave_no_partial_folder(tmp_path, sig):
    proc, out, workers, log = _start_slow_run(tmp_path)
    proc.send_signal(sig)
    rc = proc.wait(timeout=60)
    log.close()
    err = (tmp_path / "stderr.txt").read_text()
    assert rc == 128 + sig, err
    assert f"interrupted ({signal.Signals(sig).name})" in err and "Traceback" not in err
    time.sleep(0.5)
    assert not any(_alive(w) for w in workers), "orphan worker processes"
    assert not out.exists()
    assert not list(tmp_path.glob(".out.*")), "partial folder left behind"


@pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="needs Linux /proc to find worker processes")
def test_sigkill_leaves_no_orphan_and_the_next_start_cleans_the_partial_folder(tmp_path, capsys):
    proc, out, workers, log = _start_slow_run(tmp_path)
    proc.kill()  # no handler can run: the workers die with their parent (PR_SET_PDEATHSIG)
    proc.wait(timeout=60)
    log.close()
    deadline = time.monotonic() + 10
    while any(_alive(w) for w in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not any(_alive(w) for w in workers), "orphan worker processes after SIGKILL"
    stale = list(tmp_path.glob(".out.partial-*"))
    assert len(stale) == 1  # what a SIGKILL leaves; cleaned on the next start
    scn = write_scenario(tmp_path, LINEAR)  # the same output folder, a quick scenario
    assert main([str(scn), "--out", str(out)] + MONO) == 0
    assert f"removed {stale[0]}" in capsys.readouterr().err
    assert not stale[0].exists() and (out / "summary.json").is_file()
