"""Parameters of the base oscillator with a plain linear TMD: the declared rows (names, units, ranges,
docs) and the structure class.

The main mass M [kg] stands on a spring K [N/m] and a viscous damper C [N s/m] to the ground, under
F cos(w t) [N]; the absorber, a mass m [kg], hangs on it by a spring k [N/m] and a viscous damper
c [N s/m]. No inerter, no friction, no play: the model is linear. An absorber with k = c = 0 is
detached (the main mass responds alone: the "no TMD" curve).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from ...physics.params import check_structure
from ...physics.registry import Parameter, declare, structure_row

#: the subsystem (and the scenario block, the model's name) the parameters are declared under
SUBSYSTEM = "linear_tmd"


#: the fields in the order of the LinearTMD FMU's value references 0, 1, ... (fmus/variables.py)
_FMU_ORDER = (
    "mass",
    "stiffness",
    "damping",
    "force_amplitude",
    "absorber_mass",
    "absorber_stiffness",
    "absorber_damping",
)


def _row(name: str, symbol: str, unit: str, default: float, minimum: float | None, strict: bool, doc: str) -> Parameter:
    """A declared row (its FMU parameter the LinearTMD FMU's, fmus/variables.py; its Modelica one LinearTMD.mo's)."""
    return structure_row(SUBSYSTEM, name, symbol, unit, default, minimum, strict, doc, _FMU_ORDER.index(name))


#: the model's declared parameters, in the order of :class:`LinearTMDParams`'s fields
PARAMETERS: tuple[Parameter, ...] = declare(
    SUBSYSTEM,
    (
        _row("mass", "M", "kg", 10.0, 0.0, True, "main mass"),
        _row("stiffness", "K", "N/m", 4.0e3, 0.0, True, "main spring, mass to ground"),
        _row("damping", "C", "N.s/m", 0.0, 0.0, False, "main viscous damper, mass to ground"),
        _row(
            "force_amplitude", "F", "N", 10.0, None, False, "amplitude F of the excitation F cos(w t) on the main mass"
        ),
        _row("absorber_mass", "m", "kg", 0.5, 0.0, True, "absorber (TMD) mass"),
        _row("absorber_stiffness", "k", "N/m", 190.0, 0.0, False, "absorber spring, absorber to main mass"),
        _row("absorber_damping", "c", "N.s/m", 2.0, 0.0, False, "absorber viscous damper, absorber to main mass"),
    ),
)


@dataclass(frozen=True)
class LinearTMDParams:
    """The main oscillator with its plain linear TMD (module doc). Validated at construction against
    the declared rows (:class:`ParameterError` naming the field, its value and ``source``)."""

    mass: float = 10.0
    stiffness: float = 4.0e3
    damping: float = 0.0
    force_amplitude: float = 10.0
    absorber_mass: float = 0.5
    absorber_stiffness: float = 190.0
    absorber_damping: float = 2.0
    source: str | None = None

    #: what the reported amplitude max |z[0]| is the displacement of (plots' y-label, summary.md)
    response_body = "the main mass"

    def __post_init__(self) -> None:
        check_structure(self, PARAMETERS, self.source)

    @property
    def natural_frequency(self) -> float:
        """max(sqrt(K / M), sqrt(k / m)) [rad/s]: the fastest own scale of the two masses."""
        return max(math.sqrt(self.stiffness / self.mass), math.sqrt(self.absorber_stiffness / self.absorber_mass))

    @property
    def mass_ratio(self) -> float:
        """mu = m / M."""
        return self.absorber_mass / self.mass

    @property
    def detached(self) -> bool:
        """The absorber has no link to the main mass (k = c = 0)."""
        return self.absorber_stiffness == 0.0 and self.absorber_damping == 0.0

    @classmethod
    def den_hartog(cls, mu: float, **kw: Any) -> LinearTMDParams:
        """The absorber of mass ratio mu tuned by Den Hartog for an undamped main mass: frequency
        ratio f = 1 / (1 + mu), damping ratio sqrt(3 mu / (8 (1 + mu)^3)) (the other fields from kw
        or the defaults)."""
        base: dict[str, Any] = {f.name: f.default for f in fields(cls) if f.name != "source"} | kw
        M, K = float(base["mass"]), float(base["stiffness"])
        m = mu * M
        wa = math.sqrt(K / M) / (1.0 + mu)
        zeta = math.sqrt(3.0 * mu / (8.0 * (1.0 + mu) ** 3))
        base.update(absorber_mass=m, absorber_stiffness=m * wa**2, absorber_damping=2.0 * zeta * m * wa)
        return cls(**base)
