"""The effect vocabulary a model unit declares (physics/effects.py, models/base_tmd/effects.py): what
each effect does to the model is held against the paper's force laws written out here (not read from
the table), and the table's own rules (one unit per parameter name, each name once)."""

from __future__ import annotations

import math

import pytest

from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.physics.effects import Effect, EffectParam, Vocabulary, report_unit
from pyfmu_wrapper.physics.kernels import static_link_force
from pyfmu_wrapper.physics.params import P_I, BaseParams, P_m, TMDParams, pack
from pyfmu_wrapper.physics.registry import PACK_INDEX

VOCAB = MODELS.get("base_tmd").effects
BASE = BaseParams(mass=100.0, stiffness=4.0e4, damping=100.0, force_amplitude=200.0)
TMD = TMDParams(mass=9.0, stiffness=4.0e3, damping=15.0, inertance=1.0, friction_force=2.0, friction_slope=50.0)


def _packed(p):
    return {k: p[i] for k, i in PACK_INDEX.items()}


def _link(p, u, v):
    """Fs = k u + k3 u^3 + c v + df (2/pi) atan(s v): the paper's link law (physics notes), written out."""
    P = _packed(p)
    k, k3, c = P["tmd.stiffness"], P["tmd.cubic_stiffness"], P["tmd.damping"]
    df, s = P["tmd.friction_force"], P["tmd.friction_slope"]
    return k * u + k3 * u**3 + c * v + df * 2 / math.pi * math.atan(s * v)


@pytest.mark.parametrize(
    ("effect", "theta"),
    [("viscous", [7.0]), ("cubic", [2e5]), ("friction", [5.0, 300.0]), ("tmd_stiffness", [-150.0])],
)
def test_link_effects_change_the_kernels_link_force_as_the_law_says(effect, theta):
    """Applied to the packed array, a link effect changes the kernels' link force by exactly what its
    label says: c -> c + dc, + k3 u^3, the friction (df, s) replacing the nominal's 2 N, k -> k + dk."""
    p0 = pack(BASE, TMD)
    p = p0.copy()
    values = dict(_packed(p))
    VOCAB.change(values, (effect,), theta)
    for k, v in values.items():
        p[PACK_INDEX[k]] = v
    u, v = 3e-3, 0.02
    want = (
        _link(p0, u, v)
        + {
            "viscous": 7.0 * v,
            "cubic": 2e5 * u**3,
            "friction": (5.0 * math.atan(300.0 * v) - 2.0 * math.atan(50.0 * v)) * 2 / math.pi,
            "tmd_stiffness": -150.0 * u,
        }[effect]
    )
    got = static_link_force(u, v, 0.0, 0.0, p)
    assert abs(got - want) < 1e-12 * max(abs(want), 1.0)


def test_mass_split_keeps_m_plus_i_and_measurement_effects_change_no_parameter():
    p0 = pack(BASE, TMD)
    values = dict(_packed(p0))
    VOCAB.change(values, ("mass_split", "force_error", "sensor_offset"), [0.4, 0.05, 1e-3, 2e-3])
    assert values["tmd.inertance"] == p0[P_I] + 0.4 and values["tmd.mass"] == p0[P_m] - 0.4
    assert {k: v for k, v in values.items() if k not in ("tmd.inertance", "tmd.mass")} == {
        k: v for k, v in _packed(p0).items() if k not in ("tmd.inertance", "tmd.mass")
    }


def test_changed_parameters_stay_within_the_registry_bounds():
    """A change past a bound is held at it: a damping that would go negative is 0, a mass (strict
    minimum 0) is 1e-6 of the nominal; within the bounds the change is exact."""
    new = VOCAB.changed(
        {"base": BASE, "tmd": TMD},
        {"viscous.delta_damping": -40.0, "base_mass.delta_mass": -200.0, "base_stiffness.delta_stiffness": 500.0},
    )
    assert new["tmd"].damping == 0.0 and new["base"].mass == 1e-6 * BASE.mass
    assert new["base"].stiffness == BASE.stiffness + 500.0 and new["tmd"] == TMDParams(
        **{**TMD.__dict__, "damping": 0.0}
    )


def test_every_declared_parameter_of_the_pair_is_an_effect_at_its_element():
    """The candidates include every declared mass, stiffness and damper of the pair (base and TMD) and the
    inertance, each once, at the element it belongs to; units from the registry in the reports' form."""
    targets = {t for e in VOCAB.effects.values() for p in e.params for t, c in p.targets if not p.replaces}
    assert {"base.mass", "base.stiffness", "base.damping", "tmd.mass", "tmd.stiffness", "tmd.damping"} <= targets
    assert VOCAB["base_mass"].element == "base" and VOCAB["viscous"].element == "tmd link"
    assert VOCAB["cubic"].params[0].unit == "N/m^3" and VOCAB["viscous"].params[0].unit == "N s/m"
    assert report_unit("N.s/m") == "N s/m" and report_unit("N/m3") == "N/m^3"
    assert VOCAB["friction"].linear_params == ("friction_force",)  # the slope is searched, not linear


def test_a_vocabulary_refuses_a_name_twice_and_a_parameter_with_two_units():
    a = Effect("a", "a", "tmd", (EffectParam("x", "m"),))
    with pytest.raises(ValueError, match="declared twice"):
        Vocabulary([a, a])
    with pytest.raises(ValueError, match="two units"):
        Vocabulary([a, Effect("b", "b", "tmd", (EffectParam("x", "N"),))])
    with pytest.raises(KeyError, match="not in the vocabulary"):
        VOCAB.select(["viscous", "no_such_effect"])
