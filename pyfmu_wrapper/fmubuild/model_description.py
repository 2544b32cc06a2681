"""Generate ``modelDescription.xml`` (FMI 2.0 co-simulation) and the stub's variable table.

Both are produced from one :class:`~pyfmu_wrapper.fmi.varspec.FmuSpec`; nothing is written by hand. The
UnitDefinitions are read off the unit strings by FMI's unit grammar (:func:`~pyfmu_wrapper.fmi.units.base_unit`).
"""

from __future__ import annotations

import hashlib
import math
import sys
import uuid
from collections.abc import Sequence
from xml.sax.saxutils import quoteattr

from ..fmi.contract import LOG_CATEGORIES
from ..fmi.units import base_unit
from ..fmi.varspec import BOOLEAN, INTEGER, REAL, FmuSpec, Variable

TYPE_CODE = {REAL: "R", INTEGER: "I", BOOLEAN: "B"}


def xml_value(v: float | int | bool | str) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def _variable_xml(spec: FmuSpec, v: Variable) -> str:
    attrs = (
        f'name={quoteattr(v.name)} valueReference="{v.vr}" description={quoteattr(v.description)} '
        f'causality="{v.causality}" variability="{v.variability}"'
    )
    if v.initial is not None and v.causality != "input":
        attrs += f' initial="{v.initial}"'
    inner = ""
    if v.derivative_of is not None:
        inner += f' derivative="{spec.index(v.derivative_of)}"'
    if v.type == REAL and v.unit:
        inner += f' unit="{v.unit}"'
    if v.start is not None:
        start = bool(v.start) if v.type == BOOLEAN else (int(v.start) if v.type == INTEGER else float(v.start))
        inner += f' start="{xml_value(start)}"'
    lo, hi = declared_range(v)
    if lo is not None:
        inner += f' min="{xml_value(lo)}"'
    if hi is not None:
        inner += f' max="{xml_value(hi)}"'
    return f"    <ScalarVariable {attrs}>\n      <{v.type}{inner}/>\n    </ScalarVariable>"


def declared_range(v: Variable) -> tuple[float | int | None, float | int | None]:
    """(min, max) as declared in modelDescription.xml: FMI's min is inclusive, so an exclusive
    minimum m is declared as the next value above m (the next double, 2.2250738585072014e-308 for
    m = 0; m + 1 for an Integer); the stub refuses m itself."""
    lo = v.min
    if lo is not None:
        if v.type == INTEGER:
            lo = int(lo) + (1 if v.min_exclusive else 0)
        else:
            lo = float(lo)
            if v.min_exclusive:  # > 0: the smallest normal double (a subnormal may not parse everywhere)
                lo = sys.float_info.min if lo == 0.0 else math.nextafter(lo, math.inf)
    hi = None if v.max is None else (int(v.max) if v.type == INTEGER else float(v.max))
    return lo, hi


def _unknown(spec: FmuSpec, v: Variable, deps: Sequence[str] | None, kinds: Sequence[str] | None) -> str:
    s = f'      <Unknown index="{spec.index(v.name)}"'
    if deps is not None:
        s += f' dependencies="{" ".join(str(spec.index(d)) for d in deps)}"'
        if kinds is not None and deps:
            s += f' dependenciesKind="{" ".join(kinds)}"'
    return s + "/>"


def unit_exponents(spec: FmuSpec, unit: str) -> dict[str, int]:
    """The BaseUnit exponents of a unit string of ``spec`` (a bad string refused with the FMU and the
    variables that use it named)."""
    users = ", ".join(repr(v.name) for v in spec.variables if v.unit == unit) or "(none)"
    return base_unit(unit, where=f"FMU {spec.model_name}, variable(s) {users}")


def guid_of(spec: FmuSpec, salt: str = "") -> str:
    """A deterministic GUID: a hash of the variable table (and of the sources, through salt)."""
    h = hashlib.sha256(repr(spec.variables).encode() + spec.model_name.encode() + salt.encode()).digest()
    return "{" + str(uuid.UUID(bytes=h[:16])) + "}"


def initial_unknowns(spec: FmuSpec) -> list[Variable]:
    """What is computed in initialisation (FMI 2.0 / 3.0 InitialUnknowns): the outputs and calculated
    parameters, and with Model Exchange the states and their derivatives that are calculated."""
    me = {v.name for v in spec.states() + spec.derivatives() if v.initial in (None, "approx", "calculated")}
    return [
        v
        for v in spec.variables
        if (v.causality == "output" and v.initial in (None, "approx", "calculated"))
        or v.causality == "calculatedParameter"
        or v.name in me
    ]


