"""``run-scenario`` with the co-simulation engine (the default) on the cases of issue 28, item 3.

Before: Case 1 with ``frequencies: [0.5, 1, 2, 4, 8, 12, 40, 80]`` ended with an FMU traceback,
"MasterError: state y = -4.2e+102", exit 1 and nothing written for any of the 8 points; a base of
1e-300 kg gave ~2 m "converged and periodic" (the FMU now refuses it at its interface). Now the
first is right at every point against the exact frequency response and the second is refused
before computing (exit 2) with a sentence naming ``base.mass``; a sweep refused at some frequencies
only reports those points not converged with the reason.
"""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pandas as pd

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.models.solve import exact_amplitude
from pyfmu_wrapper.physics.params import BaseParams, paper_case

SCENARIO = textwrap.dedent(
    """\
    schema_version: 2
    name: {name}
    base: {{mass: {mass}, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}}
    tmd: {{case: 1, inerter: ideal, stiffness: 4000.0, damping: 0.0}}
    frequencies: [0.5, 1, 2, 4, 8, 12, 40, 80]
    studies:
      - kind: frc
        name: frc
        curves:
          - {{label: "ideal"}}
    """
)


def _run(tmp_path, name: str, mass: str) -> tuple[int, pd.DataFrame, dict]:
    path = tmp_path / f"{name}.yaml"
    path.write_text(SCENARIO.format(name=name, mass=mass), encoding="utf-8")
    out = tmp_path / "out"
    rc = main([str(path), "--out", str(out), "--quiet"])
    table = pd.read_csv(out / "frc.csv", keep_default_na=True)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    return rc, table, summary


def test_low_frequencies_of_case1_right_at_every_point(tmp_path):
    rc, table, _ = _run(tmp_path, "low", "100.0")
    assert rc == 0 and len(table) == 8
    assert table["engine"].eq("cosim").all() and table["converged"].all()
    exact = exact_amplitude(BaseParams(), paper_case(1), table["omega"].to_numpy())
    assert np.max(np.abs(table["amplitude"].to_numpy() / exact - 1.0)) <= 5e-3


def test_absurd_base_mass_refused_naming_the_parameter(tmp_path, capsys):
    """Every frequency refused: the run is refused before computing (exit 2), naming base.mass."""
    path = tmp_path / "light.yaml"
    path.write_text(SCENARIO.format(name="light", mass="1.0e-300"), encoding="utf-8")
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "base.mass (M) = 1e-300 kg" in err and "8 of 8 frequencies" in err and "monolithic" in err
    assert not (tmp_path / "out").exists()


def test_a_partly_refused_sweep_reports_those_points_with_the_parameter(tmp_path, capsys):
    """Only the low frequencies refused (a 1 g base on a stiff link): a warning before computing,
    those points written not converged with the reason (CSV, summary.json, closing lines)."""
    path = tmp_path / "stiff.yaml"
    text = SCENARIO.format(name="stiff", mass="0.001").replace("stiffness: 4000.0", "stiffness: 1.0e7")
    path.write_text(text.replace("[0.5, 1, 2, 4, 8, 12, 40, 80]", "[0.5, 1, 20]"), encoding="utf-8")
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet"]) == 0
    said = capsys.readouterr()
    assert "warning" in said.err and "2 of 3 frequencies" in said.err and "base.mass (M) = 0.001 kg" in said.err
    assert "because the base alone" in said.out
    table = pd.read_csv(out / "frc.csv", keep_default_na=True)
    assert list(table["converged"]) == [False, False, True]
    assert table["reason"].iloc[:2].str.contains("tmd.stiffness (k) = 1e+07 N/m", regex=False).all()
    up = json.loads((out / "summary.json").read_text())["studies"][0]["curves"][0]["directions"]["up"]
    assert [r["omega"] for r in up["not_converged_reasons"]] == [0.5, 1.0]
