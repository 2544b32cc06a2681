"""Every registered model unit (models/__init__.py) tested alike, on its example structure: the
Jacobian against the complex-step derivative of its own right-hand side, the linear system read off
the right-hand side against the right-hand side itself, the exact steady state against the
integrated one, the start state's length checked, its declared parameters documented."""

from __future__ import annotations

import numpy as np
import pytest

from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.physics.params import paper_case
from pyfmu_wrapper.physics.unit import ModelError
from pyfmu_wrapper.solvers.frequency_response import exact_amplitude
from pyfmu_wrapper.solvers.monolithic import steady_state

UNITS = MODELS.units()
TMDS = {
    "ideal": paper_case(1, damping=10.0),
    "play": paper_case(1, inerter="play", play_gap=1e-4, damping=10.0),
    "friction": paper_case(1, friction_force=10.0),
    "cubic": paper_case(2, cubic_stiffness=2e6, damping=5.0),
}


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
@pytest.mark.parametrize("tmd", sorted(TMDS))
def test_jacobian_is_the_complex_step_of_the_rhs(unit, tmd):
    s = unit.example()
    n = unit.n_state(s)
    p = unit.pack(s, TMDS[tmd], 19.0)
    u = np.zeros(1)
    rng = np.random.default_rng(3)
    for _ in range(5):
        z = rng.normal(size=n) * 1e-3
        t = float(rng.uniform())
        J, ft = np.empty((n, n)), np.empty(n)
        unit.ode.jacobian(t, z, p, u, J, ft, np.empty(n, complex), np.empty(n, complex))
        Jc = np.empty((n, n))
        for j in range(n):  # the complex step, column by column, of the unit's own rhs
            zc = z.astype(complex)
            zc[j] += 1e-30j
            out = np.empty(n, complex)
            unit.ode.rhs(t, zc, p, u, out)
            Jc[:, j] = out.imag / 1e-30
        assert np.max(np.abs(J - Jc)) <= 1e-9 * np.max(np.abs(Jc))


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_linear_system_reproduces_the_rhs(unit):
    s = unit.example()
    n = unit.n_state(s)
    tmd = TMDS["ideal"]
    A, b = unit.linear_system(s, tmd)
    p = unit.pack(s, tmd, 19.0)
    z = np.random.default_rng(4).normal(size=n) * 1e-3
    t = 0.3
    out = np.empty(n)
    unit.ode.rhs(t, z, p, np.zeros(1), out)
    expected = A @ z + b * s.force_amplitude * np.cos(19.0 * t)
    assert np.max(np.abs(out - expected)) <= 1e-12 * np.max(np.abs(out))


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_integrated_steady_state_is_the_exact_one_and_the_start_is_checked(unit):
    s = unit.example()
    tmd = TMDS["ideal"]
    for w in (15.0, 21.0):
        ss = steady_state(s, tmd, w)
        assert ss.converged and abs(ss.amplitude / exact_amplitude(s, tmd, [w])[0] - 1) < 1e-5
    with pytest.raises(ModelError, match=f"start state of model '{unit.name}' must have {unit.n_state(s)} entries"):
        steady_state(s, tmd, 20.0, z0=np.zeros(unit.n_state(s) + 1))


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_declared_parameters_have_units_ranges_and_docs(unit):
    assert MODELS.of(unit.example()) is unit
    for par in unit.parameters:
        assert par.unit and par.description and par.symbol
        assert par.minimum is None or par.default >= par.minimum


def _scenario_text(block: str, values: dict, takes_tmd: bool) -> str:
    import yaml

    doc = {"schema_version": 2, "name": "t", block: values, "frequencies": [10.0]}
    if takes_tmd:
        doc["tmd"] = {"case": 1}
    doc["studies"] = [{"kind": "frc", "name": "f", "curves": [{"label": "a"}]}]
    return yaml.safe_dump(doc, sort_keys=False)


