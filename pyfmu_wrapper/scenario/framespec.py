"""The ``frame:`` block of a scenario (a multi-storey shear frame as the primary structure, in place
of ``base:``) and the TMD's attachment keys (``storey``, ``inerter_to`` in a ``tmd:`` block), read into
:class:`~pyfmu_wrapper.models.frame_model.FrameParams` with located errors (file, line, key path)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ..models.frame_model import FrameParams
from ..models.frame_model.params import MAX_STOREYS
from ..physics.params import ParameterError
from .reader import Reader, key_path, line_of
from .tmdspec import ATTACH_KEYS, TMDSpec

if TYPE_CHECKING:
    from .yamlio import MarkedDict

#: keys of a frame: block (mass, stiffness, damping: one number for every storey, or a list, one per storey)
FRAME_REQUIRED = ("storeys", "mass", "stiffness", "damping", "force_amplitude")
FRAME_OPTIONAL = ("force_storey",)


def read_frame(rd: Reader, node: MarkedDict, line: int | None) -> FrameParams:
    """The frame: block as FrameParams (the TMD on the top storey, its inerter to the same storey)."""
    rd.mapping(node, "frame", line, required=FRAME_REQUIRED, optional=FRAME_OPTIONAL)
    n = rd.integer(node, "storeys", "frame", minimum=1, maximum=MAX_STOREYS)
    per: dict[str, tuple[float, ...]] = {}
    for key in ("mass", "stiffness", "damping"):
        v, p, ln = node[key], key_path("frame", key), line_of(node, key)
        positive = key != "damping"
        if isinstance(v, list):
            if len(v) != n:
                rd.fail(p, ln, f"must be one number, or a list of one per storey ({n}, storey 1 first)", v)
            per[key] = tuple(
                rd.check_number(x, key_path(p, i), line_of(v, i) or ln, minimum=0.0, strict=positive)
                for i, x in enumerate(v)
            )
        else:
            per[key] = (rd.check_number(v, p, ln, minimum=0.0, strict=positive),) * n
    force = rd.number(node, "force_amplitude", "frame")
    storey = rd.integer(node, "force_storey", "frame", minimum=1, maximum=n, default=n)
    try:
        return FrameParams(
            per["mass"], per["stiffness"], per["damping"], force_amplitude=force, force_storey=storey, tmd_storey=n
        )
    except ParameterError as exc:  # pragma: no cover - every value was checked above
        rd.fail("frame", line, str(exc), show_value=False)


def attached(rd: Reader, frame: Any, spec: TMDSpec, path: str, line: int | None) -> Any:
    """The structure with the attachment a TMD block set (``storey``, ``inerter_to``); a base
    scenario refuses the keys (they need a frame: block)."""
    keys = [k for k in ATTACH_KEYS if k in spec.values]
    if not keys:
        return frame
    if not isinstance(frame, FrameParams):
        p, ln = spec.origin[keys[0]]
        rd.fail(
            p, ln, "attaches the TMD to a storey of a frame: the scenario needs a frame: block", spec.values[keys[0]]
        )
    n = frame.n
    storey = spec.values.get("storey", frame.tmd_at)
    to = spec.values.get("inerter_to", -1)
    for key, v, lo in (("storey", storey, 1), ("inerter_to", to, 0)):
        if key in spec.values and (isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= n):
            p, ln = spec.origin[key]
            ground = "" if lo == 1 else ", or 0 for the ground"
            rd.fail(p, ln, f"must be a storey of the {n}-storey frame, 1..{n}{ground}", v)
    return replace(frame, tmd_storey=storey, inerter_to=to)
