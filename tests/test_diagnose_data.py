"""diagnose: bad data gets a clear error naming the file, row and column."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.cli import main_diagnose
from pyfmu_wrapper.diagnose.data import DataError, load_dataset

NOM = {"stiffness": 4000.0, "damping": 40.0, "inertance": 1.0}


def _write(tmp_path, csv_text, name="r1.csv", nominal=NOM, level="link"):
    (tmp_path / name).write_text(csv_text)
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": level, "nominal": nominal,
                                                           "records": [{"file": name, "omega": 20.0}]}))
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
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": "link", "nominal": NOM, "records": ["nothere.csv"]}))
    with pytest.raises(DataError, match=r"nothere\.csv: file not found"):
        load_dataset(tmp_path)
    with pytest.raises(DataError, match=r"dataset\.yaml: file not found"):
        load_dataset(tmp_path / "sub")


def test_frc_bad_direction_and_system_nominal(tmp_path):
    _write(tmp_path, "omega,force_amplitude,x_max,direction\n15,200,0.01,up\n16,200,0.01,sideways\n17,200,0.01,up\n",
           name="frc.csv", level="system",
           nominal={"base": {"mass": 100.0, "stiffness": 4e4, "damping": 100.0, "force_amplitude": 200.0},
                    "tmd": {"mass": 9.0, "stiffness": 4e3, "inertance": 1.0}})
    with pytest.raises(DataError, match=r"frc\.csv, row 2, column 'direction'"):
        load_dataset(tmp_path)
    _write(tmp_path, "omega,force_amplitude,x_max\n15,200,0.01\n16,200,0.01\n17,200,0.01\n", name="frc.csv",
           level="system", nominal={"base": {"mass": -1.0}, "tmd": {}})
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

    from pyfmu_wrapper.diagnose.cli import main_diagnose
    from pyfmu_wrapper.diagnose.data import write_record

    recs = []
    for k, w in enumerate((15.0, 20.0, 25.0)):
        t = np.arange(600) * (2 * math.pi / w) / 200
        d = 0.01 * np.sin(w * t)
        write_record(tmp_path / f"r{k}.csv", {"t": t, "displacement": d, "force": 4e3 * d})
        recs.append({"file": f"r{k}.csv", "omega": w, "role": "train"})
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump({"level": "link", "nominal": {"stiffness": 4e3},
                                                           "records": recs}))
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert "role 'train'" in capsys.readouterr().err


def test_brfd_names_any_tension_and_header(tmp_path):
    import json

    import numpy as np
    import yaml

    from pyfmu_wrapper.diagnose.brfd import _parse, derive

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
