"""The shear frame's part of the Modelica package: its classes (``Frames.mo`` beside this module,
written into ``modelica/TMDInerter/`` by :mod:`pyfmu_wrapper.generate.modelica`:
``ShearFrame``, and the frame with the paper's TMD on storey ``tmd_storey`` and its inerter to
``inerter_to``, per inerter model), the Modelica modifiers of a :class:`~.params.FrameParams`, its
cases (the frame scenarios' TMD curves, and one storey = the paper's base oscillator) and the Modelica
state variables' places in the unit's state."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ...physics.modelica_source import ModelicaCase, ModelicaSource
from ...physics.params import BaseParams, InerterModel, TMDParams, paper_case
from .equations import storey_index
from .params import FrameParams

#: the class of each inerter model in Frames.mo
FRAME_CLASS = {
    InerterModel.NONE: "Frames.FrameNoInerter",
    InerterModel.IDEAL: "Frames.FrameIdealInerter",
    InerterModel.PLAY: "Frames.FramePlayInerter",
}


def _real(v: float) -> str:
    return repr(float(v))


def modifiers(frame: FrameParams) -> dict[str, str]:
    """The frame's Modelica parameters: n, the per-storey arrays, F, the loaded storey, the TMD's
    storey and the inerter's second terminal (0: the ground)."""
    return {
        "n": str(frame.n),
        "Ms": "{" + ", ".join(map(_real, frame.masses)) + "}",
        "Ks": "{" + ", ".join(map(_real, frame.stiffnesses)) + "}",
        "Cs": "{" + ", ".join(map(_real, frame.dampings)) + "}",
        "F": _real(frame.force_amplitude),
        "force_storey": str(frame.loaded_storey),
        "tmd_storey": str(frame.tmd_at),
        "inerter_to": str(frame.terminal),
    }


def states(frame: FrameParams) -> dict[str, int]:
    """Modelica variable -> index in the unit's state (:mod:`.equations`)."""
    out = {}
    for i in range(1, frame.n + 1):
        out[f"x[{i}]"] = storey_index(i, frame.n)
        out[f"xd[{i}]"] = storey_index(i, frame.n) + 1
    return out | {"y": 2, "yd": 3, "d": 4, "dd": 5}


def cases() -> tuple[ModelicaCase, ...]:
    """The frame scenarios' TMD curves (scenarios/frame3_tmdi.yaml, frame10_tmd.yaml, frame3_full.yaml;
    tests/test_modelica.py holds the values to the files), the TMDI's inerter to the ground, and one
    storey with the paper's Case 1 (the paper's base oscillator)."""
    frame3 = FrameParams.uniform(3, 100.0, 1.2e5, 100.0, force_amplitude=200.0, force_storey=3, tmd_storey=3)
    tmd3 = TMDParams(mass=10.0, stiffness=3500.0, damping=20.0, inerter=InerterModel.IDEAL, inertance=5.0)
    frame10 = FrameParams.uniform(10, 100.0, 1.8e6, 200.0, force_amplitude=200.0, force_storey=10, tmd_storey=10)
    tmd10 = TMDParams(mass=15.0, stiffness=8000.0, damping=40.0, inerter=InerterModel.IDEAL, inertance=5.0)
    full = TMDParams(
        mass=9.0,
        inertance=1.0,
        stiffness=4000.0,
        damping=10.0,
        friction_force=10.0,
        inerter=InerterModel.PLAY,
        play_gap=1e-4,
        mesh_stiffness=2e7,
        mesh_damping=0.01,
    )
    b = BaseParams()
    one = FrameParams((b.mass,), (b.stiffness,), (b.damping,), force_amplitude=b.force_amplitude)
    return (
        ModelicaCase("Frame3TMDInerter", "frame3_tmdi: 3 storeys, TMD-inerter on storey 3", frame3, tmd3),
        ModelicaCase(
            "Frame3TMDI",
            "frame3_tmdi: 3 storeys, TMD on storey 3, inerter to storey 2 (TMDI)",
            replace(frame3, inerter_to=2),
            tmd3,
        ),
        ModelicaCase(
            "Frame3TMDIGround", "3 storeys, TMD on storey 3, inerter to the ground", replace(frame3, inerter_to=0), tmd3
        ),
        ModelicaCase("Frame10TMDInerter", "frame10_tmd: 10 storeys, TMD-inerter on storey 10", frame10, tmd10),
        ModelicaCase("Frame3Full", "frame3_full: 3 storeys, the paper's full TMD on storey 3", frame3, full),
        ModelicaCase(
            "Frame1Case1",
            "1 storey = the paper's base oscillator, Case 1 with c = 10",
            one,
            paper_case(1, damping=10.0),
        ),
    )


MODELICA = ModelicaSource(
    source=Path(__file__).with_name("Frames.mo"),
    system=lambda tmd: FRAME_CLASS[tmd.inerter],
    modifiers=modifiers,
    cases=cases,
    states=states,
)
