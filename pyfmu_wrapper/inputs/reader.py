"""Reading a scenario document with located errors: :class:`Reader` checks mappings, lists, numbers,
strings and grids and raises :class:`ScenarioError` naming the file, the line, the key path
(``tmd.friction_force``, ``studies[2].values[3]``) and the offending value; the scenario loader and a
model's own block reader (:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.scenario_reader`) use it."""

from __future__ import annotations

import math
import re
from collections.abc import Iterable, Mapping
from typing import TYPE_CHECKING, Any, NoReturn

import numpy as np

from ..errors import InputError, short
from ..physics.params import ParameterError
from .yamlio import MAX_LIST_ITEMS, MarkedDict, MarkedList

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray

    from .yamlio import MarkedDict, MarkedList


class ScenarioError(InputError):
    """A scenario file that cannot be read or is not valid.

    Attributes: ``file``, ``line`` (1-based, or None), ``path`` (key path such as
    ``studies[2].values[3]``, or None) and ``value`` (the offending value, when there is one).
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        line: int | None = None,
        path: str | None = None,
        value: Any = None,
    ) -> None:
        super().__init__(message)
        self.file, self.line, self.path, self.value = file, line, path, value


MAX_GRID = MAX_LIST_ITEMS  # the longest list a YAML file may hold (inputs/yamlio.py)
#: the longest text a scenario field may hold (a description of a few paragraphs is a few thousand)
MAX_STRING = 20_000


def key_path(path: str, key: int | str) -> str:
    if isinstance(key, int):
        return f"{path}[{key}]"
    return f"{path}.{key}" if path else str(key)


class Reader:
    """Validation context: the file name and helpers that raise located errors."""

    def __init__(self, file: str) -> None:
        self.file = file

    # -- errors ---------------------------------------------------------------------------------
    def fail(self, path: str, line: int | None, reason: str, value: Any = None, *, show_value: bool = True) -> NoReturn:
        where = f"{self.file}:{line}" if line else self.file
        got = f" (got {short(value)})" if show_value else ""
        raise ScenarioError(
            f"{where}: {path or '<top level>'}: {reason}{got}", file=self.file, line=line, path=path, value=value
        )

    def parameter_error(self, exc: ParameterError, path: str, line: int | None, value: Any) -> NoReturn:
        """Re-raise a ParameterError built with ``source=self.source(path, line)`` as a ScenarioError."""
        text = str(exc).replace(f" (from {self.source(path, line)})", "")
        where = f"{self.file}:{line}" if line else self.file
        raise ScenarioError(f"{where}: {path}: {text}", file=self.file, line=line, path=path, value=value) from None

    def source(self, path: str, line: int | None) -> str:
        return f"{self.file}:{line} {path}" if line else f"{self.file} {path}"

    # -- structure ------------------------------------------------------------------------------
    def mapping(
        self,
        node: Any,
        path: str,
        line: int | None,
        *,
        required: Iterable[str] = (),
        optional: Iterable[str] = (),
        hints: Mapping[str, str] | None = None,
    ) -> Any:
        """Check a mapping's keys; ``hints``: key -> where it belongs instead (a clearer refusal)."""
        if not isinstance(node, dict):
            self.fail(path, line, f"must be a mapping with keys {list(required) + list(optional)}", node)
        allowed = set(required) | set(optional)
        for key in node:
            if key not in allowed:
                hint = (hints or {}).get(key)
                reason = (
                    f"does not apply here: {hint}"
                    if hint
                    else f"unknown key {short(key)}; allowed keys: {sorted(map(str, allowed))}"
                )
                self.fail(key_path(path, key), line_of(node, key), reason, node[key])
        for key in required:
            if key not in node:
                self.fail(key_path(path, key), line_of(node), "missing required key", show_value=False)
        return node

    def sequence(self, node: Any, path: str, line: int | None, *, nonempty: bool = True) -> Any:
        if not isinstance(node, list):
            self.fail(path, line, "must be a list", node)
        if nonempty and not node:
            self.fail(path, line, "must not be empty", node)
        return node

    # -- scalars ------------------------------------------------------------------------------
    def number(
        self,
        node: Any,
        key: str,
        path: str,
        *,
        minimum: float | None = None,
        strict: bool = False,
        maximum: float | None = None,
        default: Any = None,
    ) -> Any:
        p = key_path(path, key)
        if key not in node:
            return default
        v, line = node[key], line_of(node, key)
        return self.check_number(v, p, line, minimum=minimum, strict=strict, maximum=maximum)

    def check_number(
        self,
        v: Any,
        p: str,
        line: int | None,
        *,
        minimum: float | None = None,
        strict: bool = False,
        maximum: float | None = None,
    ) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(p, line, "must be a number", v)
        if not math.isfinite(v):
            self.fail(p, line, "must be finite", v)
        if minimum is not None and (v <= minimum if strict else v < minimum):
            self.fail(p, line, f"must be {'>' if strict else '>='} {minimum:g}", v)
        if maximum is not None and v > maximum:
            self.fail(p, line, f"must be <= {maximum:g}", v)
        return float(v)

    def integer(
        self,
        node: Any,
        key: str,
        path: str,
        *,
        minimum: int | None = None,
        maximum: int | None = None,
        default: Any = None,
        allow_null: bool = False,
    ) -> Any:
        p = key_path(path, key)
        if key not in node:
            return default
        v, line = node[key], line_of(node, key)
        if v is None and allow_null:
            return None
        if isinstance(v, bool) or not isinstance(v, int):
            self.fail(p, line, "must be an integer" + (" or null" if allow_null else ""), v)
        if minimum is not None and v < minimum:
            self.fail(p, line, f"must be >= {minimum}", v)
        if maximum is not None and v > maximum:
            self.fail(p, line, f"must be <= {maximum}", v)
        return int(v)

    def string(
        self,
        node: Any,
        key: str,
        path: str,
        *,
        default: Any = None,
        choices: Iterable[str] | None = None,
        pattern: re.Pattern[str] | None = None,
    ) -> Any:
        p = key_path(path, key)
        if key not in node:
            return default
        v, line = node[key], line_of(node, key)
        if not isinstance(v, str):
            self.fail(p, line, "must be a string", v)
        if len(v) > MAX_STRING:
            self.fail(p, line, f"a text of {len(v):,} characters: at most {MAX_STRING:,}", show_value=False)
        if choices is not None and v not in choices:
            self.fail(p, line, f"must be one of {list(choices)}", v)
        if pattern is not None and not pattern.match(v):
            self.fail(p, line, "must be a simple name (letters, digits, '_', '-', '.')", v)
        return v

    def boolean(self, node: Any, key: str, path: str, *, default: bool = False) -> bool:
        if key not in node:
            return default
        v = node[key]
        if not isinstance(v, bool):
            self.fail(key_path(path, key), line_of(node, key), "must be true or false", v)
        return v

    # -- grids ----------------------------------------------------------------------------------
    def grid(self, node: Any, path: str, line: int | None, *, positive: bool = False) -> ndarray:
        """{start, stop, count} (evenly spaced, both ends included) or an explicit list of numbers."""
        minimum = 0.0 if positive else None
        if isinstance(node, list):
            self.sequence(node, path, line)
            if len(node) > MAX_GRID:
                self.fail(path, line, f"a list of {len(node):,} values: at most {MAX_GRID:,}", show_value=False)
            vals = [
                self.check_number(v, key_path(path, i), line_of(node, i), minimum=minimum, strict=positive)
                for i, v in enumerate(node)
            ]
            return np.array(vals)
        self.mapping(node, path, line, required=("start", "stop", "count"))
        start = self.number(node, "start", path, minimum=minimum, strict=positive)
        stop = self.number(node, "stop", path, minimum=minimum, strict=positive)
        count = self.integer(node, "count", path, minimum=1, maximum=MAX_GRID)
        if stop < start:
            self.fail(key_path(path, "stop"), line_of(node, "stop"), f"must be >= start = {start:g}", stop)
        if count == 1 and stop != start:
            self.fail(key_path(path, "count"), line_of(node, "count"), "must be >= 2 when stop != start", count)
        return np.linspace(start, stop, count)


def line_of(node: Any, key: Any = None) -> int | None:
    if key is not None and isinstance(node, (MarkedDict, MarkedList)):
        return node.line_of(key)
    return getattr(node, "line", None)
