"""FMU unit strings are read by FMI's unit grammar (pyfmu_wrapper/fmi/units.py), never looked up in a table of
whole strings: any product of known symbols gives its BaseUnit exponents, a malformed string or an unknown
symbol is refused with the FMU, the variable and the string named (never a bare ``KeyError``)."""

from __future__ import annotations

import re

import pytest

from pyfmu_wrapper.fmi.units import BASE_UNITS, UnitError, base_unit, time_derivative
from pyfmu_wrapper.fmi.varspec import REAL, FmuSpec, Variable, parameter
from pyfmu_wrapper.fmubuild.model_description import model_description_xml
from pyfmu_wrapper.fmubuild.model_description3 import model_description3_xml
from pyfmu_wrapper.models.catalog import SPECS


@pytest.mark.parametrize(
    ("unit", "exponents"),
    [
        ("N.m.s/rad", {"kg": 1, "m": 2, "s": -1, "rad": -1}),  # a torsional damper (the pendulum's c_p)
        ("N.m", {"kg": 1, "m": 2, "s": -2}),
        ("kg.m2", {"kg": 1, "m": 2}),
        ("m/s2", {"m": 1, "s": -2}),
        ("N/m", {"kg": 1, "s": -2}),
        ("N.s/m", {"kg": 1, "s": -1}),
        ("N/m3", {"kg": 1, "m": -2, "s": -2}),
        ("rad/s", {"rad": 1, "s": -1}),
        ("s/m", {"s": 1, "m": -1}),
        ("1/kg", {"kg": -1}),
        ("1", {}),
        ("kg.m.s-2", {"kg": 1, "m": 1, "s": -2}),
        ("J/(kg.K)", {"m": 2, "s": -2, "K": -1}),
        ("W", {"kg": 1, "m": 2, "s": -3}),
        ("Pa.s", {"kg": 1, "m": -1, "s": -1}),
        ("Hz", {"s": -1}),
        ("A.s", {"s": 1, "A": 1}),
        ("m/m", {}),
    ],
)
def test_exponents(unit, exponents):
    got = base_unit(unit)
    assert got == exponents
    assert set(got) <= set(BASE_UNITS) and all(got.values())


def test_the_order_is_the_order_the_symbols_bring_the_base_units_in():
    """(What the model descriptions write; XML attribute order carries no meaning, and this order kept every
    model description byte for byte as the table it replaced wrote it.)"""
    assert list(base_unit("N.s/m")) == ["kg", "s"]
    assert list(base_unit("s/m")) == ["s", "m"]
    assert list(base_unit("N.m.s/rad")) == ["kg", "m", "s", "rad"]


@pytest.mark.parametrize(
    ("unit", "words"),
    [
        ("N.m.s/radd", "unknown symbol 'radd'"),
        ("mm", "unknown symbol 'mm'"),  # a prefix needs a factor, which these FMUs never declare
        ("degC", "unknown symbol 'degC'"),
        ("N..m", "an empty factor"),
        ("N.m/", "an empty factor"),
        ("m/s/s", "at most one '/'"),
        ("N/m.s", "must be in parentheses"),
        ("m^2", "the factor 'm^2'"),
        ("m2.5", "the factor '5'"),
        ("N m", "no white space"),
        ("", "is malformed"),
        ("2/s", "the factor '2'"),
    ],
)
def test_a_bad_unit_is_refused_with_the_string(unit, words):
    with pytest.raises(UnitError, match=re.escape(f"unit {unit!r}")) as err:
        base_unit(unit)
    assert words in str(err.value)
    assert isinstance(err.value, ValueError) and not isinstance(err.value, KeyError)


def _spec(unit: str) -> FmuSpec:
    return FmuSpec(
        model_name="PendulumTMD",
        model_identifier="PendulumTMD",
        description="a pendulum",
        variables=(
            parameter("c_p", 0, 0.0177228, unit, "pivot damping"),
            Variable(name="x", vr=1, type=REAL, causality="output", variability="continuous", description="x"),
        ),
    )


def test_a_malformed_unit_is_refused_naming_the_fmu_and_the_variable():
    with pytest.raises(UnitError) as err:
        _spec("N.m.s/rad/s")
    assert str(err.value).startswith("FMU PendulumTMD, variable 'c_p': unit 'N.m.s/rad/s' is malformed")
    with pytest.raises(UnitError, match=r"^FMU PendulumTMD, variable 'c_p': unit 'N.m.s/rd': unknown symbol 'rd'"):
        _spec("N.m.s/rd")


def test_a_unit_no_table_listed_goes_into_both_model_descriptions():
    """The pendulum's torsional damper: the unit string that ended in a KeyError."""
    spec = _spec("N.m.s/rad")
    guid = "{00000000-0000-0000-0000-000000000000}"
    unit = '<Unit name="N.m.s/rad">\n      <BaseUnit kg="1" m="2" s="-1" rad="-1"/>\n    </Unit>'
    assert unit in model_description_xml(spec, guid)
    assert unit in model_description3_xml(spec, guid)


@pytest.mark.parametrize(
    ("unit", "order", "derived"),
    [
        ("m", 1, "m/s"),
        ("m", 2, "m/s2"),
        ("m/s", 1, "m/s2"),
        ("m/s2", 2, "m/s4"),
        ("N", 1, "N/s"),
        ("N", 2, "N/s2"),
        ("N.s/m", 1, "N.s/(m.s)"),
        ("1", 1, "1/s"),
        ("m.s-1/s-1", 1, "m.s-1"),
    ],
)
def test_the_unit_of_a_time_derivative(unit, order, derived):
    """(The FMI 3.0 variant's input derivatives der(u), der(u,2).)"""
    assert time_derivative(unit, order) == derived
    exps = dict(base_unit(unit))
    exps["s"] = exps.get("s", 0) - order
    assert base_unit(derived) == {k: v for k, v in exps.items() if v}


def test_every_fmu_unit_reads():
    for name, spec in SPECS.items():
        for v in spec.variables:
            if v.unit is not None:
                base_unit(v.unit, where=f"{name}.{v.name}")
