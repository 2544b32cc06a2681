"""The generated tables of the docs (pyfmu_wrapper/generate/docs.py): docs/fmus.md holds one variable
table per FMU spec of fmi/variables.SPECS (the ShearFrame's included), row for row; docs/parameters.md
one parameter table per subsystem a registered unit declares; both files are current."""

from __future__ import annotations

import re

from pyfmu_wrapper.generate import docs as gen
from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.models.catalog import SPECS


def _section(text: str, heading: str) -> str:
    i = text.index(heading)
    j = text.find("\n### ", i + len(heading))
    return text[i : j if j > 0 else len(text)]


def test_fmus_md_has_every_specs_variables_row_for_row():
    text = gen.FMUS_FILE.read_text(encoding="utf-8")
    assert gen.fmus_text(text) == text, "docs/fmus.md is stale: run `python -m pyfmu_wrapper.generate.docs`"
    generated = text[text.index(gen.VARIABLES_HEADING) :]
    assert "ShearFrame" in SPECS
    for name, spec in SPECS.items():
        rows = re.findall(r"^\| `([^`]+)` \| (\d+) \| (\w+) \| (\w+) \|", _section(generated, f"\n### {name}\n"), re.M)
        want = [(v.name, str(v.vr), v.type, v.causality) for v in spec.variables]
        assert rows == want, name


def test_parameters_md_has_a_table_per_declared_subsystem():
    text = gen.DOCS_FILE.read_text(encoding="utf-8")
    assert gen.parameters_text() == text, "docs/parameters.md is stale: run `python -m pyfmu_wrapper.generate.docs`"
    for unit in MODELS.units():
        if unit.name == "base_tmd":
            continue  # the paper's base and tmd tables
        assert f"model `{unit.name}`" in text
        for p in unit.parameters:
            assert f"| `{p.name}` | {p.symbol} | {p.unit} |" in text, (unit.name, p.name)
