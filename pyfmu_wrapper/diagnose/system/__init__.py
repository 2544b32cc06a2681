"""The system pipeline: the coupled base + TMD measured as a rig does (time records and
stepped-sine FRCs): the system model, the diagnosis with its gates, the play fit, the report,
the field-like benchmark suite and its score."""
