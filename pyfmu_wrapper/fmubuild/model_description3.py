"""Generate the FMI 3.0 co-simulation ``modelDescription.xml`` from the same :class:`~.variables.FmuSpec`
as the FMI 2.0 one (:mod:`.model_description`): one table, two writers.

What FMI 3.0 declares differently, and the rule this writer shares with the stub's FMI 3.0 layer
(``fmu/src/fmi3_api.c``; a test ties the two through the built FMU):

* Types: Real -> ``Float64``, Integer -> ``Int32``, Boolean -> ``Boolean``; units as attributes.
* ``time``, the independent variable FMI 3.0 requires, has the value reference ``N`` =
  (largest value reference of the table) + 1.
* FMI 3.0 has no ``fmi3SetInputDerivatives``: the derivative of order k (1, 2) of each continuous
  Real input ``u`` with value reference v is an input variable of its own, ``der(u)`` /
  ``der(u,2)``, with value reference ``N + 1 + 2 v + k - 1`` (what ``fmi2SetRealInputDerivatives``
  set in FMI 2.0: the FMU integrates with the input's Taylor polynomial over the step). They start
  at 0 and apply to the next doStep only: the FMU resets them to 0 after each step (as it does with
  FMI 2.0's input derivatives); setting the input itself leaves them as they are.
* ``<ModelStructure>`` refers to value references (FMI 2.0: indices).
"""

from __future__ import annotations

from collections.abc import Sequence
from xml.sax.saxutils import quoteattr

from ..fmi.contract import LOG_CATEGORIES
from ..fmi.units import base_unit, time_derivative
from ..fmi.varspec import BOOLEAN, INTEGER, REAL, FmuSpec, Variable
from .model_description import declared_range, initial_unknowns, me_dependencies, unit_exponents, xml_value

TYPE3 = {REAL: "Float64", INTEGER: "Int32", BOOLEAN: "Boolean"}
#: orders of the input derivatives an FMI 3.0 variant declares (FMI 2.0: canInterpolateInputs, order <= 2)
INPUT_DERIVATIVE_ORDERS = (1, 2)


def time_vr(spec: FmuSpec) -> int:
    """Value reference of ``time`` in the FMI 3.0 variant: N = largest value reference + 1 (of the binary's value
    space, :attr:`~pyfmu_wrapper.fmi.varspec.FmuSpec.vr_top`, where a shipped table leaves a test hook out: the
    stub puts ``time`` there too)."""
    return max(max(v.vr for v in spec.variables), -1 if spec.vr_top is None else spec.vr_top) + 1


def derivative_vr(spec: FmuSpec, input_vr: int, order: int) -> int:
    """Value reference of the order-``order`` derivative of the input with value reference ``input_vr``."""
    if order not in INPUT_DERIVATIVE_ORDERS:
        raise ValueError(f"input derivative order {order} (supported: {INPUT_DERIVATIVE_ORDERS})")
    return time_vr(spec) + 1 + 2 * input_vr + order - 1


def _derived_unit(unit: str | None, order: int) -> str | None:
    """The unit of the order-th time derivative: m -> m/s, m/s -> m/s2, N -> N/s2 (order 2)."""
    return None if unit is None else time_derivative(unit, order)


def input_derivatives(spec: FmuSpec) -> list[tuple[Variable, int, str | None]]:
    """(derivative variable, order, unit) of every continuous Real input."""
    out = []
    for u in spec.variables:
        if u.causality == "input" and u.type == REAL and u.variability == "continuous":
            for k in INPUT_DERIVATIVE_ORDERS:
                name = f"der({u.name})" if k == 1 else f"der({u.name},{k})"
                what = "first" if k == 1 else "second"
                v = Variable(
                    name=name,
                    vr=derivative_vr(spec, u.vr, k),
                    type=REAL,
                    causality="input",
                    variability="continuous",
                    description=f"{what} time derivative of the input {u.name} at the start of the step: the FMU "
                    f"integrates with the input's Taylor polynomial over the step (FMI 2.0: "
                    f"fmi2SetRealInputDerivatives order {k}); applies to the next doStep only (reset to 0 after it)",
                    unit=None,
                    start=0.0,
                )
                out.append((v, k, _derived_unit(u.unit, k)))
    return out


def _units_used(spec: FmuSpec) -> dict[str, dict[str, int]]:
    used = {v.unit: unit_exponents(spec, v.unit) for v in spec.variables if v.unit}
    for _, _, unit in input_derivatives(spec):
        if unit and unit not in used:
            used[unit] = base_unit(unit)
    used.setdefault("s", {"s": 1})  # of time
    return dict(sorted(used.items()))


