"""Generate the parameter parts of the Modelica package ``modelica/TMDInerter`` from Python.

The Modelica package restates the physics of :mod:`pyfmu_wrapper.physics.kernels` in plain
Modelica (no Modelica Standard Library). Its parameter values have one source, the Python
parameter definitions: :class:`~pyfmu_wrapper.physics.params.BaseParams` and
:class:`~pyfmu_wrapper.physics.params.TMDParams` defaults and
:func:`~pyfmu_wrapper.physics.params.paper_case`. This module writes

* ``Defaults.mo``: the dataclass defaults, used as the default values of every component;
* ``Cases.mo``: one model per case of the paper (Cases 1-3 of each study, and the two endpoints
  of the Iratio map), each extending a coupled system with every parameter written out, then the
  cases of every registered model unit that has a Modelica source
  (:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.modelica`: the frame's ``Frames.mo``), each extending
  the unit's class with the structure's modifiers and the TMD's;
* the generated parameter blocks of ``Systems.mo`` and of every unit's file (``Frames.mo``).

Run ``python -m pyfmu_wrapper.generate.modelica`` to rewrite the files, ``--check`` to fail when the
committed files differ from the generated text (the test suite does the same check).
"""

from __future__ import annotations

import argparse
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from ..physics import registry
from ..physics.modelica_source import ModelicaCase
from ..physics.params import BaseParams, InerterModel, TMDParams, paper_case
from ..physics.unit import ModelUnit
from ..physics.units import MODELS

PACKAGE = "TMDInerter"
#: default location of the package, relative to the repository root
PACKAGE_DIR = Path(__file__).resolve().parents[2] / "modelica" / PACKAGE

#: default excitation frequency [rad/s] of the Modelica models (omega is not a structural
#: parameter in Python; it is passed to the solvers)
DEFAULT_OMEGA = 19.0
#: simulation interval and tolerance written in the experiment annotation of each case
EXPERIMENT_STOP_TIME = 2.0
EXPERIMENT_TOLERANCE = 1e-8

#: Modelica parameter name of each dataclass field, from the parameter registry
BASE_NAMES = {p.name: p.modelica_name for p in registry.fields("base") if p.modelica_name}
TMD_NAMES = {p.name: p.modelica_name for p in registry.fields("tmd") if p.modelica_name}
#: the coupled system class of each inerter model
SYSTEM_CLASS = {
    InerterModel.NONE: "CoupledNoInerter",
    InerterModel.IDEAL: "CoupledIdealInerter",
    InerterModel.PLAY: "CoupledPlayInerter",
}
#: the TMD subsystem class of each inerter model
TMD_CLASS = {
    InerterModel.NONE: "TMDNoInerter",
    InerterModel.IDEAL: "TMDIdealInerter",
    InerterModel.PLAY: "TMDPlayInerter",
}


def system_parameters(model: InerterModel) -> tuple[str, ...]:
    """Modelica names of the TMD parameters a coupled system of this inerter model has."""
    return tuple(p.modelica_name for p in registry.fields("tmd") if p.modelica_name and int(model) in p.models)


#: the coupled system class and its TMD parameters, per inerter model
SYSTEM_PARAMS = {m: (SYSTEM_CLASS[m], system_parameters(m)) for m in InerterModel}

# Paper values per study (Sects. 4-7 of Brzeski & Perlikowski 2017).
C_OPT = {1: 56.38, 2: 31.73, 3: 6.45}  #: optimised viscous damping c [N s/m] (Sect. 4, Fig. 3)
DF_OPT = {1: 45.78, 2: 37.65, 3: 15.44}  #: optimised dry friction df [N] (Sect. 5, Fig. 4)
STANDARD_GAP = 1e-4  #: standardised play gap eps [m] (Sect. 6)
#: full model (Sect. 7, line "5" of Fig. 6): c and df; Case 3 uses half the values
FULL_C_DF = {1: (10.0, 10.0), 2: (10.0, 10.0), 3: (5.0, 5.0)}
#: cubic TMD spring check case (not in the paper): Case 1, c = 10, hardening k3 [N/m^3]
CUBIC_K3 = 1.0e6


@dataclass(frozen=True)
class CaseSpec:
    """One Modelica case model and the Python parameters it stands for."""

    name: str  #: Modelica class name inside ``TMDInerter.Cases``
    description: str
    base: BaseParams
    tmd: TMDParams

    @property
    def system(self) -> str:
        return SYSTEM_PARAMS[self.tmd.inerter][0]

    def modelica_parameters(self) -> dict[str, float]:
        """Modelica parameter name -> value, for the parameters the system has."""
        out = {BASE_NAMES[n]: getattr(self.base, n) for n in BASE_NAMES}
        keep = system_parameters(self.tmd.inerter)
        for f, n in TMD_NAMES.items():
            if n in keep:
                out[n] = getattr(self.tmd, f)
        return out


