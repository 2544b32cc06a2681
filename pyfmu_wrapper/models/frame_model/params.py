"""Parameters of the shear frame: the declared rows (names, units, ranges, docs) and the class.

A frame of n storeys (1 = the lowest): storey i has mass ``masses[i-1]`` [kg] and is joined to the
storey below (storey 0 = the ground) by a spring ``stiffnesses[i-1]`` [N/m] and a viscous damper
``dampings[i-1]`` [N s/m]; F cos(w t) [N] acts on storey ``force_storey``. The TMD (the paper's
:class:`~pyfmu_wrapper.physics.params.TMDParams`) hangs on storey ``tmd_storey`` by its spring,
damper and friction; its inerter's second terminal is ``inerter_to``: the same storey (the paper's
TMD-inerter), another storey, or 0, the ground (the TMDI).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from ...physics.params import ParameterError
from ...physics.registry import Parameter, declare

#: most storeys of a frame
MAX_STOREYS = 20


#: the ShearFrame FMU's variable (value reference) of each parameter (fmi/frame_variables.py)
_FMU = {
    "storeys": ("storeys", 0),
    "mass": ("m1..m20", 200),
    "stiffness": ("k1..k20", 300),
    "damping": ("c1..c20", 400),
    "force_amplitude": ("F", 1),
    "force_storey": ("force_storey", 3),
    "tmd_storey": ("tmd_storey", 4),
    "inerter_to": ("inerter_to", 5),
}


def _row(name: str, symbol: str, unit: str, default: float, minimum: float | None, strict: bool, doc: str) -> Parameter:
    return Parameter(
        name=name,
        symbol=symbol,
        subsystem="frame",
        unit=unit,
        default=default,
        minimum=minimum,
        strict=strict,
        description=doc,
        fmu_name=_FMU[name][0],
        fmu_vr=_FMU[name][1],
        modelica_name=None,
        modelica_type=None,
        mappable=False,
    )


#: the frame's declared parameters (per storey: a number for every storey, or one per storey)
PARAMETERS: tuple[Parameter, ...] = declare(
    "frame",
    (
        _row("storeys", "n", "1", 1, 1, False, f"number of storeys, 1 to {MAX_STOREYS}"),
        _row("mass", "M_i", "kg", 100.0, 0.0, True, "storey masses (per storey)"),
        _row("stiffness", "K_i", "N/m", 4.0e4, 0.0, True, "inter-storey stiffnesses, storey i to i-1 (per storey)"),
        _row(
            "damping", "C_i", "N.s/m", 100.0, 0.0, False, "inter-storey viscous dampers, storey i to i-1 (per storey)"
        ),
        _row("force_amplitude", "F", "N", 200.0, None, False, "amplitude F of the excitation F cos(w t)"),
        _row("force_storey", "-", "1", 0, 0, False, "the storey the force acts on (0: the top)"),
        _row("tmd_storey", "-", "1", 0, 0, False, "the storey the TMD hangs on (0: the top)"),
        _row(
            "inerter_to",
            "-",
            "1",
            -1,
            -1,
            False,
            "the inerter's second terminal: a storey, 0 the ground, -1 the TMD's storey",
        ),
    ),
)


@dataclass(frozen=True)
class FrameParams:
    """A shear frame with the attachment of its TMD (module doc); storeys are numbered 1..n.

    Validated at construction (:class:`ParameterError` naming the field and value); ``force_storey``
    and ``tmd_storey`` 0 mean the top storey, ``inerter_to`` -1 the TMD's own storey.
    """

    masses: tuple[float, ...]
    stiffnesses: tuple[float, ...]
    dampings: tuple[float, ...]
    force_amplitude: float = 200.0
    force_storey: int = 0
    tmd_storey: int = 0
    inerter_to: int = -1
    source: str | None = None

    def __post_init__(self) -> None:
        where = f" (from {self.source})" if self.source else ""
        n = len(self.masses)
        if not 1 <= n <= MAX_STOREYS:
            raise ParameterError(f"storeys must be 1 to {MAX_STOREYS}, got {n}{where}")
        for name, vals, strict in (("mass", self.masses, True), ("stiffness", self.stiffnesses, True)):
            if len(vals) != n:
                raise ParameterError(f"{name} must have one value per storey ({n}), got {len(vals)}{where}")
            for i, v in enumerate(vals):
                if not _number(v) or not (v > 0 if strict else v >= 0):
                    raise ParameterError(f"{name} of storey {i + 1} must be a finite number > 0, got {v!r}{where}")
        if len(self.dampings) != n:
            raise ParameterError(f"damping must have one value per storey ({n}), got {len(self.dampings)}{where}")
        for i, v in enumerate(self.dampings):
            if not _number(v) or v < 0:
                raise ParameterError(f"damping of storey {i + 1} must be a finite number >= 0, got {v!r}{where}")
        if not _number(self.force_amplitude):
            raise ParameterError(f"force_amplitude (F) must be a finite number, got {self.force_amplitude!r}{where}")
        for name, lo in (("force_storey", 0), ("tmd_storey", 0), ("inerter_to", -1)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= n:
                raise ParameterError(f"{name} must be an integer storey {lo}..{n}, got {v!r}{where}")
        for name in ("masses", "stiffnesses", "dampings"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
        object.__setattr__(self, "force_amplitude", float(self.force_amplitude))

    @classmethod
    def uniform(cls, n: int, mass: float, stiffness: float, damping: float, **kw: Any) -> FrameParams:
        """n equal storeys."""
        if isinstance(n, bool) or not isinstance(n, int):
            raise ParameterError(f"storeys must be an integer 1 to {MAX_STOREYS}, got {n!r}")
        return cls((mass,) * n, (stiffness,) * n, (damping,) * n, **kw)

    @property
    def n(self) -> int:
        return len(self.masses)

    @property
    def loaded_storey(self) -> int:
        return self.force_storey or self.n

    @property
    def tmd_at(self) -> int:
        return self.tmd_storey or self.n

    @property
    def terminal(self) -> int:
        """The inerter's second terminal: a storey 1..n, or 0 for the ground."""
        return self.tmd_at if self.inerter_to < 0 else self.inerter_to

    #: what the reported amplitude max |z[0]| is the displacement of (plots' y-label, summary.md)
    response_body = "the top storey"

    def attachment(self) -> dict[str, Any]:
        """Where the TMD hangs and where its inerter's second terminal is, as a scenario's tmd: block
        writes them (``storey`` 1..n, ``inerter_to`` a storey or 0 for the ground), with the words."""
        to = self.terminal
        where = "the ground" if to == 0 else ("its own storey" if to == self.tmd_at else f"storey {to}")
        return dict(storey=self.tmd_at, inerter_to=to, text=f"storey {self.tmd_at}, inerter to {where}")

    def resolved(self) -> FrameParams:
        """The same frame with the defaults spelled out (0 = the top, -1 = the TMD's own storey):
        values a scenario's keys accept, for the summary."""
        return replace(self, force_storey=self.loaded_storey, tmd_storey=self.tmd_at, inerter_to=self.terminal)

    @property
    def stiffness(self) -> float:
        """1 / sum(1 / K_i) [N/m]: the top's static deflection under F is at most F over it."""
        if self.n == 1:
            return self.stiffnesses[0]
        return 1.0 / sum(1.0 / k for k in self.stiffnesses)

    @property
    def natural_frequency(self) -> float:
        """max sqrt(K_i / M_i) [rad/s], the fastest storey's own scale (sqrt(K/M) for one storey)."""
        return max(math.sqrt(k / m) for k, m in zip(self.stiffnesses, self.masses))


def _number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
