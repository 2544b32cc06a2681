"""What the run-scenario safety tests share: a tiny linear scenario, the options of a quick monolithic
run, a scenario writer, a snapshot of a folder's files; the fixture
``no_computing`` is in conftest.py."""

from __future__ import annotations

import textwrap
from pathlib import Path

LINEAR = """\
schema_version: 2
name: tiny
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: ideal, stiffness: 4000.0, damping: 10.0}
frequencies: {start: 17.0, stop: 23.0, count: 5}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "c = 10"}
"""


#: friction curves with the co-simulation: a few seconds per curve, several curves in parallel
SLOW = """\
schema_version: 2
name: slow
base: {mass: 100.0, stiffness: 40000.0, damping: 100.0, force_amplitude: 200.0}
tmd: {case: 1, inerter: ideal, stiffness: 4000.0, damping: 0.0}
frequencies: {start: 15.0, stop: 25.0, count: 81}
studies:
  - kind: frc
    name: frc
    curves:
      - {label: "df = 10", tmd: {friction_force: 10.0}}
      - {label: "df = 20", tmd: {friction_force: 20.0}}
      - {label: "df = 30", tmd: {friction_force: 30.0}}
      - {label: "df = 40", tmd: {friction_force: 40.0}}
"""

MONO = ["--quiet", "--engine", "monolithic", "--executor", "sequential"]


def write_scenario(folder: Path, text: str = LINEAR, name: str = "scn.yaml") -> Path:
    p = folder / name
    p.write_text(textwrap.dedent(text))
    return p


def snapshot(folder: Path) -> dict:
    """Every file under folder (hidden ones too) with its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}
