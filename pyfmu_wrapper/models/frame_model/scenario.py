"""The ``frame:`` block of a scenario (a multi-storey shear frame as the primary structure, in place of
``base:``), read into :class:`~.params.FrameParams` with located errors (file, line, key path): the frame
unit's own reader (its per-storey lists are more than its declared rows can state)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...physics.params import ParameterError
from .params import MAX_STOREYS, FrameParams

if TYPE_CHECKING:
    from ...inputs.reader import Reader
    from ...inputs.yamlio import MarkedDict

#: keys of a frame: block (mass, stiffness, damping: one number for every storey, or a list, one per storey)
FRAME_REQUIRED = ("storeys", "mass", "stiffness", "damping", "force_amplitude")
FRAME_OPTIONAL = ("force_storey",)


def read_frame(rd: Reader, node: MarkedDict, line: int | None) -> FrameParams:
    """The frame: block as FrameParams (the TMD on the top storey, its inerter to the same storey)."""
    from ...inputs.reader import key_path, line_of  # here: an FMU, which imports the unit, reads no scenario

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
