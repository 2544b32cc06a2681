"""The frame unit's effect vocabulary (:mod:`pyfmu_wrapper.physics.effects`): what ``diagnose`` can
name on a shear frame with its TMD-inerter / TMDI, declared once here (the names and element strings
are the contract the frame diagnosis and the frame benchmark share, /work/notes/frame_contract.md).

Per-storey effects (``per="storey"``) are declared once and instantiated at every storey
(element ``storey i``, 1 = the lowest); the channel gain at every recorded channel (``channel
x3dd``). Their parameters change the frame's declared per-storey rows (``frame.mass`` of storey i:
the diagnosis indexes the storey) or the TMD's (``tmd.mass`` ...). The measurement effects act on a
channel: the force's gain (measured = (1 + g) true, indistinguishable in a linear model from one
common gain of every response channel) and a response channel's gain.
"""

from __future__ import annotations

import math

from ...physics.effects import SYSTEM, Effect, EffectParam, Vocabulary, registry_param
from .params import PARAMETERS  # noqa: F401 -- declares the frame rows the parameters name

POSITIVE = (0.0, math.inf)

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
    Effect("tmd_mass", "TMD mass m off the nominal", "tmd", (registry_param("tmd", "mass", "delta_mass"),), True),
    Effect(
        "tmd_stiffness",
        "TMD spring stiffness k off the nominal",
        "tmd",
        (registry_param("tmd", "stiffness", "delta_stiffness"),),
        True,
    ),
    Effect(
        "viscous",
        "TMD link damping c off the nominal",
        "tmd link",
        (registry_param("tmd", "damping", "delta_damping"),),
        True,
    ),
    Effect(
        "inertance",
        "inertance I off the nominal (m unchanged)",
        "tmd link",
        (registry_param("tmd", "inertance", "delta_inertance"),),
        True,
    ),
    Effect(
        "friction",
        "dry friction in the TMD link",
        "tmd link",
        (registry_param("tmd", "friction_force", bounds=POSITIVE, replaces=True),),
    ),
    Effect(
        "play",
        "play in the inerter gear",
        "tmd link",
        (registry_param("tmd", "play_gap", linear=False, bounds=POSITIVE, replaces=True),),
    ),
    Effect(
        "force_error",
        "force-channel gain error (= a common gain of every response channel)",
        "force",
        (EffectParam("force_gain", "1"),),
        signed=True,
    ),
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
#: the effects the linear frame diagnosis fits (friction and play: not yet for frames)
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