def cases() -> list[CaseSpec]:
    """Every case of the paper, in the order they are written to ``Cases.mo``."""
    base = BaseParams()
    out = [
        CaseSpec(
            "IratioMap0",
            "Iratio map endpoint Iratio = 0: classical TMD, m = 10, no inerter",
            base,
            TMDParams(mass=10.0, inertance=0.0, inerter=InerterModel.NONE),
        ),
        CaseSpec(
            "IratioMap1",
            "Iratio map endpoint Iratio = 1: massless TMD node, ideal inerter I = 10",
            base,
            TMDParams(mass=0.0, inertance=10.0, inerter=InerterModel.IDEAL),
        ),
    ]
    for n in (1, 2, 3):
        out.append(CaseSpec(f"IdealCase{n}", f"Sect. 3, Case {n}: ideal inerter, no damping", base, paper_case(n)))
    for n in (1, 2, 3):
        out.append(
            CaseSpec(
                f"ViscousCase{n}",
                f"Sect. 4, Case {n}: ideal inerter, optimised viscous damping c",
                base,
                paper_case(n, damping=C_OPT[n]),
            )
        )
    for n in (1, 2, 3):
        out.append(
            CaseSpec(
                f"DryFrictionCase{n}",
                f"Sect. 5, Case {n}: ideal inerter, optimised dry friction df",
                base,
                paper_case(n, friction_force=DF_OPT[n]),
            )
        )
    for n in (1, 2, 3):
        out.append(
            CaseSpec(
                f"PlayCase{n}",
                f"Sect. 6, Case {n}: inerter with play, standard gap eps",
                base,
                paper_case(n, inerter=InerterModel.PLAY, play_gap=STANDARD_GAP),
            )
        )
    for n in (1, 2, 3):
        c, df = FULL_C_DF[n]
        out.append(
            CaseSpec(
                f"FullCase{n}",
                f"Sect. 7, Case {n}: full model (viscous damping, dry friction, play)",
                base,
                paper_case(n, damping=c, friction_force=df, inerter=InerterModel.PLAY, play_gap=STANDARD_GAP),
            )
        )
    out.append(
        CaseSpec(
            "CubicSpringCase1",
            "Not in the paper: Case 1, c = 10, hardening cubic TMD spring k3",
            base,
            paper_case(1, damping=10.0, cubic_stiffness=CUBIC_K3),
        )
    )
    return out


def fmt(value: float) -> str:
    """A Modelica real literal that reads back to exactly the same double."""
    s = repr(float(value))
    if s in ("inf", "-inf", "nan"):
        raise ValueError(f"cannot write {value!r} as a Modelica literal")
    return s


HEADER = (
    "  // Generated by pyfmu_wrapper.generate.modelica from pyfmu_wrapper/physics/params.py and the model units.\n"
    "  // Do not edit: run `python -m pyfmu_wrapper.generate.modelica` instead.\n"
)


def defaults_text() -> str:
    """``Defaults.mo``: the registry defaults (the Python dataclass defaults)."""
    lines = [
        f"within {PACKAGE};",
        'package Defaults "Default parameter values (Python dataclass defaults)"',
        HEADER.rstrip("\n"),
        f"  extends {PACKAGE}.Icons.Package;",
    ]
    for p in registry.PARAMETERS:
        if not p.modelica_name:
            continue
        if p.name == "omega":
            lines.append(
                f'  constant Real w = {fmt(DEFAULT_OMEGA)} "Excitation frequency [rad/s] (generate.modelica.DEFAULT_OMEGA)";'
            )
            continue
        cls = "BaseParams" if p.subsystem == "base" else "TMDParams"
        lines.append(f'  constant Real {p.modelica_name} = {fmt(p.default)} "{cls}.{p.name}";')
    lines.append("end Defaults;")
    return "\n".join(lines) + "\n"


