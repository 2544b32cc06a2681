"""Settings declared once: solvers/settings_table.py is the one rule of every setting.

The engines' settings classes take their defaults and ranges from it, the scenario loader refuses
exactly what the classes refuse (one rule, not the two that disagreed on steps_per_period and tol),
and the table in docs/scenarios.md is generated from it (``python -m pyfmu_wrapper.generate.docs --check``).
"""

from __future__ import annotations

from dataclasses import fields

import pytest

from pyfmu_wrapper.generate import docs as docs_gen
from pyfmu_wrapper.scenario.loader import parse_scenario
from pyfmu_wrapper.scenario.schema import COSIM_KEYS, ScenarioError
from pyfmu_wrapper.solvers import settings_table as T
from pyfmu_wrapper.solvers.monolithic import SolverSettings
from pyfmu_wrapper.solvers.steady import PLAY_STARTS, SettingsError, SteadySettings

HEAD = """schema_version: 2
name: t
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, stiffness: 4000.0}
frequencies: {start: 19.0, stop: 21.0, count: 3}
studies:
  - {kind: frc, name: f, curves: [{label: a}]}
"""


def _cosim_settings():
    from pyfmu_wrapper.cosim.settings import CosimSettings

    return CosimSettings


def test_every_field_of_both_engines_is_one_row_with_its_default():
    CosimSettings = _cosim_settings()
    for cls, engine in ((SolverSettings, T.MONO), (CosimSettings, T.COSIM)):
        names = {f.name for f in fields(cls)}
        assert names == {s.name for s in T.settings_of(engine)}, cls
        obj = cls()
        for name in names:
            assert getattr(obj, name) == T.default(name, engine), (cls.__name__, name)
    assert {f.name for f in fields(SteadySettings)} == {s.name for s in T.shared()}


def test_the_table_choices_are_the_codes_choices():
    from pyfmu_wrapper.master.schemes import SCHEMES
    from pyfmu_wrapper.models.base_tmd.cosim import COUPLINGS

    assert set(T.BY_NAME["coupling"].choices) == set(COUPLINGS)
    assert set(T.BY_NAME["scheme"].choices) == set(SCHEMES)
    assert set(T.BY_NAME["play_start"].choices) == set(PLAY_STARTS)
    # the scenario blocks accept exactly the table's keys
    assert set(COSIM_KEYS) == {s.name for s in T.SETTINGS if T.COSIM in s.blocks}


# values out of each rule (and the boundary values inside it)
OUT = [
    ("tol", 0.6),
    ("tol", -1e-9),
    ("tol_window", 0.51),
    ("min_periods", 0),
    ("window", 0),
    ("steps_per_period", 4),
    ("steps_per_period", 100_001),
    ("accuracy", 0.0),
    ("accuracy", 0.7),
    ("fmu_rtol", 0.2),
    ("order", 3),
    ("coupling", "spring"),
    ("interface_jacobian", 1),
    ("rtol", 0.0),
    ("rtol", 0.5),
    ("atol_scale", 0.0),
]
IN = [("tol", 0.5), ("tol_window", 0.0), ("steps_per_period", 8), ("accuracy", 0.5), ("rtol", 0.1), ("order", 0)]


@pytest.mark.parametrize("name,value", OUT)
def test_loader_and_settings_classes_refuse_the_same_values(name, value):
    s = T.BY_NAME[name]
    assert s.problem(value) is not None
    classes = {T.MONO: SolverSettings, T.COSIM: _cosim_settings()}
    for engine in s.engines:
        with pytest.raises(SettingsError) as e:
            classes[engine](**{name: value})
        assert e.value.field == name and e.value.reason == s.problem(value)
    for engine in s.blocks:
        block = {T.MONO: "solver", T.COSIM: "cosim"}[engine]
        text = HEAD + f"{block}: {{{name}: {value!r}}}\n".replace("'", "")
        with pytest.raises(ScenarioError) as e:
            parse_scenario(text, "s.yaml")
        msg = str(e.value)
        assert f"s.yaml:8: {block}.{name}" in msg and s.rule() in msg, msg


@pytest.mark.parametrize("name,value", IN)
def test_boundary_values_are_accepted_by_both(name, value):
    s = T.BY_NAME[name]
    assert s.problem(value) is None
    for engine in s.blocks:
        block = {T.MONO: "solver", T.COSIM: "cosim"}[engine]
        sc = parse_scenario(HEAD + f"{block}: {{{name}: {value!r}}}\n", "s.yaml")
        cfg = sc.solver if block == "solver" else sc.cosim
        assert getattr(cfg.settings(), name) == value


def test_former_disagreement_is_one_rule_now():
    # steps_per_period: the loader said >= 8, CosimSettings >= 1; tol: the loader <= 0.5, the classes no bound
    CosimSettings = _cosim_settings()
    with pytest.raises(SettingsError, match="steps_per_period"):
        CosimSettings(steps_per_period=4)
    with pytest.raises(SettingsError, match="tol"):
        SolverSettings(tol=0.9)


def test_docs_table_is_generated_from_the_table():
    text = docs_gen.SCENARIOS_FILE.read_text(encoding="utf-8")
    assert T.docs_table() in text
    for s in T.SETTINGS:
        assert f"| {s.name} | " in text
    assert docs_gen.main(["--check"]) == 0
