"""The TMD's attachment keys of a scenario (``storey``, ``inerter_to`` in a ``tmd:`` block), read onto a
:class:`~pyfmu_wrapper.models.frame_model.FrameParams` with located errors (file, line, key path); the
``frame:`` block itself is the frame unit's own reader (:mod:`pyfmu_wrapper.models.frame_model.scenario`)."""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

from ..inputs.reader import Reader
from ..models.frame_model import FrameParams
from .tmdspec import ATTACH_KEYS, TMDSpec

if TYPE_CHECKING:
    pass


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
