"""The pair's effect vocabulary (:mod:`pyfmu_wrapper.physics.effects`): what ``diagnose`` can name on
the base + TMD-inerter, declared once here and read by every diagnosis path, benchmark and report.

The mechanisms are the kernels' own terms (:mod:`pyfmu_wrapper.physics.kernels`): dry friction
``df (2/pi) atan(s v)`` in the link has two parameters, the force df and the regularisation slope s
(the kernel cannot be evaluated without s; the fits that do not resolve it hold it on a grid and
report it beside df); play is the gear's half gap eps of the inerter chain; the cubic spring k3. The
parameter effects are changes of the unit's declared parameters (base M, K, C; TMD m, k, I), their
units from the registry. The measurement effects act on a channel: the force's gain, the
displacement sensors' offsets (the link rig's displacement bias, seen as the force k b).
"""

from __future__ import annotations

import math

from ...physics.effects import LINK, SYSTEM, Effect, EffectParam, Vocabulary, registry_param

BOTH = (SYSTEM, LINK)
POSITIVE = (0.0, math.inf)

EFFECTS = (
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
            registry_param("tmd", "friction_slope", linear=False, bounds=(0.0, math.inf), replaces=True),
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
        "cubic", "cubic term in the TMD spring", "tmd link", (registry_param("tmd", "cubic_stiffness"),), levels=BOTH
    ),
    Effect(
        "force_error",
        "forcing-amplitude error",
        "force",
        (EffectParam("force_gain_error", "1"),),
        signed=True,
        levels=BOTH,
    ),
    Effect(
        "sensor_offset",
        "displacement-sensor offset",
        "channels x, y",
        (EffectParam("x_offset", "m"), EffectParam("y_offset", "m")),
        signed=True,
    ),
    Effect("base_mass", "base mass M off the nominal", "base", (registry_param("base", "mass", "delta_mass"),), True),
    Effect(
        "base_stiffness",
        "base stiffness K off the nominal",
        "base",
        (registry_param("base", "stiffness", "delta_stiffness"),),
        True,
    ),
    Effect(
        "base_damping",
        "base damping C off the nominal",
        "base",
        (registry_param("base", "damping", "delta_damping"),),
        True,
    ),
    Effect(
        "tmd_stiffness",
        "TMD spring stiffness k off the nominal",
        "tmd link",
        (registry_param("tmd", "stiffness", "delta_stiffness"),),
        True,
    ),
    Effect("tmd_mass", "TMD mass m off the nominal", "tmd", (registry_param("tmd", "mass", "delta_mass"),), True),
    Effect(
        "inertance",
        "inertance I off the nominal (m unchanged)",
        "tmd link",
        (registry_param("tmd", "inertance", "delta_inertance"),),
        True,
    ),
    # the link rig (the TMD link alone on a test machine): a bias of its displacement sensor, fitted as
    # the force k b it adds; dry friction with contact compliance, the rival of play in front of friction
    Effect(
        "bias",
        "sensor bias (constant offset)",
        "channel d",
        (EffectParam("force_offset", "N"),),
        signed=True,
        levels=(LINK,),
    ),
    Effect(
        "compliant_friction",
        "dry friction with contact compliance (no play)",
        "tmd link",
        (
            registry_param("tmd", "friction_force", bounds=POSITIVE),
            EffectParam("elastic_deflection", "m", False, POSITIVE),
        ),
        levels=(LINK,),
    ),
)
VOCABULARY = Vocabulary(EFFECTS)
