"""The paper's scenarios and how they are run: ``scenarios/paper/`` (the paper-resolution variants of
``scenarios/``), shrunk to smaller grids on request, run by the scenario runner with one engine.

The console command ``reproduce`` (:mod:`pyfmu_wrapper.cli.reproduce`) runs them (:func:`run_all`), judges the
claims (:mod:`.claims`), draws the figures (:mod:`.figures`) and writes the report (:mod:`.report`).
Finished sweeps are checkpointed under ``<results>/.cache/``, keyed by the code version and every setting, so
rows computed by older code are never reused.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from ..inputs.yamlio import load_marked
from ..scenario.engines import RunSettings
from ..scenario.loader import Scenario, parse_scenario, plain_data
from ..scenario.output import run_scenario
from ..scenario.runner import work_units
from .names import CASES as CASES  # re-exported: the figures and claims read them here
from .names import DEFAULT_ENGINE

ROOT = Path(__file__).resolve().parents[2]
PAPER_DIR = ROOT / "scenarios" / "paper"

# --- scenarios -------------------------------------------------------------------------------------


def _shrink(doc: dict, level: str, exact: bool) -> dict:
    """Smaller grids: 'quick' (tests) or 'coarse' (medium maps). Exact (linear) scenarios stay finer."""
    if level == "quick":
        nf_frc, nf_map, nv_map = (201, 101, 21) if exact else (9, 7, 3)
    else:
        nf_frc, nf_map, nv_map = (None, 41, 21)
    if nf_frc is not None:
        doc["frequencies"] = dict(start=15.0, stop=25.0, count=nf_frc)
    for st in doc["studies"]:
        if st["kind"] == "map":
            v = st["values"]
            st["values"] = dict(start=v["start"], stop=v["stop"], count=nv_map)
            st["frequencies"] = dict(start=15.0, stop=25.0, count=nf_map)
        elif st["kind"] == "phase_portrait" and level == "quick":
            st["n_periods"], st["samples_per_period"] = 1, 400
        elif st["kind"] == "frc" and level == "quick" and "frequencies" in st:
            st["frequencies"] = dict(start=15.0, stop=25.0, count=nf_frc)
    doc["description"] = f"[{level} grid] " + doc.get("description", "")
    return doc


def load_paper_scenario(name: str, level: str | None = None) -> Scenario:
    """A scenario of scenarios/paper/, optionally shrunk ('quick' or 'coarse')."""
    path = PAPER_DIR / f"{name}.yaml"
    text = path.read_text(encoding="utf-8")
    if level:
        doc = _shrink(plain_data(load_marked(text, name=str(path))), level, exact=name.startswith(("fig2", "fig3")))
        text = yaml.safe_dump(doc, sort_keys=False)
    return parse_scenario(text, str(path))


# --- running ----------------------------------------------------------------------------------------


@dataclass
class Run:
    name: str
    scenario: Scenario
    level: str | None
    datas: dict  #: study name -> data object
    summary: dict
    folder: Path


def run_all(
    names: Iterable[str],
    results: Path,
    level_of: Callable[[str], str | None],
    executor: Any,
    resume: bool = True,
    progress: bool = True,
    engine: str = DEFAULT_ENGINE,
) -> dict[str, Run]:
    """Run the scenarios with ``engine`` (checkpointed under ``results/.cache``) and collect their data objects."""
    from tqdm import tqdm

    runs = {}
    for name in names:
        level = level_of(name)
        scn = load_paper_scenario(name, level)
        settings = RunSettings.for_scenario(scn, engine=engine)
        collect: list = []
        out = results / name
        with tqdm(
            total=work_units(scn, settings), desc=name, unit="pt", disable=not progress, file=sys.stderr, leave=False
        ) as bar:
            run_scenario(
                scn,
                out,
                settings,
                progress=bar.update,
                executor=executor,
                checkpoint_dir=results / ".cache" / name,
                resume=resume,
                collect=collect,
            )
        summary = json.loads((out / "summary.json").read_text())
        runs[name] = Run(name, scn, level, {d.study.name: d for d in collect}, summary, out)
    return runs
