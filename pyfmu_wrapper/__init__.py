"""Tuned mass dampers with inerters: physics, solvers, co-simulation FMUs, scenarios and diagnosis (docs/architecture.md maps the folders)."""
