"""The pendulum TMD model's part of the Modelica package: its subpackage (``PendulumTMD.mo`` beside this
module: ``BaseWithPendulum``, the two equations of motion written directly), the Modelica modifiers of a
:class:`~.params.PendulumTMDParams` (its declared rows' Modelica names), its case (the scenario's pendulum
at its large force) and the Modelica state variables' places in the unit's state."""

from __future__ import annotations

from pathlib import Path

from ...physics.modelica_source import ModelicaCase, ModelicaSource
from ...physics.params import TMDParams
from .params import PARAMETERS, PendulumTMDParams


def modifiers(s: PendulumTMDParams) -> dict[str, str]:
    """Every declared parameter under its Modelica name."""
    return {p.modelica_name: repr(float(getattr(s, p.name))) for p in PARAMETERS if p.modelica_name}


def cases() -> tuple[ModelicaCase, ...]:
    """The pendulum of scenarios/pendulum_tmd.yaml at F = 60 N (swings of ~0.5 rad within the 2 s run)."""
    s = PendulumTMDParams(force_amplitude=60.0)
    return (ModelicaCase("PendulumTMDF60", "main mass with a pendulum TMD, F = 60 N", s, TMDParams()),)


def system(tmd: TMDParams) -> str:
    """The one class every case extends (the model takes no paper TMD)."""
    return "PendulumTMD.BaseWithPendulum"


def states(s: PendulumTMDParams) -> dict[str, int]:
    """The Modelica state variables' places in the unit's state [x, xd, th, thd]."""
    return {"x": 0, "xd": 1, "th": 2, "thd": 3}


MODELICA = ModelicaSource(
    source=Path(__file__).with_name("PendulumTMD.mo"),
    system=system,
    modifiers=modifiers,
    cases=cases,
    states=states,
)
