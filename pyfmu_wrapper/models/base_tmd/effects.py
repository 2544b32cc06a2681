"""The pair's effect vocabulary (:mod:`pyfmu_wrapper.physics.effects`): what ``diagnose`` can name on
the base + TMD-inerter, read by every diagnosis path, benchmark and report.

The TMD-inerter's effects and the force channel's gain are declared once for every structure that
carries the absorber (:mod:`pyfmu_wrapper.physics.tmd_effects`); the pair adds its base's parameter
effects (M, K, C off the nominal, their units from the registry), the displacement sensors' offsets,
and the link rig's two (the TMD link alone on a test machine): a displacement bias, seen as the force
k b, and dry friction with contact compliance, the rival of play in front of friction.
"""

from __future__ import annotations

from ...physics.effects import LINK, SYSTEM, Effect, EffectParam, Vocabulary, registry_param
from ...physics.tmd_effects import FORCE_ERROR, POSITIVE, TMD

EFFECTS = (
    TMD["viscous"],
    TMD["friction"],
    TMD["play"],
    TMD["mass_split"],
    TMD["cubic"],
    FORCE_ERROR,
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
    TMD["tmd_stiffness"],
    TMD["tmd_mass"],
    TMD["inertance"],
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
__all__ = ["EFFECTS", "SYSTEM", "VOCABULARY"]
