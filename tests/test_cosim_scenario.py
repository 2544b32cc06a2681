"""``run-scenario`` with the co-simulation engine (the default) on the cases of issue 28, item 3.

Before: Case 1 with ``frequencies: [0.5, 1, 2, 4, 8, 12, 40, 80]`` ended with an FMU traceback,
"MasterError: state y = -4.2e+102", exit 1 and nothing written for any of the 8 points; a base of
1e-300 kg gave ~2 m "converged and periodic" (the FMU now refuses it at its interface). Now the
first is right at every point against the exact frequency response and the second is reported
not converged at every point, with a reason naming ``base.mass`` in the CSV and in summary.json.
"""

from __future__ import annotations

import json
import textwrap

import numpy as np
import pandas as pd

from pyfmu_wrapper.cli.run_scenario import main
from pyfmu_wrapper.physics.params import BaseParams, paper_case
from pyfmu_wrapper.solvers.frequency_response import exact_amplitude

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


def test_absurd_base_mass_reported_with_the_parameter(tmp_path):
    rc, table, summary = _run(tmp_path, "light", "1.0e-300")
    assert rc == 0 and len(table) == 8  # every point written, none lost
    assert not table["converged"].any() and table["amplitude"].isna().all()
    assert table["reason"].str.contains("base.mass (M) = 1e-300 kg", regex=False).all()
    up = summary["studies"][0]["curves"][0]["directions"]["up"]
    assert up["not_converged"] == 8 and up["peak_amplitude"] is None and up["peak_omega"] is None
    assert len(up["not_converged_reasons"]) == 8
    assert all("base.mass (M)" in r["reason"] for r in up["not_converged_reasons"])