def _variable3(v: Variable, unit: str | None = None, spec: FmuSpec | None = None) -> str:
    t = TYPE3[v.type]
    attrs = (
        f'name={quoteattr(v.name)} valueReference="{v.vr}" description={quoteattr(v.description)} '
        f'causality="{v.causality}" variability="{v.variability}"'
    )
    if v.initial is not None and v.causality != "input":
        attrs += f' initial="{v.initial}"'
    if v.derivative_of is not None and spec is not None:
        attrs += f' derivative="{spec.vr(v.derivative_of)}"'
    unit = unit if unit is not None else v.unit
    if v.type == REAL and unit:
        attrs += f' unit="{unit}"'
    lo, hi = declared_range(v)
    if lo is not None:
        attrs += f' min="{xml_value(lo)}"'
    if hi is not None:
        attrs += f' max="{xml_value(hi)}"'
    if v.start is not None:
        start = bool(v.start) if v.type == BOOLEAN else (int(v.start) if v.type == INTEGER else float(v.start))
        attrs += f' start="{xml_value(start)}"'
    return f"    <{t} {attrs}/>"


def _unknown3(spec: FmuSpec, tag: str, v: Variable, deps: Sequence[str] | None, kinds: Sequence[str] | None) -> str:
    s = f'    <{tag} valueReference="{v.vr}"'
    if deps is not None:
        s += f' dependencies="{" ".join(str(spec.vr(d)) for d in deps)}"'
        if kinds is not None and deps:
            s += f' dependenciesKind="{" ".join(kinds)}"'
    return s + "/>"


def model_description3_xml(
    spec: FmuSpec, token: str, generation_tool: str = "pyfmu_wrapper", model_exchange: bool = False
) -> str:
    """The complete FMI 3.0 modelDescription.xml of spec (instantiationToken = token, the FMI 2.0 variant's
    GUID: the same core, the same FMU states): co-simulation, and Model Exchange too when asked."""
    if model_exchange and not spec.derivatives():
        raise ValueError(f"{spec.model_name}: Model Exchange needs states (variables with derivative_of)")
    units = [
        f'    <Unit name="{u}">\n      <BaseUnit {" ".join(f"{k}={chr(34)}{e}{chr(34)}" for k, e in ex.items())}/>\n'
        f"    </Unit>"
        for u, ex in _units_used(spec).items()
    ]
    cs = (
        f'  <CoSimulation modelIdentifier="{spec.model_identifier}" canHandleVariableCommunicationStepSize="true" '
        f'canGetAndSetFMUState="true" canSerializeFMUState="true" '
        f'providesDirectionalDerivatives="{str(spec.provides_directional_derivative).lower()}" '
        f'hasEventMode="false" providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>'
    )
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<fmiModelDescription fmiVersion="3.0" modelName="{spec.model_name}" instantiationToken="{token}" '
        f'description={quoteattr(spec.description)} generationTool="{generation_tool}" '
        f'variableNamingConvention="flat">',
        *(
            [
                f'  <ModelExchange modelIdentifier="{spec.model_identifier}" canGetAndSetFMUState="true" '
                'canSerializeFMUState="true" providesDirectionalDerivatives="true"/>'
            ]
            if model_exchange
            else []
        ),
        cs,
        *(["  <UnitDefinitions>", *units, "  </UnitDefinitions>"] if units else []),
        "  <LogCategories>",
        *[f'    <Category name="{c}"/>' for c in LOG_CATEGORIES],
        "  </LogCategories>",
        f'  <DefaultExperiment startTime="0.0" stepSize="{xml_value(spec.default_step)}"/>',
        "  <ModelVariables>",
        f'    <Float64 name="time" valueReference="{time_vr(spec)}" causality="independent" '
        f'variability="continuous" description="simulation time" unit="s"/>',
    ]
    for v in spec.variables:
        lines.append(_variable3(v, spec=spec))
    for v, _, unit in input_derivatives(spec):
        lines.append(_variable3(v, unit))
    lines.append("  </ModelVariables>")
    lines.append("  <ModelStructure>")
    for v in spec.of("output"):
        out_deps = me_dependencies(spec, v)
        lines.append(_unknown3(spec, "Output", v, out_deps, None if out_deps is None else v.dependencies_kind))
    for v in spec.derivatives():
        lines.append(_unknown3(spec, "ContinuousStateDerivative", v, None, None))
    for v in sorted(initial_unknowns(spec), key=lambda v: v.vr):
        deps = None if v.initial_depends_on is None else sorted(v.initial_depends_on, key=spec.vr)
        lines.append(_unknown3(spec, "InitialUnknown", v, deps, None))
    for v in spec.event_indicators():
        lines.append(_unknown3(spec, "EventIndicator", v, None, None))
    lines.append("  </ModelStructure>")
    lines.append("</fmiModelDescription>")
    return "\n".join(lines) + "\n"
