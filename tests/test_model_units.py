"""Every registered model unit (models/__init__.py) tested alike, on its example structure, with no
assumption that its equations are linear: the Jacobian against the complex-step derivative of its own
right-hand side, the linear system read off the right-hand side against the right-hand side itself (a
nonlinear model's linearisation about rest, against its rhs at small states), the integrated steady
state against the exact one (a nonlinear model's at a small force, against its linearisation), the
start state's length checked, its declared parameters documented, its scenario block read back."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.models.solve import exact_amplitude, steady_state
from pyfmu_wrapper.physics.params import paper_case
from pyfmu_wrapper.physics.unit import ModelError

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


def _small(unit, s, tmd):
    """The unit's example where its equations are linear, else the same structure at a force 1e-4 of its
    own: the small-amplitude limit, where the linearisation about rest is exact to O(F) relative."""
    if unit.is_linear(s, tmd):
        return s, False
    return replace(s, force_amplitude=1e-4 * s.force_amplitude), True


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_linear_system_reproduces_the_rhs(unit):
    """A linear model's rhs is A z + b F cos(w t) to rounding; a nonlinear one's tends to its linearisation
    about rest: the gap is of second order or higher in the state (halving z divides it by 4 or more, to
    10 %: a quadratic term quarters it, an odd one (the sine of an angle) divides it by 8, a mix
    of both by anything between)."""
    s = unit.example()
    n = unit.n_state(s)
    tmd = TMDS["ideal"]
    linear = unit.is_linear(s, tmd)
    A, b = unit.linear_system(s, tmd, linearise=not linear)
    p = unit.pack(s, tmd, 19.0)
    z = np.random.default_rng(4).normal(size=n) * 1e-3
    t = 0.3

    def gap(zz):
        out = np.empty(n)
        unit.ode.rhs(t, zz, p, np.zeros(1), out)
        expected = A @ zz + b * s.force_amplitude * np.cos(19.0 * t)
        return np.max(np.abs(out - expected)), np.max(np.abs(out))

    g, size = gap(z)
    if linear:
        assert g <= 1e-12 * size
    else:
        g2, _ = gap(z / 2)
        assert g > 0.0 and g2 / g <= 0.25 * 1.1, (g, g2)


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_integrated_steady_state_is_the_exact_one_and_the_start_is_checked(unit):
    """The integrated steady state against the exact response: of the model where it is linear, else of
    its linearisation at a small force (1e-4 of the example's: the relative gap is O(F^2), far below 1e-5)."""
    tmd = TMDS["ideal"]
    s, linearise = _small(unit, unit.example(), tmd)
    for w in (15.0, 21.0):
        ss = steady_state(s, tmd, w)
        exact = exact_amplitude(s, tmd, [w], linearise=linearise)[0]
        assert ss.converged and abs(ss.amplitude / exact - 1) < 1e-5
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
    from pyfmu_wrapper.physics.params import ParameterError, TMDParams
    from pyfmu_wrapper.scenario.engines import RunSettings, uses_exact
    from pyfmu_wrapper.scenario.tmdspec import detached_tmd

    s, t = unit.example(), TMDS[tmd]
    linear = unit.is_linear(s, t)
    if unit.takes_tmd:
        assert linear == t.is_linear
    else:  # a model with its own absorber: its own parameters decide, whatever TMD the engines pass
        assert linear == unit.is_linear(s, detached_tmd(TMDParams()))
    assert uses_exact(s, t, RunSettings(engine="monolithic")) == linear
    if not linear:
        with pytest.raises(ParameterError, match="linear configuration"):
            exact_amplitude(s, t, 19.0)
        return
    if not unit.takes_tmd:  # the scenario loader's TMD for a model with its own absorber
        assert exact_amplitude(s, t, 19.0) == exact_amplitude(s, detached_tmd(TMDParams()), 19.0)
        t = detached_tmd(TMDParams())
    ss = steady_state(s, t, 19.0)
    assert exact_amplitude(s, t, 19.0) == pytest.approx(ss.amplitude, rel=1e-6)


@pytest.mark.parametrize("unit", UNITS, ids=lambda u: u.name)
def test_the_scenario_block_of_every_unit_is_the_units(unit):
    """A scenario's primary-structure block is found by the key the unit gives (its scenario_block,
    else its name), and a reader the unit holds is a function: the loader lists no model."""
    from pyfmu_wrapper.scenario.structspec import block_units

    assert block_units()[unit.scenario_block or unit.name] is unit
    assert len(block_units()) == len(UNITS)
    assert unit.scenario_reader is None or callable(unit.scenario_reader)
