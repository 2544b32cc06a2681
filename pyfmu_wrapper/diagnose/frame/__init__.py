"""Diagnosis of a shear frame with its TMD-inerter / TMDI from transient records (issue 41): the linear
model and its exact sampled simulation (:mod:`.model`), the output-error fit of every effect of the
frame unit's vocabulary at every element (:mod:`.fit`), the verdict and the report (:mod:`.report`)."""
