"""The linear TMD model's part of the Modelica package: its subpackage (``LinearTMD.mo`` beside this
module: ``BaseWithTMD`` on the package's masses, springs and dampers), the Modelica modifiers of a
:class:`~.params.LinearTMDParams` (its declared rows' Modelica names), its case (the scenario's Den
Hartog tuning) and the Modelica state variables' places in the unit's state."""

from __future__ import annotations

from pathlib import Path

from ...physics.modelica_source import ModelicaCase, ModelicaSource
from ...physics.params import TMDParams
from .params import PARAMETERS, LinearTMDParams


def modifiers(s: LinearTMDParams) -> dict[str, str]:
    """Every declared parameter under its Modelica name."""
    return {p.modelica_name: repr(float(getattr(s, p.name))) for p in PARAMETERS if p.modelica_name}


def cases() -> tuple[ModelicaCase, ...]:
    """The Den Hartog tuning of scenarios/linear_tmd.yaml (mu = 0.05, main damper C = 2 N s/m)."""
    s = LinearTMDParams.den_hartog(0.05, mass=10.0, stiffness=4000.0, damping=2.0, force_amplitude=10.0)
    return (
        ModelicaCase("LinearTMDDenHartog", "main mass with a Den Hartog-tuned linear TMD, mu = 0.05", s, TMDParams()),
    )


MODELICA = ModelicaSource(
    source=Path(__file__).with_name("LinearTMD.mo"),
    system=lambda tmd: "LinearTMD.BaseWithTMD",
    modifiers=modifiers,
    cases=cases,
    states=lambda s: {"x": 0, "xd": 1, "y": 2, "yd": 3},
)
