"""The link pipeline: one TMD link measured on a displacement-controlled rig (models of the
link force, their fit, where the gap is, the report, the link benchmark, the BRFD real data)."""
