"""The FMUs come from the registered model units as objects: the catalogue (models/catalog.py) gathers the
declarations each unit's ``fmus()`` gives, the builders take declarations as arguments, and a unit registered
later brings its FMU with no edit of fmi/, fmubuild/ or the catalogue.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest

from pyfmu_wrapper.fmi.fmumodel import FmuModel, NativeFmu, dotted_name, resolve
from pyfmu_wrapper.fmi.slave import Slave
from pyfmu_wrapper.fmi.varspec import REAL, FmuSpec, Variable, parameter
from pyfmu_wrapper.fmubuild import native_obj
from pyfmu_wrapper.fmubuild.bundle import bundled_files, model_py
from pyfmu_wrapper.models import MODELS, catalog
from pyfmu_wrapper.physics.unit import Registry

PKG = Path(catalog.__file__).resolve().parents[1]


def test_the_catalogue_is_the_units_declarations_and_trivial():
    """Every FMU a registered unit gives, each once, in registration order, then Trivial; nothing else."""
    expected: list[FmuModel] = []
    for unit in MODELS.units():
        for fmu in unit.fmus():
            assert isinstance(fmu, FmuModel)
            assert unit.fmus()[list(unit.fmus()).index(fmu)] is fmu  # the same objects on every call
            if fmu not in expected:
                expected.append(fmu)
    assert expected, "no registered unit gives an FMU"
    assert list(catalog.FMUS.values()) == [*expected, catalog.FMUS["Trivial"]]
    assert {n: f.spec for n, f in catalog.FMUS.items()} == catalog.SPECS
    assert tuple(f.name for f in expected) == catalog.BUILD_FMUS
    first = next(u for u in MODELS.units() if u.fmus())
    assert tuple(f.name for f in first.fmus() if not f.system) == catalog.PROJECT_FMUS
    assert set(native_obj.native_models(catalog.pick(catalog.NATIVE_FMUS))) == set(catalog.NATIVE_FMUS)
    assert set(catalog.NATIVE_FMUS) == {n for n, f in catalog.FMUS.items() if f.native is not None}
    assert catalog.pick("TMDInerter") == (catalog.FMUS["TMDInerter"],)
    with pytest.raises(ValueError, match=r"unknown FMU\(s\) \['Nope'\]; choose from"):
        catalog.pick(("TMDInerter", "Nope"))


@pytest.mark.parametrize("name", sorted(n for n in catalog.FMUS if n != "Trivial"))
def test_each_model_fmu_lives_in_its_units_folder(name):
    """A model's FMU code (declaration, slave, native functions) sits in the FMU folder of the unit that
    gives it; the declaration holds the objects themselves, and a name derived from one leads back to it."""
    fmu = catalog.FMUS[name]
    owners = [u for u in MODELS.units() if any(f is fmu for f in u.fmus())]
    assert owners, f"{name}: no unit gives it"
    folder = f"{owners[0].fmus.__module__}.fmus"  # the FMU folder beside the unit's fmus()
    assert folder.startswith("pyfmu_wrapper.models.")
    assert fmu.slave.__module__.startswith(folder + "."), fmu.slave.__module__
    assert issubclass(fmu.slave, Slave) and fmu.slave.spec is fmu.spec
    assert resolve(dotted_name(fmu.slave)) is fmu.slave
    if fmu.native is None:  # Python-hosted only
        return
    for factory in fmu.native.factories():
        assert callable(factory) and factory.__module__.startswith(folder + "."), factory
        assert resolve(dotted_name(factory)) is factory
    table = fmu.native.table()
    assert set(table) == {"nstate", "np", "nu", "states", "checks", "fields", "check_vars"}
    assert len(table["states"]) == table["nstate"]
    for var in table["check_vars"]:
        fmu.spec.by_name(var)  # every variable a failed check reports is the FMU's


def test_fmi_and_fmubuild_name_no_model():
    """No code of fmi/ or fmubuild/ names a model, its FMU or its module (docstrings aside), and none
    imports the models or their catalogue: what differs per model is a field of the declaration it is given."""
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
                if literal and (node.value in names or "pyfmu_wrapper.models" in node.value):
                    found.append(f"{path.name}:{node.lineno}: {node.value!r}")
                if (
                    isinstance(node, ast.ImportFrom)
                    and node.module
                    and ("fmus" in node.module or "models" in node.module)
                ):
                    found.append(f"{path.name}:{node.lineno}: imports {node.module}")
    assert not found, found


def test_no_hand_written_dotted_name_of_a_model():
    """No string literal of the package (docstrings aside) names a module of the models by its dotted name:
    a unit holds its parts as objects: its FMUs, its co-simulation, its scenario reader."""
    found = []
    for path in sorted(PKG.rglob("*.py")):
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
            if literal and "pyfmu_wrapper.models." in node.value:
                found.append(f"{path.relative_to(PKG)}:{node.lineno}: {node.value!r}")
    assert not found, found


class ToySlave(Slave):
    """A toy FMU's slave (top level: its name is derived for the FMU's loader)."""

    spec = FmuSpec(
        model_name="ToyFmu",
        model_identifier="ToyFmu",
        description="a toy",
        variables=(
            parameter("k", 0, 1.0, "N.m/rad", "stiffness of a torsion spring"),
            Variable(name="y", vr=1, type=REAL, causality="output", variability="continuous", description="y"),
        ),
    )


def toy_step() -> None:
    """A toy native factory."""


def test_a_unit_registered_later_brings_its_fmu():
    """A unit whose ``fmus()`` gives a declaration gets its FMU into the catalogue, after the registered
    ones and before Trivial, with no edit of fmi/ or of the catalogue (the old fmi/variables.SPECS was a
    hand-written list)."""
    toy = FmuModel(spec=ToySlave.spec, slave=ToySlave, native=NativeFmu(step=toy_step, functions=dict, table=dict))
    reg = Registry()
    for unit in MODELS.units():
        reg.register(unit)

    class ToyStructure:
        pass

    reg.register(replace(MODELS.units()[-1], name="toy", structure=ToyStructure, fmus=lambda: (toy,)))
    fmus = catalog.gather(reg)
    assert list(fmus)[-2:] == ["ToyFmu", "Trivial"]
    assert fmus["ToyFmu"] is toy and fmus["ToyFmu"].native is not None and fmus["ToyFmu"].native.step is toy_step
    assert list(fmus)[:-2] == list(catalog.FMUS)[:-1]
    assert native_obj.native_models([toy])["ToyFmu"][0] == f"{__name__}:toy_step"  # derived, for the subprocess


def test_a_declaration_holds_the_slave_of_its_own_spec_and_derived_names_only():
    spec = replace(ToySlave.spec, model_identifier="Other")
    with pytest.raises(ValueError, match="the slave ToySlave runs another spec"):
        FmuModel(spec=spec, slave=ToySlave)

    def local_step() -> None:
        pass

    with pytest.raises(ValueError, match="define it at a module's top level"):
        dotted_name(local_step)
    with pytest.raises(TypeError, match=r"fmus\(\) gave 'a.module.name', not an FmuModel"):
        reg = Registry()
        reg.register(replace(MODELS.units()[0], fmus=lambda: ("a.module.name",)))
        catalog.gather(reg)


def test_the_bundle_is_the_closure_of_the_slaves_given():
    """The builders bundle what the slaves of the FMUs they are given import; every FMU of a model carries
    the same bundle whichever FMUs are built with it (the registry imports every unit, each unit its FMUs),
    so the FMUs of one build share one package; a slave outside the package cannot be bundled."""
    every = bundled_files(catalog.FMUS.values())
    for fmu in catalog.FMUS.values():
        if fmu.name != "Trivial":
            assert bundled_files([fmu]) == every, fmu.name
    assert {"fmi/slave.py", "fmi/fmu_loader.py", "fmi/trivial.py", "fmi/units.py"} <= set(every)
    assert not any(f.startswith(("fmubuild/", "cosim/", "master/", "scenario/")) for f in every)
    assert "models/catalog.py" not in every
    text = model_py(catalog.FMUS["TMDInerter"], "_pyfmu_0", "0" * 64, every)
    assert "'models.base_tmd.fmus.slaves:TMDInerterSlave'" in text  # derived from the class
    with pytest.raises(ValueError, match="cannot be bundled"):
        bundled_files([FmuModel(spec=ToySlave.spec, slave=ToySlave)])


def test_importing_the_models_imports_no_fmu_code():
    """A unit's FMUs are imported on the first call of its ``fmus()``: importing the registry stays cheap."""
    code = (
        "import sys, pyfmu_wrapper.models as m\n"
        "print(sorted(n for n in sys.modules if '.fmus' in n or n.startswith('pyfmu_wrapper.fmi')))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.strip() == "[]", r.stdout
