"""The paper's ``base:`` block of a scenario, read into :class:`~pyfmu_wrapper.physics.params.BaseParams` with
located errors (file, line, key path, value): the base_tmd unit's own reader (its declared rows hold omega,
which a scenario gives as ``frequencies``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...physics.params import BaseParams, ParameterError, field_names

if TYPE_CHECKING:
    from ...inputs.reader import Reader
    from ...inputs.yamlio import MarkedDict

#: the keys of a base: block, every one required
BASE_FIELDS = tuple(field_names(BaseParams))


def read_base(rd: Reader, node: MarkedDict, line: int | None) -> BaseParams:
    """The paper's ``base:`` block as BaseParams (the base_tmd unit's reader: its declared rows hold
    omega, which a scenario gives as ``frequencies``)."""
    from ...inputs.reader import line_of  # here: an FMU, which imports the unit, reads no scenario

    b = rd.mapping(node, "base", line, required=BASE_FIELDS)
    for key in BASE_FIELDS:
        rd.number(b, key, "base")
    try:
        return BaseParams(**{k: b[k] for k in BASE_FIELDS})
    except ParameterError:
        key = next(k for k in BASE_FIELDS if _base_fails(b, k))
        p, ln = f"base.{key}", line_of(b, key)
        try:
            BaseParams(**{k: b[k] for k in BASE_FIELDS}, source=rd.source(p, ln))
        except ParameterError as exc:
            rd.parameter_error(exc, p, ln, b[key])
        raise  # pragma: no cover - the same values cannot pass the second time


def _base_fails(b: MarkedDict, key: str) -> bool:
    try:
        BaseParams(**{key: b[key]})
        return False
    except ParameterError:
        return True
