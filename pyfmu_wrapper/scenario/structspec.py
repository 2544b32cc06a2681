"""The primary structure's block of a scenario for a model unit read from the unit alone: the block is
named after the unit (``linear_tmd:``), its keys are the unit's declared parameters
(:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.parameters`: name, unit, bounds), its value is the
unit's structure class built from them, with located errors (file, line, key path, value).

A new model needs no edit here: the units with a reader of their own (``base:``, the loader's;
``frame:``, :mod:`.framespec`, whose per-storey lists the declared rows cannot state) are the
exceptions :data:`OWN_READERS` names.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ..physics.params import ParameterError
from ..physics.unit import ModelUnit
from ..physics.units import MODELS
from .reader import Reader, key_path, line_of

if TYPE_CHECKING:
    from .yamlio import MarkedDict

#: units whose block another reader reads (block key -> model name): the two models that came
#: before the units (the paper's base oscillator, the frame's per-storey lists)
OWN_READERS = {"base": "base_tmd", "frame": "frame"}


def block_units() -> dict[str, ModelUnit]:
    """Every primary-structure block a scenario may have, by key: the own readers' and one per
    other registered unit (its name)."""
    own = {model: key for key, model in OWN_READERS.items()}
    return {own.get(u.name, u.name): u for u in MODELS.units()}


def read_block(rd: Reader, unit: ModelUnit, node: MarkedDict, path: str, line: int | None) -> Any:
    """The block as the unit's structure: every declared parameter required."""
    names = [p.name for p in unit.parameters]
    rd.mapping(node, path, line, required=names)
    return _build(rd, unit, None, node, path, line)


def over_block(rd: Reader, unit: ModelUnit, structure: Any, node: MarkedDict, path: str, line: int | None) -> Any:
    """``structure`` with the keys a curve's block sets (any of the declared parameters)."""
    rd.mapping(node, path, line, optional=[p.name for p in unit.parameters])
    return _build(rd, unit, structure, node, path, line)


def _build(rd: Reader, unit: ModelUnit, structure: Any, node: MarkedDict, path: str, line: int | None) -> Any:
    values = {}
    for p in unit.parameters:
        if p.name in node:
            values[p.name] = rd.check_number(
                node[p.name],
                key_path(path, p.name),
                line_of(node, p.name),
                minimum=p.minimum,
                strict=p.strict,
                maximum=p.maximum,
            )
    try:
        return unit.structure(**values) if structure is None else replace(structure, **values)
    except ParameterError as exc:  # a rule between fields: blame the block
        rd.parameter_error(exc, path, line, dict(node))