# --- generated blocks of Systems.mo -------------------------------------------------------------
# Systems.mo is written by hand (the structure: components and connections); the parameter
# declarations and the TMD instance modifiers are generated between marker comments
#   // <generated KIND ARG>   ...   // </generated>
# KIND = params (ARG: base | tmd-all | tmd-ideal | tmd-play) or instance (ARG: ideal | play | none).
_MARK_OPEN = re.compile(r"^(?P<indent>\s*)// <generated (?P<kind>\w+) (?P<arg>[\w-]+)>\s*$")
_MARK_CLOSE = "// </generated>"
_MODEL_OF = {"none": InerterModel.NONE, "ideal": InerterModel.IDEAL, "play": InerterModel.PLAY}


def _param_lines(arg: str, indent: str) -> list[str]:
    if arg in registry.declared():  # a unit's own subsystem: its declared rows, literal defaults
        return [
            f"{indent}parameter {PACKAGE}.Units.{p.modelica_type} {p.modelica_name} = "
            f'{fmt(p.default)} "{p.symbol}: {p.description}";'
            for p in registry.of(arg)
            if p.modelica_name
        ]
    if arg == "base":
        pars = [p for p in registry.of("base") if p.modelica_name]
    else:
        which = arg.split("-", 1)[1]
        pars = [p for p in registry.fields("tmd") if p.modelica_name]
        if which == "all":
            pars = [p for p in pars if p.models == registry.ALL_MODELS]
        else:
            m = int(_MODEL_OF[which])
            pars = [p for p in pars if m in p.models and p.models != registry.ALL_MODELS]
    return [
        f"{indent}parameter {PACKAGE}.Units.{p.modelica_type} {p.modelica_name} = "
        f'{PACKAGE}.Defaults.{p.modelica_name} "{p.symbol}: {p.description}";'
        for p in pars
    ]


def _instance_line(arg: str, indent: str) -> list[str]:
    model = _MODEL_OF[arg]
    mods = ", ".join(f"{n} = {n}" for n in system_parameters(model))
    return [f"{indent}{PACKAGE}.Systems.{TMD_CLASS[model]} tmd({mods});"]


def systems_text(text: str) -> str:
    """Systems.mo (or a unit's file) with every generated block rewritten from the registry."""
    out, lines, i = [], text.splitlines(), 0
    while i < len(lines):
        line = lines[i]
        out.append(line)
        m = _MARK_OPEN.match(line)
        i += 1
        if not m:
            continue
        while i < len(lines) and lines[i].strip() != _MARK_CLOSE:
            i += 1
        if i == len(lines):
            raise ValueError(f"Systems.mo: unclosed generated block opened by {line.strip()!r}")
        indent, kind, arg = m.group("indent"), m.group("kind"), m.group("arg")
        out.extend(_param_lines(arg, indent) if kind == "params" else _instance_line(arg, indent))
        out.append(lines[i])
        i += 1
    return "\n".join(out) + "\n"


def case_text(spec: CaseSpec) -> str:
    params = spec.modelica_parameters()
    mods = ", ".join(f"{n} = {fmt(v)}" for n, v in params.items())
    return (
        f'  model {spec.name} "{spec.description}"\n'
        f"    extends {PACKAGE}.Systems.{spec.system}({mods}, w = {fmt(DEFAULT_OMEGA)});\n"
        f"    annotation(experiment(StartTime = 0, StopTime = {fmt(EXPERIMENT_STOP_TIME)}, "
        f"Tolerance = {fmt(EXPERIMENT_TOLERANCE)}));\n"
        f"  end {spec.name};\n"
    )


def modelica_units() -> tuple[ModelUnit, ...]:
    """The registered model units that have a Modelica source."""
    return tuple(u for u in MODELS.units() if u.modelica is not None)


def unit_cases() -> list[tuple[ModelUnit, ModelicaCase]]:
    """Every unit's cases, in the order they are written to ``Cases.mo`` (after the paper's)."""
    return [(u, c) for u in modelica_units() if u.modelica is not None for c in u.modelica.cases()]


def unit_case_parameters(unit: ModelUnit, case: ModelicaCase) -> dict[str, str]:
    """Modelica parameter name -> literal of a unit's case: the structure's (from the unit), then the
    TMD's the case's class has (from the registry), then w."""
    assert unit.modelica is not None
    out = dict(unit.modelica.modifiers(case.structure))
    if unit.takes_tmd:
        keep = system_parameters(case.tmd.inerter)
        for f, n in TMD_NAMES.items():
            if n in keep:
                out[n] = fmt(getattr(case.tmd, f))
    out["w"] = fmt(DEFAULT_OMEGA)
    return out


