"""The system diagnosis's view of the vocabulary: the effects it can name are those the model unit
declares (:data:`pyfmu_wrapper.models.base_tmd.effects.EFFECTS`, read through the unit, as the solvers
read its equations); here only how many one verdict may name, and which effects take part in which fit
(the equation-error fits of the time records, the FRC-alone prior, the play refit, the transient fits).
"""

from ...models.base_tmd import UNIT
from ...physics.effects import Vocabulary

assert UNIT.effects is not None
VOCAB: Vocabulary = UNIT.effects
#: the most effects one verdict names
MAX_EFFECTS = 2
#: what the report calls each effect
LABELS = VOCAB.labels()
#: SI unit of each effect parameter (and of the steady path's play signature, see .model.EFFECT_PARAMS)
UNITS = {**VOCAB.units, "delta_inertance_eff": "kg", "signature_scale": "1"}
FRC_PRIOR = VOCAB.select(
    (
        "viscous",
        "mass_split",
        "cubic",
        "force_error",
        "base_mass",
        "base_stiffness",
        "base_damping",
        "tmd_stiffness",
    )
)  #: effects whose FRC-alone fit is a prior for the time-record folds
TMD_EFFECTS = VOCAB.select(
    (
        "viscous",
        "tmd_stiffness",
        "friction",
        "cubic",
        "mass_split",
        "base_damping",
        "base_mass",
        "base_stiffness",
    )
)  #: effects that change the rattle (play is refitted with them)
EQ_EFFECTS = VOCAB.select(
    (
        "friction",
        "viscous",
        "mass_split",
        "cubic",
        "force_error",
        "sensor_offset",
        "base_mass",
        "base_stiffness",
        "base_damping",
        "tmd_stiffness",
    )
)  #: the steady records' equation-error candidates (play is fitted by its rattle signature)
#: the transient records' candidates: every system-level effect of the vocabulary, in its order (the
#: fit simulates the model, so each can be tried)
TRANSIENT_EFFECTS = VOCAB.names()
