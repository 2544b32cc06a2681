"""Parameters of the base oscillator with a pendulum TMD: the declared rows (names, units, ranges, docs)
and the structure class.

The main mass M [kg] stands on a spring K [N/m] and a viscous damper C [N s/m] to the ground, under
F cos(w t) [N]; the absorber is a mass m [kg] on a massless rod of length L [m] pivoted on the main mass,
with a viscous pivot damper c_p [N m s/rad], swinging under gravity g. The model is nonlinear in its own
way (the angle enters through sin and cos); about rest it is the linear TMD of mass m, stiffness m g / L
and damping c_p / L^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...physics.params import check_structure
from ...physics.registry import Parameter, declare, structure_row

#: the subsystem (and the scenario block, the model's name) the parameters are declared under
SUBSYSTEM = "pendulum_tmd"

#: the acceleration of gravity [m/s^2]
GRAVITY = 9.81

#: the FMU parameter each row is set on (name, value reference): the pendulum's own rows on the PendulumTMD
#: FMU's (``fmus/variables.py``), the main mass's on the paper's BaseOscillator FMU (declared by ``base_tmd``),
#: which the co-simulation couples to it (``cosim.py``)
FMU_VARIABLES = {
    "mass": ("BaseOscillator.M", 0),
    "stiffness": ("BaseOscillator.K", 1),
    "damping": ("BaseOscillator.C", 2),
    "force_amplitude": ("BaseOscillator.F", 3),
    "pendulum_mass": ("m", 0),
    "length": ("L", 1),
    "pivot_damping": ("c_p", 2),
}
#: the rows of the PendulumTMD FMU's own parameters (the others are the BaseOscillator's)
OWN = ("pendulum_mass", "length", "pivot_damping")


def _row(name: str, symbol: str, unit: str, default: float, minimum: float | None, strict: bool, doc: str) -> Parameter:
    """A declared row (its FMU parameter :data:`FMU_VARIABLES`'s; its Modelica one PendulumTMD.mo's)."""
    fmu_name, vr = FMU_VARIABLES[name]
    return structure_row(SUBSYSTEM, name, symbol, unit, default, minimum, strict, doc, vr, fmu_name)


#: the model's declared parameters, in the order of :class:`PendulumTMDParams`'s fields (the defaults:
#: scenarios/pendulum_tmd.yaml's, at its large force)
PARAMETERS: tuple[Parameter, ...] = declare(
    SUBSYSTEM,
    (
        _row("mass", "M", "kg", 100.0, 0.0, True, "main mass"),
        _row("stiffness", "K", "N/m", 4.0e4, 0.0, True, "main spring, mass to ground"),
        _row("damping", "C", "N.s/m", 100.0, 0.0, False, "main viscous damper, mass to ground"),
        _row(
            "force_amplitude", "F", "N", 60.0, None, False, "amplitude F of the excitation F cos(w t) on the main mass"
        ),
        _row("pendulum_mass", "m", "kg", 5.0, 0.0, True, "pendulum bob mass (the absorber)"),
        _row("length", "L", "m", 0.0270388, 0.0, True, "pendulum rod length, pivot to bob (massless rod)"),
        _row("pivot_damping", "c_p", "N.m.s/rad", 0.0177228, 0.0, False, "viscous damper of the pivot"),
    ),
)


@dataclass(frozen=True)
class PendulumTMDParams:
    """The main oscillator with its pendulum TMD (module doc). Validated at construction against the
    declared rows (:class:`ParameterError` naming the field, its value and ``source``)."""

    mass: float = 100.0
    stiffness: float = 4.0e4
    damping: float = 100.0
    force_amplitude: float = 60.0
    pendulum_mass: float = 5.0
    length: float = 0.0270388
    pivot_damping: float = 0.0177228
    source: str | None = None

    def __post_init__(self) -> None:
        check_structure(self, PARAMETERS, self.source)

    @property
    def pendulum_frequency(self) -> float:
        """sqrt(g / L) [rad/s]: the pendulum's small-swing frequency on a fixed pivot."""
        return math.sqrt(GRAVITY / self.length)

    @property
    def natural_frequency(self) -> float:
        """max(sqrt(K / M), sqrt(g / L)) [rad/s]: the fastest own scale of the two bodies."""
        return max(math.sqrt(self.stiffness / self.mass), self.pendulum_frequency)
