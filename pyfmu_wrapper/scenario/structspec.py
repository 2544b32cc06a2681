"""The primary structure's block of a scenario for a model unit read from the unit alone: the block is
named after the unit (``linear_tmd:``), its keys are the unit's declared parameters
(:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.parameters`: name, unit, bounds), its value is the
unit's structure class built from them, with located errors (file, line, key path, value).

A new model needs no edit here: a unit may name its block (``scenario_block``: the paper's ``base:``)
and a reader of its own (``scenario_reader``: the frame's per-storey lists, which the declared rows
cannot state; the paper's ``base:``), which the unit holds.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ..inputs.reader import Reader, key_path, line_of
from ..models import MODELS
from ..physics.params import ParameterError
from ..physics.unit import ModelUnit

if TYPE_CHECKING:
    from ..inputs.yamlio import MarkedDict


def block_units() -> dict[str, ModelUnit]:
    """Every primary-structure block a scenario may have, by key (the unit's ``scenario_block``, else
    its name): one per registered unit."""
    return {u.scenario_block or u.name: u for u in MODELS.units()}


def read_structure(rd: Reader, unit: ModelUnit, node: MarkedDict, path: str, line: int | None) -> Any:
    """The scenario's block as the unit's structure: by the unit's own reader if it holds one, else from
    its declared parameters (:func:`read_block`)."""
    if unit.scenario_reader is None:
        return read_block(rd, unit, node, path, line)
    return unit.scenario_reader(rd, node, line)


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
