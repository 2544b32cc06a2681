"""Generate ``modelDescription.xml`` (FMI 2.0 co-simulation) and the stub's variable table.

Both are produced from one :class:`~.variables.FmuSpec`; nothing is written by hand.
"""
from __future__ import annotations

import hashlib
import uuid
from xml.sax.saxutils import quoteattr

from .variables import BOOLEAN, INTEGER, REAL, FmuSpec, Variable

#: SI base-unit exponents of the units the tables use (FMI 2.0 UnitDefinitions).
UNITS = {
    "kg": dict(kg=1),
    "m": dict(m=1),
    "m/s": dict(m=1, s=-1),
    "m/s2": dict(m=1, s=-2),
    "N": dict(kg=1, m=1, s=-2),
    "N/m": dict(kg=1, s=-2),
    "N/m3": dict(kg=1, m=-2, s=-2),
    "N.s/m": dict(kg=1, s=-1),
    "rad/s": dict(rad=1, s=-1),
    "s/m": dict(s=1, m=-1),
    "1/kg": dict(kg=-1),
}

#: Log categories the stub uses (keep in sync with fmi2SetDebugLogging in fmu/src/pyfmu_stub.c).
LOG_CATEGORIES = ("logStatusError", "logStatusWarning", "logAll")

TYPE_CODE = {REAL: "R", INTEGER: "I", BOOLEAN: "B"}


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    return repr(float(v))


def _variable_xml(v: Variable) -> str:
    attrs = f'name={quoteattr(v.name)} valueReference="{v.vr}" description={quoteattr(v.description)} ' \
            f'causality="{v.causality}" variability="{v.variability}"'
    if v.initial is not None and v.causality != "input":
        attrs += f' initial="{v.initial}"'
    inner = ""
    if v.type == REAL and v.unit:
        inner += f' unit="{v.unit}"'
    if v.start is not None:
        start = bool(v.start) if v.type == BOOLEAN else (int(v.start) if v.type == INTEGER else float(v.start))
        inner += f' start="{_fmt(start)}"'
    return f'    <ScalarVariable {attrs}>\n      <{v.type}{inner}/>\n    </ScalarVariable>'


def _unknown(spec: FmuSpec, v: Variable, deps, kinds) -> str:
    s = f'      <Unknown index="{spec.index(v.name)}"'
    if deps is not None:
        s += f' dependencies="{" ".join(str(spec.index(d)) for d in deps)}"'
        if kinds is not None and deps:
            s += f' dependenciesKind="{" ".join(kinds)}"'
    return s + "/>"


def guid_of(spec: FmuSpec, salt: str = "") -> str:
    """A deterministic GUID: a hash of the variable table (and of the sources, through salt)."""
    h = hashlib.sha256(repr(spec.variables).encode() + spec.model_name.encode() + salt.encode()).digest()
    return "{" + str(uuid.UUID(bytes=h[:16])) + "}"


def model_description_xml(spec: FmuSpec, guid: str, generation_tool: str = "pyfmu_wrapper") -> str:
    """The complete FMI 2.0 co-simulation modelDescription.xml of spec."""
    used_units = sorted({v.unit for v in spec.variables if v.unit})
    units = []
    for u in used_units:
        exps = " ".join(f'{k}="{e}"' for k, e in UNITS[u].items())
        units.append(f'    <Unit name="{u}">\n      <BaseUnit {exps}/>\n    </Unit>')
    outputs = spec.of("output")
    init_unknowns = [v for v in spec.variables
                     if (v.causality == "output" and v.initial in (None, "approx", "calculated"))
                     or v.causality == "calculatedParameter"]
    cs = (f'  <CoSimulation modelIdentifier="{spec.model_identifier}" canHandleVariableCommunicationStepSize="true" '
          f'canInterpolateInputs="{str(spec.can_interpolate_inputs).lower()}" '
          f'maxOutputDerivativeOrder="{spec.max_output_derivative_order}" '
          f'canGetAndSetFMUstate="true" canSerializeFMUstate="true" '
          f'providesDirectionalDerivative="{str(spec.provides_directional_derivative).lower()}" '
          f'canNotUseMemoryManagementFunctions="true"/>')
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="2.0" modelName="{spec.model_name}" guid="{guid}" '
        f'description={quoteattr(spec.description)} generationTool="{generation_tool}" '
        f'variableNamingConvention="flat" numberOfEventIndicators="0">',
        cs,
        *(["  <UnitDefinitions>", *units, "  </UnitDefinitions>"] if units else []),
        "  <LogCategories>",
        *[f'    <Category name="{c}"/>' for c in LOG_CATEGORIES],
        "  </LogCategories>",
        f'  <DefaultExperiment startTime="0.0" stepSize="{_fmt(spec.default_step)}"/>',
        "  <ModelVariables>",
    ]
    for v in spec.variables:
        lines.append(f"    <!-- index {spec.index(v.name)} -->")
        lines.append(_variable_xml(v))
    lines.append("  </ModelVariables>")
    lines.append("  <ModelStructure>")
    if outputs:
        lines.append("    <Outputs>")
        for v in outputs:
            lines.append(_unknown(spec, v, v.depends_on, v.dependencies_kind))
        lines.append("    </Outputs>")
    if init_unknowns:
        lines.append("    <InitialUnknowns>")
        for v in sorted(init_unknowns, key=lambda v: spec.index(v.name)):
            deps = v.initial_depends_on
            if deps is not None:
                deps = sorted(deps, key=spec.index)
            lines.append(_unknown(spec, v, deps, None))
        lines.append("    </InitialUnknowns>")
    lines.append("  </ModelStructure>")
    lines.append("</fmiModelDescription>")
    return "\n".join(lines) + "\n"


def variable_table_tsv(spec: FmuSpec) -> str:
    """The table the C stub reads: vr, type code, causality, variability, name (one per line)."""
    rows = [f"{v.vr}\t{TYPE_CODE[v.type]}\t{v.causality}\t{v.variability}\t{v.name}" for v in spec.variables]
    return "\n".join(rows) + "\n"
