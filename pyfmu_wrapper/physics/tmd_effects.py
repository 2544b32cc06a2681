"""The TMD-inerter's effects (:mod:`pyfmu_wrapper.physics.effects`), declared once for every structure
that carries it (:mod:`pyfmu_wrapper.physics.tmd`): the pair (``models/base_tmd``) and the frame
(``models/frame_model``) compose their vocabularies from these, so an effect of the TMD has one name, one
element, one set of parameters and one label whatever it is mounted on.

Elements: ``tmd`` is the absorber's mass; ``tmd link`` is everything between the absorber and the
structure (the spring k, the viscous damper c, the dry friction, the inerter I and its gear);
``force`` is the force channel. The mechanisms are the kernels' own terms
(:mod:`pyfmu_wrapper.physics.kernels`): dry friction ``df (2/pi) atan(s v)`` has two parameters, the
force df and the regularisation slope s (the kernel cannot be evaluated without s; a fit that does
not resolve it holds it on a grid and reports it beside df); play is the gear's half gap eps of the
inerter chain; the cubic spring term k3.
"""

from __future__ import annotations

import math

from .effects import LINK, SYSTEM, Effect, EffectParam, registry_param

BOTH = (SYSTEM, LINK)
POSITIVE = (0.0, math.inf)

#: the TMD-inerter's effects by name
TMD: dict[str, Effect] = {
    e.name: e
    for e in (
        Effect(
            "viscous",
            "extra viscous damping",
            "tmd link",
            (registry_param("tmd", "damping", "delta_damping"),),
            levels=BOTH,
        ),
        Effect(
            "friction",
            "dry friction in the TMD link",
            "tmd link",
            (
                registry_param("tmd", "friction_force", bounds=POSITIVE, replaces=True),
                registry_param("tmd", "friction_slope", linear=False, bounds=POSITIVE, replaces=True),
            ),
            levels=BOTH,
        ),
        Effect(
            "play",
            "play in the inerter gear",
            "tmd link",
            (registry_param("tmd", "play_gap", linear=False, bounds=POSITIVE, replaces=True),),
            levels=BOTH,
        ),
        Effect(
            "mass_split",
            "different split of m and I (m + I fixed)",
            "tmd",
            (registry_param("tmd", "inertance", "delta_inertance", also=(("tmd.mass", -1.0),)),),
            signed=True,
            levels=BOTH,
        ),
        Effect(
            "cubic",
            "cubic term in the TMD spring",
            "tmd link",
            (registry_param("tmd", "cubic_stiffness"),),
            levels=BOTH,
        ),
        Effect(
            "tmd_stiffness",
            "TMD spring stiffness k off the nominal",
            "tmd link",
            (registry_param("tmd", "stiffness", "delta_stiffness"),),
            signed=True,
        ),
        Effect(
            "tmd_mass",
            "TMD mass m off the nominal",
            "tmd",
            (registry_param("tmd", "mass", "delta_mass"),),
            signed=True,
        ),
        Effect(
            "inertance",
            "inertance I off the nominal (m unchanged)",
            "tmd link",
            (registry_param("tmd", "inertance", "delta_inertance"),),
            signed=True,
        ),
    )
}

#: the force channel's gain error: measured = (1 + a) x true (in a linear model the same as one
#: common gain of every response channel)
FORCE_ERROR = Effect(
    "force_error",
    "forcing-amplitude error",
    "force",
    (EffectParam("force_gain_error", "1"),),
    signed=True,
    levels=BOTH,
)

__all__ = ["BOTH", "FORCE_ERROR", "POSITIVE", "TMD"]
