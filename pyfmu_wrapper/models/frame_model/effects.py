"""The frame unit's effect vocabulary (:mod:`pyfmu_wrapper.physics.effects`): what ``diagnose`` can
name on a shear frame with its TMD-inerter / TMDI, declared once here (the names and element strings
are the contract the frame diagnosis and the frame benchmark share, docs/diagnose-frame.md).

Per-storey effects (``per="storey"``) are declared once and instantiated at every storey
(element ``storey i``, 1 = the lowest); the channel gain at every recorded channel (``channel
x3dd``). Their parameters change the frame's declared per-storey rows (``frame.mass`` of storey i:
the diagnosis indexes the storey). The TMD's effects and the force channel's gain are the ones every
structure carrying the TMD-inerter composes (:mod:`pyfmu_wrapper.physics.tmd_effects`, declared once);
the frame adds a response channel's gain.
"""

from __future__ import annotations

from ...physics.effects import SYSTEM, Effect, EffectParam, Vocabulary, registry_param
from ...physics.tmd_effects import FORCE_ERROR, TMD
from .params import PARAMETERS  # noqa: F401 -- declares the frame rows the parameters name

EFFECTS = (
    Effect(
        "storey_mass",
        "storey mass off the nominal",
        "storey {}",
        (registry_param("frame", "mass", "delta_mass"),),
        signed=True,
        per="storey",
    ),
    Effect(
        "storey_stiffness",
        "inter-storey stiffness off the nominal",
        "storey {}",
        (registry_param("frame", "stiffness", "delta_stiffness"),),
        signed=True,
        per="storey",
    ),
    Effect(
        "storey_damping",
        "inter-storey damping off the nominal",
        "storey {}",
        (registry_param("frame", "damping", "delta_damping"),),
        signed=True,
        per="storey",
    ),
    TMD["tmd_mass"],
    TMD["tmd_stiffness"],
    TMD["viscous"],
    TMD["inertance"],
    TMD["friction"],
    TMD["play"],
    FORCE_ERROR,
    Effect(
        "channel_gain",
        "gain error of one response channel",
        "channel {}",
        (EffectParam("gain", "1"),),
        signed=True,
        per="channel",
    ),
)
VOCABULARY = Vocabulary(EFFECTS)
#: the effects the linear frame diagnosis fits (dry friction is tried apart, when nothing linear
#: explains; play is not fitted for frames yet)
LINEAR = VOCABULARY.select(
    (
        "storey_mass",
        "storey_stiffness",
        "storey_damping",
        "tmd_mass",
        "tmd_stiffness",
        "viscous",
        "inertance",
        "force_error",
        "channel_gain",
    )
)
__all__ = ["EFFECTS", "LINEAR", "SYSTEM", "VOCABULARY"]