@pytest.mark.parametrize("unit", [u for u in UNITS if u.name not in ("base_tmd", "frame")], ids=lambda u: u.name)
def test_a_units_scenario_block_is_read_from_its_declared_parameters(unit):
    """A scenario's block of the unit (named after it, its keys the declared parameters) reads back
    the unit's example structure (the units with readers of their own, base: and frame:, aside)."""
    from pyfmu_wrapper.scenario.loader import parse_scenario

    s = unit.example()
    scn = parse_scenario(
        _scenario_text(unit.name, {p.name: getattr(s, p.name) for p in unit.parameters}, unit.takes_tmd)
    )
    assert scn.base == s and MODELS.of(scn.base) is unit


def test_a_model_registered_later_needs_no_edit_of_the_scenario_reader(monkeypatch):
    """A unit registered at run time (no edit anywhere but the registry) gets its scenario block, its
    located refusals and its curves' overrides."""
    from dataclasses import dataclass, replace

    from pyfmu_wrapper.models.linear_tmd import UNIT, LinearTMDParams
    from pyfmu_wrapper.scenario.loader import parse_scenario
    from pyfmu_wrapper.scenario.schema import ScenarioError

    @dataclass(frozen=True)
    class Toy(LinearTMDParams):
        pass

    monkeypatch.setitem(MODELS._units, "toy", replace(UNIT, name="toy", structure=Toy))
    values = {p.name: 1.0 for p in UNIT.parameters}
    scn = parse_scenario(_scenario_text("toy", values, False))
    assert type(scn.base) is Toy and scn.base.absorber_mass == 1.0
    with pytest.raises(ScenarioError, match=r"bad.yaml:\d+: toy.absorber_mass: must be > 0 \(got -1.0\)"):
        parse_scenario(_scenario_text("toy", values | {"absorber_mass": -1.0}, False), "bad.yaml")


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
@pytest.mark.parametrize("tmd", sorted(TMDS))
def test_the_unit_decides_whether_the_exact_path_applies(unit, tmd):
    """The exact frequency response is taken when the unit says its model is linear at these
    parameters (ModelUnit.is_linear), not when the paper's TMD alone is: a model with its own
    absorber is linear whatever TMD the engines pass it. Where the unit says linear, the exact
    amplitude is the integrated steady state's (1e-6); where not, the exact path is refused."""
    from pyfmu_wrapper.physics.params import ParameterError
    from pyfmu_wrapper.scenario.engines import RunSettings, uses_exact

    s, t = unit.example(), TMDS[tmd]
    linear = unit.is_linear(s, t)
    assert linear == (t.is_linear if unit.takes_tmd else True)
    assert uses_exact(s, t, RunSettings(engine="monolithic")) == linear
    if not linear:
        with pytest.raises(ParameterError, match="linear configuration"):
            exact_amplitude(s, t, 19.0)
        return
    if not unit.takes_tmd:  # the scenario loader's TMD for a model with its own absorber
        from pyfmu_wrapper.physics.params import TMDParams
        from pyfmu_wrapper.scenario.tmdspec import detached_tmd

        assert exact_amplitude(s, t, 19.0) == exact_amplitude(s, detached_tmd(TMDParams()), 19.0)
        t = detached_tmd(TMDParams())
    ss = steady_state(s, t, 19.0)
    assert exact_amplitude(s, t, 19.0) == pytest.approx(ss.amplitude, rel=1e-6)


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_the_scenario_block_of_every_unit_is_the_units(unit):
    """A scenario's primary-structure block is found by the key the unit gives (its scenario_block,
    else its name), and a reader the unit names resolves to a function: the loader lists no model."""
    import importlib

    from pyfmu_wrapper.scenario.structspec import block_units

    assert block_units()[unit.scenario_block or unit.name] is unit
    assert len(block_units()) == len(UNITS)
    if unit.scenario_reader:
        module, _, function = unit.scenario_reader.partition(":")
        assert callable(getattr(importlib.import_module(module), function))
