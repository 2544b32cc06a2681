"""Export a coupled system of FMUs as an SSP 1.0 file (System Structure and Parameterization).

The archive holds ``SystemStructure.ssd`` (components, their connectors, the connections, a
default experiment), the FMUs under ``resources/`` and the parameter values in
``resources/parameters.ssv``, bound at system level (names ``instance.variable``). Any SSP/FMI
tool can run it; with fmpy::

    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import read_ssv
    ps = read_ssv("system.ssp", "resources/parameters.ssv")
    res = simulate_ssp("system.ssp", stop_time=3.0, step_size=1e-4, parameter_set=ps)

(fmpy's simulate_ssp applies parameter values only through its ``parameter_set`` argument; it
steps the components with a fixed step, zero-order hold and no loop handling, i.e. the naive
Jacobi scheme of :mod:`.master`, so it needs a small step.) :func:`ssp_parameter_set` returns the
same parameter set without reading the file back.

OMSimulator loads an SSP only if its system carries OMSimulator's own annotation naming a master
algorithm (SSP 1.0 has no standard element for it; OMSimulator issues #872, #1094, #1318: without
it, ``[NewSystem] internal error``). Given a ``step_size``, :func:`ssd_xml` writes its vendor
annotations (``type="org.openmodelica"``): on the system, OMSimulator's default fixed-step master
``oms-ma`` with that step and its default relative tolerance 1e-4; on the default experiment, its
default result settings (``<name>_res.mat``, every step, buffer of 10), without which it warns of
"wrong/deprecated content". Other tools ignore them (fmpy validates the file against the SSP 1.0
schema with them, and so does OMSimulator).
"""

from __future__ import annotations

import os
import zipfile
from pathlib import Path
from typing import TYPE_CHECKING
from xml.sax.saxutils import quoteattr

from fmpy import read_model_description

from .graph import Connection, build_graph

if TYPE_CHECKING:
    from fmpy.ssp.ssd import ParameterSet
    from numpy import float64

    from .graph import Connection

_NS = (
    'xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" '
    'xmlns:ssd="http://ssp-standard.org/SSP1/SystemStructureDescription" '
    'xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues"'
)

_OMS_NS = 'xmlns:oms="https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"'
#: OMSimulator's default relative tolerance (its --tolerance), written into its annotation.
_OMS_TOLERANCE = 1e-4

_TYPE_TAG = {"Real": "Real", "Integer": "Integer", "Enumeration": "Integer", "Boolean": "Boolean", "String": "String"}


def _fmt(value: float | float64 | int, type_: str) -> str:
    if type_ == "Real":
        return repr(float(value))
    if type_ in ("Integer", "Enumeration"):
        return str(int(value))
    if type_ == "Boolean":
        return "true" if bool(value) else "false"
    return str(value)


