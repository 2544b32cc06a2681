"""diagnose: bad data gets a clear error naming the file, row and column."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.cli.diagnose import main_diagnose
from pyfmu_wrapper.diagnose.data import DataError, load_dataset

NOM = {"stiffness": 4000.0, "damping": 40.0, "inertance": 1.0}


def _write(tmp_path, csv_text, name="r1.csv", nominal=NOM, level="link"):
    (tmp_path / name).write_text(csv_text)
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump({"level": level, "nominal": nominal, "records": [{"file": name, "omega": 20.0}]})
    )
    return tmp_path


def _good_rows(n=10):
    t = np.arange(n) * 0.01
    return "\n".join(f"{a},{np.sin(20 * a)},{4000 * np.sin(20 * a)}" for a in t)


def test_missing_column_names_file_and_column(tmp_path):
    _write(tmp_path, "t,displacement\n0,0\n0.1,1\n0.2,2\n")
    with pytest.raises(DataError, match=r"r1\.csv.*column 'force'"):
        load_dataset(tmp_path)


def test_nan_names_row_and_column(tmp_path):
    rows = _good_rows().splitlines()
    rows[2] = "0.02,nan,5"
    _write(tmp_path, "t,displacement,force\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"r1\.csv, row 3, column 'displacement'"):
        load_dataset(tmp_path)


def test_non_numeric_names_row_and_column(tmp_path):
    rows = _good_rows().splitlines()
    rows[6] = "0.06,0.1,abc"
    _write(tmp_path, "t,displacement,force\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"r1\.csv, row 7, column 'force'.*'abc'"):
        load_dataset(tmp_path)


def test_time_not_increasing_names_row(tmp_path):
    rows = _good_rows().splitlines()
    rows[4] = "0.02,0.1,5"  # t goes back from 0.03 to 0.02
    _write(tmp_path, "t,displacement,force\n" + "\n".join(rows) + "\n")
    with pytest.raises(DataError, match=r"r1\.csv, row 5, column 't'.*strictly increasing"):
        load_dataset(tmp_path)


def test_missing_file_and_missing_yaml(tmp_path):
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump({"level": "link", "nominal": NOM, "records": ["nothere.csv"]})
    )
    with pytest.raises(DataError, match=r"nothere\.csv: file not found"):
        load_dataset(tmp_path)
    with pytest.raises(DataError, match=r"dataset\.yaml: file not found"):
        load_dataset(tmp_path / "sub")


def test_frc_bad_direction_and_system_nominal(tmp_path):
    _write(
        tmp_path,
        "omega,force_amplitude,x_max,direction\n15,200,0.01,up\n16,200,0.01,sideways\n17,200,0.01,up\n",
        name="frc.csv",
        level="system",
        nominal={
            "base": {"mass": 100.0, "stiffness": 4e4, "damping": 100.0, "force_amplitude": 200.0},
            "tmd": {"mass": 9.0, "stiffness": 4e3, "inertance": 1.0},
        },
    )
    with pytest.raises(DataError, match=r"frc\.csv, row 2, column 'direction'"):
        load_dataset(tmp_path)
    _write(
        tmp_path,
        "omega,force_amplitude,x_max\n15,200,0.01\n16,200,0.01\n17,200,0.01\n",
        name="frc.csv",
        level="system",
        nominal={"base": {"mass": -1.0}, "tmd": {}},
    )
    with pytest.raises(DataError, match=r"dataset\.yaml:\d+: nominal model: base: mass \(M\) must be > 0"):
        load_dataset(tmp_path)


def test_cli_reports_bad_data(tmp_path, capsys):
    _write(tmp_path, "t,displacement\n0,0\n0.1,1\n0.2,2\n")
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert "r1.csv" in capsys.readouterr().err


def test_all_train_roles_is_a_data_error_exit_2(tmp_path, capsys):
    import math

    import numpy as np
    import yaml

    from pyfmu_wrapper.cli.diagnose import main_diagnose
    from pyfmu_wrapper.diagnose.records import write_record

    recs = []
    for k, w in enumerate((15.0, 20.0, 25.0)):
        t = np.arange(600) * (2 * math.pi / w) / 200
        d = 0.01 * np.sin(w * t)
        write_record(tmp_path / f"r{k}.csv", {"t": t, "displacement": d, "force": 4e3 * d})
        recs.append({"file": f"r{k}.csv", "omega": w, "role": "train"})
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump({"level": "link", "nominal": {"stiffness": 4e3}, "records": recs})
    )
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert "role 'train'" in capsys.readouterr().err


def test_brfd_names_any_tension_and_header(tmp_path):
    import json

    import numpy as np
    import yaml

    from pyfmu_wrapper.diagnose.link.brfd import _parse, derive

    assert _parse("0.5Hz30lbtension1amplitude.json") == (0.5, 1.0, 30.0)
    assert _parse("2Hz_45lbtension_0.5inamplitude.json") == (2.0, 0.5, 45.0)
    src = tmp_path / "Dataset-3"
    src.mkdir()
    fs, f = 256.0, 1.0
    t = np.arange(0, 8, 1 / fs)
    d = np.sin(2 * np.pi * f * t) * np.clip(t, 0, 1) * np.clip(8 - t, 0, 1)
    data = np.column_stack([t, d, 2.0 * np.sign(np.cos(2 * np.pi * f * t)), np.gradient(d, t)]).tolist()
    (src / "1Hz45lbtension1amplitude.json").write_text(json.dumps({"data": data, "sampling freq": fs}))
    (src / "LICENSE.txt").write_text("CC BY-SA 4.0")
    recs = derive(src, tmp_path / "out")
    assert recs[0]["file"] == "1Hz_1in.csv"
    head = (tmp_path / "out" / "dataset.yaml").read_text()
    assert "45 lb band tension" in head and '"Dataset 3"' in head and "30 lb" not in head
    assert "45 lb" in yaml.safe_load(head)["description"]


# --- issue 17: long records, unknown keys, output folders ------------------------------------------


def _long_link(tmp_path, n, seed=2):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 1e-3
    d = 0.01 * np.sin(20 * t)
    F = 4000 * d + rng.normal(0, 0.5, n)
    (tmp_path / "dataset.yaml").write_text(
        yaml.safe_dump({"level": "link", "nominal": NOM, "records": [{"file": "long.csv", "omega": 20.0}]})
    )
    return t, d, F


def test_long_record_is_block_averaged_in_chunks(tmp_path, monkeypatch):
    """A record longer than MAX_SAMPLES is read in chunks and averaged over q = ceil(n / MAX) samples:
    the result equals the block means computed directly from the raw columns (rows that do not fill
    a last block dropped), and the console says so."""
    from pyfmu_wrapper.diagnose import records
    from pyfmu_wrapper.diagnose.records import write_record

    monkeypatch.setattr(records, "MAX_SAMPLES", 1000)
    monkeypatch.setattr(records, "CHUNK_ROWS", 700)
    t, d, F = _long_link(tmp_path, 4321)
    write_record(tmp_path / "long.csv", {"t": t, "displacement": d, "force": F}, fmt="%.17g")
    said = []
    ds = load_dataset(tmp_path, log=said.append)
    rec = ds.records[0]
    q = 5  # ceil(4321 / 1000)
    m = 4321 // q * q
    np.testing.assert_array_equal(rec["t"], t[:m].reshape(-1, q).mean(axis=1))
    np.testing.assert_allclose(rec["force"], F[:m].reshape(-1, q).mean(axis=1), rtol=0, atol=1e-12)
    np.testing.assert_allclose(rec["displacement"], d[:m].reshape(-1, q).mean(axis=1), rtol=0, atol=1e-15)
    assert rec.meta["reduced"] == {
        "rows": 4321,
        "block": q,
        "samples": m // q,
        "dropped_rows": 4321 - m,
        "method": f"boxcar average of {q} consecutive samples, one sample kept per block",
    }
    assert any("averaging every 5 consecutive samples" in s for s in said)
    assert any("the last 1 rows" in s for s in said)


@pytest.mark.parametrize(
    "row,line,match",
    [
        (2345, "2.344,nan,1", r"long\.csv, row 2345, column 'displacement': value nan"),
        (
            1401,
            "1.3985,0.001,1",
            r"long\.csv, row 1401, column 't': time must be strictly increasing: t = 1\.3985 after 1\.399",
        ),
    ],
)
def test_long_record_errors_name_the_global_row(tmp_path, monkeypatch, row, line, match):
    """Errors in a later chunk name the row of the file (1-based data row), also across a chunk boundary
    (row 1401 is the first row of the third chunk of 700)."""
    from pyfmu_wrapper.diagnose import records

    monkeypatch.setattr(records, "MAX_SAMPLES", 1000)
    monkeypatch.setattr(records, "CHUNK_ROWS", 700)
    t, d, F = _long_link(tmp_path, 3000)
    lines = ["t,displacement,force"] + [f"{a:.4f},{b:.6g},{c:.6g}" for a, b, c in zip(t, d, F)]
    lines[row] = line
    (tmp_path / "long.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=match):
        load_dataset(tmp_path, log=lambda s: None)


def test_dead_channel_in_a_long_record(tmp_path, monkeypatch):
    from pyfmu_wrapper.diagnose import records
    from pyfmu_wrapper.diagnose.records import write_record

    monkeypatch.setattr(records, "MAX_SAMPLES", 1000)
    t, d, F = _long_link(tmp_path, 2500)
    write_record(tmp_path / "long.csv", {"t": t, "displacement": d, "force": 0 * F})
    with pytest.raises(DataError, match=r"long\.csv, column 'force': the channel is constant \(every value = 0\)"):
        load_dataset(tmp_path, log=lambda s: None)


def test_acquisition_key_allowed_unknown_keys_refused(tmp_path):
    """The ALLOWED_KEYS table admits issue 19's 'acquisition' block; a typo is refused with the list."""
    rows = "t,displacement,force\n" + _good_rows(60) + "\n"
    _write(tmp_path, rows)
    doc = yaml.safe_load((tmp_path / "dataset.yaml").read_text())
    doc["acquisition"] = {"force": {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 200.0}, "delay_s": 1e-4}}
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    # the key is known (not an "unknown key"): on a link dataset the acquisition parser refuses it by name
    with pytest.raises(DataError, match=r"'acquisition' is for system-level datasets"):
        load_dataset(tmp_path)
    doc["acquisiton"] = doc.pop("acquisition")
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(DataError, match=r"unknown key\(s\) \['acquisiton'\]; allowed keys: \[.*'acquisition'"):
        load_dataset(tmp_path)


