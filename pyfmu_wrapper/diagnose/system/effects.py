"""The vocabulary of the system diagnosis: the effects it can name (their labels in the report and the
SI units of their parameters), how many one verdict may name, and which effects take part in which
fit (the equation-error fits of the time records, the FRC-alone prior, the play refit).
"""

#: the most effects one verdict names
MAX_EFFECTS = 2
#: what the report calls each effect
LABELS = {
    "friction": "dry friction in the TMD link",
    "play": "play in the inerter gear",
    "viscous": "extra viscous damping",
    "mass_split": "different split of m and I (m + I fixed)",
    "cubic": "cubic term in the TMD spring",
    "force_error": "forcing-amplitude error",
    "sensor_offset": "displacement-sensor offset",
    "base_mass": "base mass M off the nominal",
    "base_stiffness": "base stiffness K off the nominal",
    "base_damping": "base damping C off the nominal",
    "tmd_stiffness": "TMD spring stiffness k off the nominal",
}
#: SI unit of each effect parameter
UNITS = {
    "friction_force": "N",
    "friction_slope": "s/m",
    "play_gap": "m",
    "delta_inertance_eff": "kg",
    "signature_scale": "1",
    "delta_damping": "N s/m",
    "delta_inertance": "kg",
    "cubic_stiffness": "N/m^3",
    "force_gain_error": "1",
    "x_offset": "m",
    "y_offset": "m",
    "delta_mass": "kg",
    "delta_stiffness": "N/m",
}
FRC_PRIOR = (
    "viscous",
    "mass_split",
    "cubic",
    "force_error",
    "base_mass",
    "base_stiffness",
    "base_damping",
    "tmd_stiffness",
)  #: effects whose FRC-alone fit is a prior for the time-record folds
TMD_EFFECTS = (
    "viscous",
    "tmd_stiffness",
    "friction",
    "cubic",
    "mass_split",
    "base_damping",
    "base_mass",
    "base_stiffness",
)  #: effects that change the rattle (play is refitted with them)
EQ_EFFECTS = (
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
