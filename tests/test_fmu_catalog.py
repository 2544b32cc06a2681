"""The FMUs come from the registered model units: the catalogue (fmi/catalog.py), the native build's table
and the builders' defaults are derived from the units' declarations, and a unit registered later brings its
FMU with no edit of fmi/ or fmubuild/.
"""

from __future__ import annotations

import ast
import sys
import types
from pathlib import Path

import pytest

from pyfmu_wrapper.fmi import catalog
from pyfmu_wrapper.fmi.fmumodel import FmuModel, NativeFmu, declared, resolve
from pyfmu_wrapper.fmi.varspec import REAL, FmuSpec, Variable, parameter
from pyfmu_wrapper.fmubuild import native_obj
from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.physics.unit import Registry

PKG = Path(catalog.__file__).resolve().parents[1]


def test_the_catalogue_is_the_units_declarations_and_trivial():
    """Every FMU a registered unit names, each once, in registration order, then Trivial; nothing else."""
    expected: list[str] = []
    for unit in MODELS.units():
        for module in unit.fmus:
            name = declared(module).name
            if name not in expected:
                expected.append(name)
    assert expected, "no registered unit names an FMU"
    assert list(catalog.FMUS) == expected + ["Trivial"]
    assert {n: f.spec for n, f in catalog.FMUS.items()} == catalog.SPECS
    assert tuple(expected) == catalog.BUILD_FMUS
    first = next(u for u in MODELS.units() if u.fmus)
    assert tuple(declared(m).name for m in first.fmus) == catalog.PROJECT_FMUS
    assert set(native_obj.native_models()) == set(catalog.NATIVE_FMUS)
    assert set(catalog.NATIVE_FMUS) == {n for n, f in catalog.FMUS.items() if f.native is not None}


@pytest.mark.parametrize("name", sorted(n for n in catalog.FMUS if n != "Trivial"))
def test_each_model_fmu_lives_in_its_units_folder(name):
    """A model's FMU code (declaring module, slave, native functions) sits in its unit's FMU folder, which
    the unit names; the declared names resolve to the objects they promise."""
    fmu = catalog.FMUS[name]
    owners = [u for u in MODELS.units() if any(declared(m) is fmu for m in u.fmus)]
    assert owners, f"{name}: no unit names it"
    folder = ".".join(next(m for m in owners[0].fmus if declared(m) is fmu).split(".")[:-1])
    assert folder.startswith("pyfmu_wrapper.models.") and folder.endswith("fmus")
    slave_module, _, cls = fmu.spec.slave.partition(":")
    assert slave_module.startswith(folder + ".")
    assert resolve(fmu.spec.slave).spec is fmu.spec
    if fmu.native is None:  # Python-hosted only
        return
    for dotted in (fmu.native.step, fmu.native.functions, fmu.native.table):
        assert dotted.startswith(folder + "."), dotted
        assert callable(resolve(dotted))
    table = resolve(fmu.native.table)()
    assert set(table) == {"nstate", "np", "nu", "states", "checks", "fields", "check_vars"}
    assert len(table["states"]) == table["nstate"]
    for var in table["check_vars"]:
        fmu.spec.by_name(var)  # every variable a failed check reports is the FMU's


def test_fmi_and_fmubuild_name_no_model():
    """No code of fmi/ or fmubuild/ names a model or its FMU (docstrings aside): what differs per model is a
    field of its declaration."""
    names = (
        {u.name for u in MODELS.units()} | set(catalog.BUILD_FMUS) | {"frame", "tmd"}
    )  # "base" is also a sysconfig key
    found = []
    for folder in ("fmi", "fmubuild"):
        for path in sorted((PKG / folder).glob("*.py")):
            tree = ast.parse(path.read_text())
            docs = {
                id(n.body[0].value)
                for n in ast.walk(tree)
                if isinstance(n, (ast.Module, ast.FunctionDef, ast.ClassDef))
                and n.body
                and isinstance(n.body[0], ast.Expr)
                and isinstance(n.body[0].value, ast.Constant)
            }
            for node in ast.walk(tree):
                literal = isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docs
                if literal and node.value in names:
                    found.append(f"{path.name}:{node.lineno}: {node.value!r}")
                if isinstance(node, ast.ImportFrom) and node.module and "fmus" in node.module:
                    found.append(f"{path.name}:{node.lineno}: imports {node.module}")
    assert not found, found


def _toy_declaration(monkeypatch: pytest.MonkeyPatch) -> str:
    """A module declaring a toy FMU, importable by its dotted name (as a model folder's would be)."""
    spec = FmuSpec(
        model_name="ToyFmu",
        model_identifier="ToyFmu",
        description="a toy",
        slave="toy_fmus_decl:ToySlave",
        variables=(
            parameter("k", 0, 1.0, None, "gain"),
            Variable(name="y", vr=1, type=REAL, causality="output", variability="continuous", description="y"),
        ),
    )
    mod = types.ModuleType("toy_fmus_decl")
    mod.FMU = FmuModel(spec=spec, native=NativeFmu(step="toy:step", functions="toy:functions", table="toy:table"))
    monkeypatch.setitem(sys.modules, "toy_fmus_decl", mod)
    return "toy_fmus_decl"


def test_a_unit_registered_later_brings_its_fmu(monkeypatch):
    """A unit that names a declaring module gets its FMU into the catalogue, after the registered ones and
    before Trivial, with no edit of fmi/ (the old fmi/variables.SPECS was a hand-written list)."""
    from dataclasses import replace

    module = _toy_declaration(monkeypatch)
    reg = Registry()
    for unit in MODELS.units():
        reg.register(unit)
    base = MODELS.units()[-1]

    class ToyStructure:
        pass

    reg.register(replace(base, name="toy", structure=ToyStructure, fmus=(module,)))
    fmus = catalog.gather(reg)
    assert list(fmus)[-2:] == ["ToyFmu", "Trivial"]
    assert fmus["ToyFmu"].native is not None and fmus["ToyFmu"].native.table == "toy:table"
    assert list(fmus)[:-2] == list(catalog.FMUS)[:-1]


def test_a_module_without_a_declaration_is_refused(monkeypatch):
    monkeypatch.setitem(sys.modules, "toy_no_fmu", types.ModuleType("toy_no_fmu"))
    with pytest.raises(TypeError, match="toy_no_fmu declares no FMU"):
        declared("toy_no_fmu")
