"""FMU unit strings read by their grammar: a unit such as ``"N.m.s/rad"`` -> the exponents of FMI's BaseUnit.

FMI 2.0 (section 2.2.2, ``fmi2Unit.xsd``) and FMI 3.0 declare a unit by its name (the schema's examples:
``"N.m"``, ``"%/s"``) and a ``BaseUnit``: integer exponents of the SI base units ``kg``, ``m``, ``s``, ``A``,
``K``, ``mol``, ``cd`` and of the derived unit ``rad``, with ``factor`` (default 1) and ``offset`` (default
0). The names follow Modelica's unit expressions (Modelica Language Specification, chapter "Unit
Expressions", the syntax FMI's examples are written in)::

    unit-expression  = unit-numerator [ "/" unit-denominator ]
    unit-numerator   = "1" | unit-factors
    unit-denominator = unit-factor | "(" unit-factors ")"
    unit-factors     = unit-factor [ "." unit-factors ]
    unit-factor      = unit-symbol [ unit-exponent ]        e.g. m2, s-2
    unit-exponent    = [ "+" | "-" ] UNSIGNED-INTEGER

that is: products with ``.``, at most one ``/`` (more than one factor after it in parentheses, as SI
asks), integer exponents written after the symbol. A symbol is one of :data:`SYMBOLS`: the base units
and the coherent derived SI units (N, J, W, Pa, Hz, ...), all with factor 1 and offset 0. Prefixed and
non-SI units (``mm``, ``deg``, ``degC``, ``min``) need a factor or an offset, which this project's FMUs
never declare: they are refused like any unknown symbol, and so is a malformed string, with a
:class:`UnitError` naming the unit string (and, from :func:`base_unit`'s ``where``, the FMU and the
variable). There is no table of whole unit strings: any product of known symbols is read.
"""

from __future__ import annotations

import re

#: the exponent attributes of FMI's BaseUnit, in the schema's order
BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")

#: symbol -> its exponents of :data:`BASE_UNITS` (factor 1): the base units, then the coherent derived SI units
SYMBOLS: dict[str, tuple[tuple[str, int], ...]] = {
    **{b: ((b, 1),) for b in BASE_UNITS},
    "Hz": (("s", -1),),
    "N": (("kg", 1), ("m", 1), ("s", -2)),
    "Pa": (("kg", 1), ("m", -1), ("s", -2)),
    "J": (("kg", 1), ("m", 2), ("s", -2)),
    "W": (("kg", 1), ("m", 2), ("s", -3)),
    "C": (("s", 1), ("A", 1)),
    "V": (("kg", 1), ("m", 2), ("s", -3), ("A", -1)),
    "F": (("kg", -1), ("m", -2), ("s", 4), ("A", 2)),
    "Ohm": (("kg", 1), ("m", 2), ("s", -3), ("A", -2)),
    "S": (("kg", -1), ("m", -2), ("s", 3), ("A", 2)),
    "Wb": (("kg", 1), ("m", 2), ("s", -2), ("A", -1)),
    "T": (("kg", 1), ("s", -2), ("A", -1)),
    "H": (("kg", 1), ("m", 2), ("s", -2), ("A", -2)),
    "Bq": (("s", -1),),
    "Gy": (("m", 2), ("s", -2)),
    "Sv": (("m", 2), ("s", -2)),
    "kat": (("mol", 1), ("s", -1)),
}

#: one factor: a symbol (letters only: a digit starts the exponent) and its optional signed integer exponent
_FACTOR = re.compile(r"([A-Za-z]+)([+-]?[0-9]+)?")

#: a factor of a unit string: (symbol, exponent)
Factor = tuple[str, int]


class UnitError(ValueError):
    """A unit string that is malformed or uses a symbol this writer cannot declare with factor 1."""


def _factors(text: str, unit: str) -> list[Factor]:
    """The factors of a product ``a.b2.c-1`` (refused with the whole unit string named)."""
    out: list[Factor] = []
    for part in text.split("."):
        m = _FACTOR.fullmatch(part)
        if m is None:
            what = "an empty factor" if not part else f"the factor {part!r}"
            raise UnitError(
                f"unit {unit!r} is malformed: {what} is not a symbol with an optional integer exponent "
                "(write products with '.', e.g. 'N.m', and exponents after the symbol, e.g. 'm2', 's-2')"
            )
        symbol, exponent = m.group(1), int(m.group(2) or 1)
        if symbol not in SYMBOLS:
            raise UnitError(
                f"unit {unit!r}: unknown symbol {symbol!r} (known, all with factor 1: {', '.join(SYMBOLS)}; "
                "prefixed or non-SI units such as 'mm' or 'deg' need a factor, which these FMUs never declare)"
            )
        out.append((symbol, exponent))
    return out


def parse(unit: str) -> tuple[list[Factor], list[Factor]]:
    """(numerator, denominator) factors of a unit string (numerator ``[]`` for ``"1"``)."""
    if not unit or unit != unit.strip() or any(c.isspace() for c in unit):
        raise UnitError(f"unit {unit!r} is malformed: a unit string is not empty and holds no white space")
    if unit.count("/") > 1:
        raise UnitError(f"unit {unit!r} is malformed: at most one '/' (write 'J/(kg.K)' or 'J.kg-1.K-1')")
    num, slash, den = unit.partition("/")
    numerator = [] if num == "1" else _factors(num, unit)
    if not slash:
        return numerator, []
    if den.startswith("(") and den.endswith(")"):
        denominator = _factors(den[1:-1], unit)
    elif "." in den:
        raise UnitError(
            f"unit {unit!r} is malformed: more than one factor after '/' must be in parentheses, e.g. 'J/(kg.K)'"
        )
    else:
        denominator = _factors(den, unit)
    return numerator, denominator


def base_unit(unit: str, where: str = "") -> dict[str, int]:
    """The BaseUnit exponents of a unit string, zeros left out, in the order its symbols bring them in
    (``"N.m.s/rad"`` -> kg 1, m 2, s -1, rad -1; ``"1"`` -> none); ``where`` (e.g. the FMU and the
    variable) starts the message of a :class:`UnitError`."""
    try:
        numerator, denominator = parse(unit)
    except UnitError as error:
        raise UnitError(f"{where}: {error}" if where else str(error)) from None
    exps: dict[str, int] = {}
    for sign, factors in ((1, numerator), (-1, denominator)):
        for symbol, exponent in factors:
            for base, e in SYMBOLS[symbol]:
                exps[base] = exps.get(base, 0) + sign * exponent * e
    return {b: e for b, e in exps.items() if e}


def _text(factors: list[Factor]) -> str:
    return ".".join(s if e == 1 else f"{s}{e}" for s, e in factors)


def time_derivative(unit: str, order: int) -> str:
    """The unit of the order-th time derivative of a quantity in ``unit``: one more ``s`` below the bar
    (``m`` -> ``m/s``, ``m/s`` -> ``m/s2``, ``N`` -> ``N/s2`` for order 2, ``N.s/m`` -> ``N.s/(m.s)``)."""
    numerator, denominator = parse(unit)
    denominator = list(denominator)
    at = next((i for i, (s, _) in enumerate(denominator) if s == "s"), None)
    if at is None:
        denominator.append(("s", order))
    elif denominator[at][1] + order:
        denominator[at] = ("s", denominator[at][1] + order)
    else:
        del denominator[at]
    above, below = _text(numerator) or "1", _text(denominator)
    if not denominator:
        return above
    return f"{above}/{below if len(denominator) == 1 else f'({below})'}"