def unit_case_text(unit: ModelUnit, case: ModelicaCase) -> str:
    assert unit.modelica is not None
    mods = ", ".join(f"{n} = {v}" for n, v in unit_case_parameters(unit, case).items())
    return (
        f'  model {case.name} "{case.description} (model {unit.name})"\n'
        f"    extends {PACKAGE}.{unit.modelica.system(case.tmd)}({mods});\n"
        f"    annotation(experiment(StartTime = 0, StopTime = {fmt(EXPERIMENT_STOP_TIME)}, "
        f"Tolerance = {fmt(EXPERIMENT_TOLERANCE)}));\n"
        f"  end {case.name};\n"
    )


def cases_text() -> str:
    """``Cases.mo``: one model per case of the paper, then the cases of the model units."""
    body = "\n".join([case_text(s) for s in cases()] + [unit_case_text(u, c) for u, c in unit_cases()])
    return (
        f"within {PACKAGE};\n"
        f'package Cases "One model per case of the paper (Brzeski & Perlikowski 2017) and of the model units"\n'
        f"{HEADER}  extends {PACKAGE}.Icons.Package;\n\n{body}end Cases;\n"
    )


#: the package's own classes, in load order (package.order: these, the units' subpackages, then
#: Defaults and Cases)
PACKAGE_ORDER = ("Icons", "Units", "pi", "Interfaces", "Components", "Systems")


def order_text() -> str:
    """``package.order``: the package's classes, every unit's subpackage, Defaults, Cases."""
    units = [u.modelica.package for u in modelica_units() if u.modelica is not None]
    return "\n".join([*PACKAGE_ORDER, *units, "Defaults", "Cases"]) + "\n"


def unit_file_text(source: Path) -> str:
    """A unit's subpackage as written into the package: its source with a do-not-edit note after
    the package line and the generated blocks filled."""
    lines = source.read_text(encoding="utf-8").splitlines(keepends=True)
    i = next((k for k, line in enumerate(lines) if line.lstrip().startswith("package ")), None)
    if i is None:
        raise ValueError(f"{source}: no 'package' line (a unit's Modelica source is one subpackage)")
    root = Path(__file__).resolve().parents[2]
    rel = source.resolve().relative_to(root) if source.resolve().is_relative_to(root) else source
    note = (
        f"  // Generated by pyfmu_wrapper.generate.modelica from {rel.as_posix()} (the model unit's source).\n"
        "  // Do not edit: edit the source and run `python -m pyfmu_wrapper.generate.modelica`.\n"
    )
    return systems_text("".join(lines[: i + 1]) + note + "".join(lines[i + 1 :]))


def generated_files(directory: Path = PACKAGE_DIR) -> dict[str, str]:
    """File name (inside the package directory) -> generated text: Defaults.mo, Cases.mo,
    package.order, Systems.mo (its own structure, read from ``directory``, with the generated blocks
    rewritten) and every unit's subpackage (its source in the unit's folder, blocks filled)."""
    out = {"Defaults.mo": defaults_text(), "Cases.mo": cases_text(), "package.order": order_text()}
    out["Systems.mo"] = systems_text((Path(directory) / "Systems.mo").read_text(encoding="utf-8"))
    for u in modelica_units():
        if u.modelica is not None:
            out[u.modelica.file] = unit_file_text(u.modelica.source)
    return out


def write(directory: Path = PACKAGE_DIR) -> list[Path]:
    """Write the generated files into the package directory; returns the paths written."""
    directory = Path(directory)
    out = []
    for name, text in generated_files(directory).items():
        path = directory / name
        path.write_text(text, encoding="utf-8")
        out.append(path)
    return out


def stale_files(directory: Path = PACKAGE_DIR) -> list[str]:
    """Names of generated files whose committed text differs from the generated one."""
    directory = Path(directory)
    bad = []
    for name, text in generated_files(directory).items():
        path = directory / name
        if not path.is_file() or path.read_text(encoding="utf-8") != text:
            bad.append(name)
    return bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dir", type=Path, default=PACKAGE_DIR, help="package directory (default: %(default)s)")
    ap.add_argument("--check", action="store_true", help="only check that the files are up to date")
    a = ap.parse_args(argv)
    if not (a.dir / "Systems.mo").is_file():
        print(f"{a.dir}: not a TMDInerter package directory (no Systems.mo)", file=sys.stderr)
        return 2
    if a.check:
        bad = stale_files(a.dir)
        if bad:
            print(
                f"stale generated Modelica files in {a.dir}: {', '.join(bad)}; "
                "run `python -m pyfmu_wrapper.generate.modelica`",
                file=sys.stderr,
            )
            return 1
        return 0
    for p in write(a.dir):
        print(p)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
