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
    with pytest.raises(DataError, match=r"dataset\.yaml: nominal model: mass \(M\) must be > 0"):
        load_dataset(tmp_path)


def test_cli_reports_bad_data(tmp_path, capsys):
    _write(tmp_path, "t,displacement\n0,0\n0.1,1\n0.2,2\n")
    assert main_diagnose([str(tmp_path), "--out", str(tmp_path / "out")]) == 2
    assert "r1.csv" in capsys.readouterr().err