def test_result_folder_replaced_as_a_whole_user_files_never_touched(tmp_path):
    from pyfmu_wrapper.diagnose.outfolder import DIAGNOSE_MARKER, ResultFolder, check_out_folder
    from pyfmu_wrapper.errors import InputError

    out = check_out_folder(tmp_path / "res", "diagnose", DIAGNOSE_MARKER)
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("one")
        (tmp / "old.png").write_text("png")
    assert sorted(p.name for p in out.iterdir()) == [DIAGNOSE_MARKER, "old.png", "report.md"]
    check_out_folder(out, "diagnose", DIAGNOSE_MARKER)  # a previous result: accepted
    # a failed run leaves the previous result and no partial folder
    with pytest.raises(RuntimeError), ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("half")
        raise RuntimeError("boom")
    assert (out / "report.md").read_text() == "one"
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("two")
    assert sorted(p.name for p in out.iterdir()) == [DIAGNOSE_MARKER, "report.md"]  # no stale old.png
    assert (out / "report.md").read_text() == "two"
    (out / "my_notes.md").write_text("mine")
    with pytest.raises(InputError, match=r"my_notes\.md \(not written by diagnose\)"):
        check_out_folder(out, "diagnose", DIAGNOSE_MARKER)
    assert (out / "my_notes.md").read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_flagged_records_are_printed(tmp_path, capsys, monkeypatch):
    """Records the analysis leaves out (or partly out) appear in the printed verdict, not only in the report."""
    from pyfmu_wrapper.cli import diagnose as cli
    from pyfmu_wrapper.diagnose import run as diagnosis  # the CLI imports run_diagnosis from here when it runs

    res = {
        "verdict": {"text": "No structural effect."},
        "held_out": {},
        "time_records": {"flagged": [{"record": "a.csv", "reason": "no 'y' column"}]},
        "flagged_records": [{"record": "b.csv", "reason": "no 'ydd' column"}],
    }
    monkeypatch.setattr(diagnosis, "run_diagnosis", lambda *a, **k: res)
    (tmp_path / "ds").mkdir()
    assert cli.main_diagnose([str(tmp_path / "ds"), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "flagged: a.csv: no 'y' column" in out and "flagged: b.csv: no 'ydd' column" in out


def test_sigterm_removes_the_partial_folder_and_stale_ones_are_cleaned(tmp_path):
    """SIGTERM during a run behaves as Ctrl-C: the partial folder is removed, the old result kept;
    a partial folder left by a killed process is removed on the next start."""
    import os
    import signal

    from pyfmu_wrapper.diagnose.outfolder import DIAGNOSE_MARKER, ResultFolder

    out = tmp_path / "res"
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("one")
    with pytest.raises(KeyboardInterrupt), ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("half")
        os.kill(os.getpid(), signal.SIGTERM)
    assert (out / "report.md").read_text() == "one"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]
    dead = tmp_path / ".res.partial-999999999-abc"  # left by a killed run: its marker names a dead process
    dead.mkdir()
    (dead / "report.md").write_text("left by a killed run")
    import json
    import socket

    (dead / DIAGNOSE_MARKER).write_text(
        json.dumps(
            dict(tool="diagnose", kind="partial", out=str(out.resolve()), pid=999999999, host=socket.gethostname())
        )
    )
    unproven = tmp_path / ".res.partial-1-xyz"  # no marker: not provably ours, reported and left alone
    unproven.mkdir()
    with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
        (tmp / "report.md").write_text("two")
    assert sorted(p.name for p in tmp_path.iterdir()) == [".res.partial-1-xyz", "res"]
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL


def test_make_benchmark_prints_no_hidden_labels(tmp_path, capsys, monkeypatch):
    """A blind benchmark does not print what it hides: the progress lines name the datasets only."""
    import json

    from pyfmu_wrapper.cli import diagnose as cli
    from pyfmu_wrapper.diagnose.system import suite as sysbench

    def fake(out, n, seed, progress=None, **kw):
        man = []
        for i in range(n):
            (out / f"sys{i:03d}").mkdir()
            (out / f"sys{i:03d}" / "dataset.yaml").write_text("level: system\n")
            row = {
                "dataset": f"sys{i:03d}",
                "case": 2,
                "hidden": ["friction"],
                "severity": {"friction": 7.25},
                "truth": {"friction.friction_force": 7.25},
            }
            man.append(row)
            progress(row)
        (out / "manifest.json").write_text(json.dumps({"datasets": man}))
        return man

    monkeypatch.setattr(sysbench, "make_system_benchmark", fake)
    assert cli.main_make_benchmark(["--out", str(tmp_path / "b"), "-n", "2"]) == 0
    out = capsys.readouterr().out
    assert "sys001: written" in out
    assert "friction" not in out and "7.25" not in out
    assert json.loads((tmp_path / "b" / "manifest.json").read_text())["datasets"][0]["hidden"] == ["friction"]
    assert (tmp_path / "b" / cli.BENCHMARK_MARKER).is_file()