def me_dependencies(spec: FmuSpec, v: Variable) -> tuple[str, ...] | None:
    """The dependencies an output declares: with Model Exchange (states among the knowns) none are listed,
    which FMI reads as "on every known" (the co-simulation's list names inputs only)."""
    return None if spec.derivatives() else v.depends_on


def model_description_xml(
    spec: FmuSpec, guid: str, generation_tool: str = "pyfmu_wrapper", model_exchange: bool = False
) -> str:
    """The complete FMI 2.0 modelDescription.xml of spec: co-simulation, and Model Exchange too when asked
    (``model_exchange``: the binary implements it; the spec must declare states)."""
    if model_exchange and not spec.derivatives():
        raise ValueError(f"{spec.model_name}: Model Exchange needs states (variables with derivative_of)")
    used_units = sorted({v.unit for v in spec.variables if v.unit})
    units = []
    for u in used_units:
        exps = " ".join(f'{k}="{e}"' for k, e in unit_exponents(spec, u).items())
        units.append(f'    <Unit name="{u}">\n      <BaseUnit {exps}/>\n    </Unit>')
    outputs = spec.of("output")
    init_unknowns = initial_unknowns(spec)
    me = (
        f'  <ModelExchange modelIdentifier="{spec.model_identifier}" canGetAndSetFMUstate="true" '
        f'canSerializeFMUstate="true" providesDirectionalDerivative="true" canNotUseMemoryManagementFunctions="true" '
        f'completedIntegratorStepNotNeeded="true"/>'
    )
    cs = (
        f'  <CoSimulation modelIdentifier="{spec.model_identifier}" canHandleVariableCommunicationStepSize="true" '
        f'canInterpolateInputs="{str(spec.can_interpolate_inputs).lower()}" '
        f'maxOutputDerivativeOrder="{spec.max_output_derivative_order}" '
        f'canGetAndSetFMUstate="true" canSerializeFMUstate="true" '
        f'providesDirectionalDerivative="{str(spec.provides_directional_derivative).lower()}" '
        f'canNotUseMemoryManagementFunctions="true"/>'
    )
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{spec.model_name}" guid="{guid}" '
        f'description={quoteattr(spec.description)} generationTool="{generation_tool}" '
        f'variableNamingConvention="flat" numberOfEventIndicators="{len(spec.event_indicators())}">',
        *([me] if model_exchange else []),
        cs,
        *(["  <UnitDefinitions>", *units, "  </UnitDefinitions>"] if units else []),
        "  <LogCategories>",
        *[f'    <Category name="{c}"/>' for c in LOG_CATEGORIES],
        "  </LogCategories>",
        f'  <DefaultExperiment startTime="0.0" stepSize="{xml_value(spec.default_step)}"/>',
        "  <ModelVariables>",
    ]
    for v in spec.variables:
        lines.append(f"    <!-- index {spec.index(v.name)} -->")
        lines.append(_variable_xml(spec, v))
    lines.append("  </ModelVariables>")
    lines.append("  <ModelStructure>")
    if outputs:
        lines.append("    <Outputs>")
        for v in outputs:
            out_deps = me_dependencies(spec, v)
            lines.append(_unknown(spec, v, out_deps, None if out_deps is None else v.dependencies_kind))
        lines.append("    </Outputs>")
    if spec.derivatives():
        lines.append("    <Derivatives>")
        lines += [_unknown(spec, v, None, None) for v in spec.derivatives()]
        lines.append("    </Derivatives>")
    if init_unknowns:
        lines.append("    <InitialUnknowns>")
        for v in sorted(init_unknowns, key=lambda v: spec.index(v.name)):
            deps = None if v.initial_depends_on is None else sorted(v.initial_depends_on, key=spec.index)
            lines.append(_unknown(spec, v, deps, None))
        lines.append("    </InitialUnknowns>")
    lines.append("  </ModelStructure>")
    lines.append("</fmiModelDescription>")
    return "\n".join(lines) + "\n"


def variable_table_tsv(spec: FmuSpec) -> str:
    """The table the C stub reads, one variable per line: vr, type code, causality, variability,
    name, minimum, maximum (``-inf`` / ``inf``: none; the registry's bounds, for messages), 1 if
    the minimum is exclusive, else 0, and the minimum declared in modelDescription.xml
    (:func:`declared_range`), which is what the stub enforces: "> 0" refuses the subnormals too."""

    def bound(x: float | None, default: str) -> str:
        return default if x is None else repr(float(x))

    rows = [
        f"{v.vr}\t{TYPE_CODE[v.type]}\t{v.causality}\t{v.variability}\t{v.name}\t{bound(v.min, '-inf')}\t"
        f"{bound(v.max, 'inf')}\t{int(v.min_exclusive)}\t{bound(declared_range(v)[0], '-inf')}"
        for v in spec.variables
    ]
    return "\n".join(rows) + "\n"
