"""TMD blocks of a scenario: merged over their parent (scenario tmd <- study tmd <- curve tmd <- map
value) and resolved into :class:`~pyfmu_wrapper.physics.params.TMDParams`, blaming the key (and line)
that set a refused value."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from ..inputs.reader import Reader, key_path, line_of
from ..physics.params import CASES, InerterModel, ParameterError, TMDParams, field_names

if TYPE_CHECKING:
    from ..inputs.yamlio import MarkedDict

TMD_FIELDS = tuple(field_names(TMDParams))
#: keys of a tmd: block that attach the TMD to a frame's storeys, not TMD parameters (.framespec reads them)
ATTACH_KEYS = ("storey", "inerter_to")
TMD_KEYS = ("case", "inertance_ratio") + TMD_FIELDS + ATTACH_KEYS


class TMDSpec:
    """A TMD block merged over its parent (scenario tmd <- study tmd <- curve tmd <- map value),
    remembering for every key where it was set (key path, line)."""

    def __init__(
        self,
        values: Mapping[str, Any] | None = None,
        origin: Mapping[str, tuple[str, int | None]] | None = None,
    ) -> None:
        self.values: dict[str, Any] = dict(values or {})
        self.origin: dict[str, tuple[str, int | None]] = dict(origin or {})

    def over(self, rd: Reader, node: MarkedDict, path: str, line: int | None) -> TMDSpec:
        rd.mapping(node, path, line, optional=TMD_KEYS)
        new = TMDSpec(self.values, self.origin)
        # a new case / ratio / explicit inertia split replaces the inherited one
        if "case" in node or "inertance_ratio" in node:
            for k in ("mass", "inertance", "case", "inertance_ratio"):
                new.values.pop(k, None)
            if "inerter" not in node and str(new.values.get("inerter", "")).lower() == "none":
                new.values.pop("inerter")  # a paper case has an inerter: back to the default, ideal
        if "mass" in node or "inertance" in node:
            new.values.pop("inertance_ratio", None)
        for key, v in node.items():
            p, ln = key_path(path, key), line_of(node, key)
            new.set(rd, key, v, p, ln)
        return new

    def set(self, rd: Reader, key: str, v: float | str | int, p: str, line: int | None) -> None:
        if key == "case":
            if isinstance(v, bool) or v not in CASES:
                rd.fail(p, line, f"must be one of {sorted(CASES)} (the paper's Cases)", v)
        elif key == "inerter":
            if not isinstance(v, str) or v.upper() not in InerterModel.__members__:
                rd.fail(p, line, f"must be one of {[m.name.lower() for m in InerterModel]}", v)
        elif key == "inertance_ratio":
            rd.check_number(v, p, line, minimum=0.0, maximum=1.0)
        else:
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                rd.fail(p, line, "must be a number", v)
        self.values[key] = v
        self.origin[key] = (p, line)

    def build(self, rd: Reader, path: str, line: int | None) -> TMDParams:
        """Resolve into TMDParams: defaults <- case <- explicit fields <- inertance_ratio."""
        v = self.values
        kw: dict[str, Any] = {}
        if "case" in v:
            kw.update(CASES[v["case"]])
        kw.update({k: v[k] for k in TMD_FIELDS if k in v})
        if "inertance_ratio" in v:
            r = float(v["inertance_ratio"])
            total = kw.get("mass", TMDParams.mass) + kw.get("inertance", TMDParams.inertance)
            kw["inertance"] = r * total
            kw["mass"] = total - kw["inertance"]
            if str(kw.get("inerter", "ideal")).lower() in ("none", "ideal"):
                kw["inerter"] = "none" if r == 0.0 else "ideal"  # Iratio = 0: there is no inerter
        try:
            return TMDParams(**kw)
        except ParameterError as exc:
            key = _blamed_key(str(exc), self.origin)
            p, ln = self.origin.get(key, (path, line))
            try:
                TMDParams(**kw, source=rd.source(p, ln))
            except ParameterError as located:
                rd.parameter_error(located, p, ln, v.get(key))
            raise  # pragma: no cover - the same values cannot pass the second time


def _blamed_key(message: str, origin: Mapping[str, Any]) -> str:
    """The scenario key to blame for a ParameterError (its message starts with the field name)."""
    first = message.split()[0] if message else ""
    if first in origin:
        return first
    if first in ("mass", "inertance", "inerter"):
        for key in ("inertance_ratio", "case", "inertance", "mass", "inerter"):
            if key in origin:
                return key
    return first


def detached_tmd(tmd: TMDParams) -> TMDParams:
    """The TMD detached from the base (no links): the base responds alone."""
    return TMDParams(
        mass=tmd.mass if tmd.mass > 0 else 1.0,
        stiffness=0.0,
        damping=0.0,
        friction_force=0.0,
        inertance=0.0,
        inerter=InerterModel.NONE,
        play_gap=0.0,
    )
