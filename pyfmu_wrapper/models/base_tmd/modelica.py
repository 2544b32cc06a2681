"""The paper's model's part of the Modelica package: its subpackage ``Systems`` (``Systems.mo``
beside this module: the base oscillator, the TMD-inerter subsystems and the coupled systems per
inerter model), the Modelica modifiers of a :class:`~pyfmu_wrapper.physics.params.BaseParams`, the
paper's cases (Cases 1-3 of each study of Sects. 3-7, the Iratio map's endpoints, and one cubic-spring
check case) and the Modelica state variables' places in the state [x, xd, y, yd, d, dd]."""

from __future__ import annotations

from pathlib import Path

from ...physics import registry
from ...physics.modelica_source import ModelicaCase, ModelicaSource
from ...physics.params import (
    PAPER_C_OPT,
    PAPER_DF_OPT,
    PAPER_FULL_C_DF,
    PAPER_GAP,
    BaseParams,
    InerterModel,
    TMDParams,
    paper_case,
)

#: the coupled system class of each inerter model (in ``Systems.mo``)
SYSTEM_CLASS = {
    InerterModel.NONE: "CoupledNoInerter",
    InerterModel.IDEAL: "CoupledIdealInerter",
    InerterModel.PLAY: "CoupledPlayInerter",
}
#: the hardening cubic TMD spring k3 [N/m^3] of the check case that is not in the paper (Case 1, c = 10)
CUBIC_K3 = 1.0e6


def modifiers(base: BaseParams) -> dict[str, str]:
    """The base's declared fields under their Modelica names (M, K, C, F), as exact literals."""
    return {p.modelica_name: repr(float(getattr(base, p.name))) for p in registry.fields("base") if p.modelica_name}


def cases() -> tuple[ModelicaCase, ...]:
    """Every case of the paper, in the order they are written to ``Cases.mo``."""
    base = BaseParams()
    out = [
        ModelicaCase(
            "IratioMap0",
            "Iratio map endpoint Iratio = 0: classical TMD, m = 10, no inerter",
            base,
            TMDParams(mass=10.0, inertance=0.0, inerter=InerterModel.NONE),
        ),
        ModelicaCase(
            "IratioMap1",
            "Iratio map endpoint Iratio = 1: massless TMD node, ideal inerter I = 10",
            base,
            TMDParams(mass=0.0, inertance=10.0, inerter=InerterModel.IDEAL),
        ),
    ]
    studies = (
        ("IdealCase", "Sect. 3, Case {n}: ideal inerter, no damping", lambda n: paper_case(n)),
        (
            "ViscousCase",
            "Sect. 4, Case {n}: ideal inerter, optimised viscous damping c",
            lambda n: paper_case(n, damping=PAPER_C_OPT[n]),
        ),
        (
            "DryFrictionCase",
            "Sect. 5, Case {n}: ideal inerter, optimised dry friction df",
            lambda n: paper_case(n, friction_force=PAPER_DF_OPT[n]),
        ),
        (
            "PlayCase",
            "Sect. 6, Case {n}: inerter with play, standard gap eps",
            lambda n: paper_case(n, inerter=InerterModel.PLAY, play_gap=PAPER_GAP),
        ),
        (
            "FullCase",
            "Sect. 7, Case {n}: full model (viscous damping, dry friction, play)",
            lambda n: paper_case(
                n,
                damping=PAPER_FULL_C_DF[n][0],
                friction_force=PAPER_FULL_C_DF[n][1],
                inerter=InerterModel.PLAY,
                play_gap=PAPER_GAP,
            ),
        ),
    )
    for name, text, tmd in studies:
        out += [ModelicaCase(f"{name}{n}", text.format(n=n), base, tmd(n)) for n in (1, 2, 3)]
    out.append(
        ModelicaCase(
            "CubicSpringCase1",
            "Not in the paper: Case 1, c = 10, hardening cubic TMD spring k3",
            base,
            paper_case(1, damping=10.0, cubic_stiffness=CUBIC_K3),
        )
    )
    return tuple(out)


MODELICA = ModelicaSource(
    source=Path(__file__).with_name("Systems.mo"),
    system=lambda tmd: f"Systems.{SYSTEM_CLASS[tmd.inerter]}",
    modifiers=modifiers,
    cases=cases,
    states=lambda base: {"x": 0, "xd": 1, "y": 2, "yd": 3, "d": 4, "dd": 5},
)