def ssd_xml(
    name: str,
    fmus: dict,
    connections: list[Connection],
    start_time: float = 0.0,
    stop_time: float | None = None,
    step_size: float | None = None,
) -> str:
    """The SystemStructure.ssd text (FMUs referenced as resources/<file name>); with ``step_size``
    [s], also OMSimulator's system annotation (its fixed-step master with that step)."""
    if step_size is not None and not (0.0 < float(step_size) < float("inf")):
        raise ValueError(f"step_size must be a positive finite number of seconds, got {step_size!r}")
    mds = {inst: read_model_description(str(p)) for inst, p in fmus.items()}
    graph = build_graph(mds, connections)  # validates the connection list
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f"<ssd:SystemStructureDescription {_NS}{' ' + _OMS_NS if step_size is not None else ''} "
        f'version="1.0" name={quoteattr(name)}>',
        f"  <ssd:System name={quoteattr(name)}>",
        "    <ssd:Elements>",
    ]
    for inst, path in fmus.items():
        md = mds[inst]
        lines.append(
            f'      <ssd:Component name={quoteattr(inst)} type="application/x-fmu-sharedlibrary" '
            f"source={quoteattr('resources/' + Path(path).name)}>"
        )
        lines.append("        <ssd:Connectors>")
        for v in md.modelVariables:
            if v.causality not in ("input", "output", "parameter"):
                continue
            tag = _TYPE_TAG.get(v.type, "Real")
            lines.append(
                f'          <ssd:Connector name={quoteattr(v.name)} kind="{v.causality}"><ssc:{tag}/></ssd:Connector>'
            )
        lines.append("        </ssd:Connectors>")
        lines.append("      </ssd:Component>")
    lines.append("    </ssd:Elements>")
    lines.append("    <ssd:Connections>")
    for c in graph.connections:
        lines.append(
            f"      <ssd:Connection startElement={quoteattr(c.src_instance)} "
            f"startConnector={quoteattr(c.src_variable)} endElement={quoteattr(c.dst_instance)} "
            f"endConnector={quoteattr(c.dst_variable)}/>"
        )
    lines.append("    </ssd:Connections>")
    if step_size is not None:  # last child of the system, as the schema orders it
        lines += [
            "    <ssd:Annotations>",
            '      <ssc:Annotation type="org.openmodelica">',
            "        <oms:Annotations>",
            "          <oms:SimulationInformation>",
            f'            <oms:FixedStepMaster description="oms-ma" stepSize="{float(step_size)!r}" '
            f'relativeTolerance="{_OMS_TOLERANCE!r}"/>',
            "          </oms:SimulationInformation>",
            "        </oms:Annotations>",
            "      </ssc:Annotation>",
            "    </ssd:Annotations>",
        ]
    lines.append("  </ssd:System>")
    stop = "" if stop_time is None else f' stopTime="{float(stop_time)!r}"'
    if step_size is None:
        lines.append(f'  <ssd:DefaultExperiment startTime="{float(start_time)!r}"{stop}/>')
    else:  # OMSimulator's result settings, its defaults (without them it warns of deprecated content)
        lines += [
            f'  <ssd:DefaultExperiment startTime="{float(start_time)!r}"{stop}>',
            "    <ssd:Annotations>",
            '      <ssc:Annotation type="org.openmodelica">',
            "        <oms:Annotations>",
            f"          <oms:SimulationInformation resultFile={quoteattr(name + '_res.mat')} "
            'loggingInterval="0.0" bufferSize="10"/>',
            "        </oms:Annotations>",
            "      </ssc:Annotation>",
            "    </ssd:Annotations>",
            "  </ssd:DefaultExperiment>",
        ]
    lines.append("</ssd:SystemStructureDescription>")
    # the parameters are bound at system level (inserted before Elements, as the schema orders them)
    i = lines.index("    <ssd:Elements>")
    lines[i:i] = [
        "    <ssd:ParameterBindings>",
        '      <ssd:ParameterBinding source="resources/parameters.ssv"/>',
        "    </ssd:ParameterBindings>",
    ]
    return "\n".join(lines) + "\n"


def ssv_xml(name: str, fmus: dict, parameters: dict) -> str:
    """The parameter set (``instance.variable`` names, typed as in the FMUs)."""
    mds = {inst: read_model_description(str(p)) for inst, p in fmus.items()}
    lines = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<ssv:ParameterSet {_NS} version="1.0" name={quoteattr(name)}>',
        "  <ssv:Parameters>",
    ]
    for key, value in parameters.items():
        inst, var = key.split(".", 1)
        if inst not in mds:
            raise ValueError(f"parameter {key!r}: unknown instance {inst!r}")
        v = next((v for v in mds[inst].modelVariables if v.name == var), None)
        if v is None:
            raise ValueError(f"parameter {key!r}: {inst} has no variable {var!r}")
        tag = _TYPE_TAG.get(v.type, "Real")
        lines.append(
            f'    <ssv:Parameter name={quoteattr(key)}><ssv:{tag} value="{_fmt(value, v.type)}"/></ssv:Parameter>'
        )
    lines.append("  </ssv:Parameters>")
    lines.append("</ssv:ParameterSet>")
    return "\n".join(lines) + "\n"


def export_ssp(
    path: str | os.PathLike[str],
    fmus: dict,
    connections: tuple[str, str, str, str],
    parameters: dict,
    name: str = "CoupledSystem",
    start_time: float = 0.0,
    stop_time: float | None = None,
    step_size: float | None = None,
) -> Path:
    """Write the SSP archive: the SSD, the FMUs and the parameter values. Returns the path.
    step_size: see :func:`ssd_xml` (needed by OMSimulator)."""
    path = Path(path)
    conns = [Connection.parse(c) for c in connections]
    ssd = ssd_xml(name, fmus, conns, start_time, stop_time, step_size)
    ssv = ssv_xml(name, fmus, parameters)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("SystemStructure.ssd", ssd)
        zf.writestr("resources/parameters.ssv", ssv)
        for p in fmus.values():
            zf.write(str(p), "resources/" + Path(p).name)
    tmp.replace(path)
    return path


def ssp_parameter_set(path: str | os.PathLike[str]) -> ParameterSet:
    """The parameter set stored in an exported SSP file, as fmpy's ``simulate_ssp`` takes it."""
    from fmpy.ssp.ssd import read_ssv

    return read_ssv(str(path), "resources/parameters.ssv")
