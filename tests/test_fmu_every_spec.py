"""Every FMU the project declares (``fmi.catalog.SPECS``, gathered from the registered units), tested alike: no FMU is named here.

For each declared FMU, Python-hosted, FMI 2.0 and 3.0:

* fmpy's validation passes and the FMI 3.0 description declares every FMI 2.0 variable the same way
  (value reference, causality, variability, unit, start, range), plus ``time`` and the input
  derivatives;
* the directional derivative of every output with respect to every input it declares to depend on
  equals a central difference of the outputs, and an output that declares no dependency on an input
  does not move with it (the ModelStructure is true);
* a short fuzz run in the C host (random call sequences: wrong states, bad value references, NaN and
  huge steps, state get/set/serialize) has no crash, no hang, every invalid call refused and logged.
"""

from __future__ import annotations

import math
from pathlib import Path

import fmpy
import pytest
from _fmu_support import run_fuzz
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu
from test_fmu_fuzz import check

from pyfmu_wrapper.fmi.varspec import REAL, FmuSpec
from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.fmubuild.model_description3 import derivative_vr, time_vr
from pyfmu_wrapper.models.catalog import FMUS, SPECS, pick

NAMES = sorted(SPECS)


@pytest.fixture(scope="module")
def fmus2() -> dict[str, Path]:
    return ensure_fmus(pick(NAMES))


@pytest.fixture(scope="module")
def fmus3() -> dict[str, Path]:
    return ensure_fmus(pick(NAMES), fmi_version=3)


@pytest.mark.parametrize("name", NAMES)
def test_fmpy_validates_both_versions_and_they_declare_the_same_variables(fmus2, fmus3, name):
    assert validate_fmu(str(fmus2[name])) == []
    assert validate_fmu(str(fmus3[name])) == []
    md2, md3 = fmpy.read_model_description(str(fmus2[name])), fmpy.read_model_description(str(fmus3[name]))
    assert (md2.fmiVersion, md3.fmiVersion) == ("2.0", "3.0")
    v2 = {v.name: v for v in md2.modelVariables}
    v3 = {v.name: v for v in md3.modelVariables}
    spec = SPECS[name]
    assert set(v2) == {v.name for v in spec.variables}
    inputs = [v for v in spec.variables if v.causality == "input"]
    assert set(v3) - set(v2) == {"time"} | {f"der({u.name})" for u in inputs} | {f"der({u.name},2)" for u in inputs}
    for n, a in v2.items():
        b = v3[n]
        key = ("valueReference", "causality", "variability", "unit", "min", "max")
        assert [getattr(a, k) for k in key] == [getattr(b, k) for k in key], n
        assert (a.start is None) == (b.start is None) and (a.start is None or float(a.start) == float(b.start)), n
    assert v3["time"].valueReference == time_vr(spec)
    for u in inputs:
        assert v3[f"der({u.name})"].valueReference == derivative_vr(spec, u.vr, 1)


def _reals(spec: FmuSpec, causality: str) -> list:
    return [v for v in spec.variables if v.causality == causality and v.type == REAL]


@pytest.mark.parametrize("name", NAMES)
def test_directional_derivatives_are_the_central_difference_and_the_dependencies_are_true(fmus2, tmp_path, name):
    spec = SPECS[name]
    inputs, outputs = _reals(spec, "input"), _reals(spec, "output")
    if FMUS[name].system:  # the whole structure in one FMU: no inputs, its parameters are the knowns
        assert not inputs and outputs, f"{name}: a system FMU has outputs and no inputs"
        _parameter_derivatives(fmus2[name], tmp_path, name, outputs)
        return
    assert inputs and outputs, f"{name}: a co-simulation FMU of this project has real inputs and outputs"
    md = fmpy.read_model_description(str(fmus2[name]))
    d = tmp_path / name
    fmpy.extract(str(fmus2[name]), str(d))
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier=name, instanceName="dd")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        # leave the rest state: inputs of a few newtons for a few steps
        base = [0.7 + 0.3 * k for k in range(len(inputs))]
        s.setReal([u.vr for u in inputs], base)
        for k in range(5):
            s.doStep(currentCommunicationPoint=0.01 * k, communicationStepSize=0.01)
        u0 = [0.4 - 0.5 * k for k in range(len(inputs))]
        s.setReal([u.vr for u in inputs], u0)
        out_vrs = [y.vr for y in outputs]
        checked = 0
        for i, u in enumerate(inputs):
            h = 1e-3 * max(1.0, abs(u0[i]))
            s.setReal([u.vr], [u0[i] + h])
            plus = s.getReal(out_vrs)
            s.setReal([u.vr], [u0[i] - h])
            minus = s.getReal(out_vrs)
            s.setReal([u.vr], [u0[i]])
            dd = s.getDirectionalDerivative(out_vrs, [u.vr], [1.0])
            for j, y in enumerate(outputs):
                fd = (plus[j] - minus[j]) / (2 * h)
                scale = max(1.0, abs(fd), abs(dd[j]))
                if u.name in y.depends_on:
                    assert math.isfinite(dd[j]) and abs(dd[j] - fd) <= 1e-6 * scale, (y.name, u.name, dd[j], fd)
                    checked += 1
                else:  # no declared dependency: the output does not move with the input
                    assert abs(fd) <= 1e-9 * scale and dd[j] == 0.0, (y.name, u.name, dd[j], fd)
        assert checked > 0, f"{name}: no output declares a dependency on an input"
        s.terminate()
    finally:
        s.freeInstance()


def _parameter_derivatives(fmu: Path, tmp_path: Path, name: str, outputs: list) -> None:
    """In initialisation mode, the directional derivative of every output with respect to the excitation's
    amplitude F and frequency w and the start states (set away from 0 first: the FMU's own difference step is
    relative to the value) equals a central difference of the outputs."""
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / name
    fmpy.extract(str(fmu), str(d))
    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier=name, instanceName="dd")
    s.instantiate()
    try:
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        vr = {v.name: v.valueReference for v in md.modelVariables}
        starts = [n for n in vr if n in ("x0", "xd0", "x0_1", "xd0_1", "y0", "yd0")]
        s.setReal([vr[n] for n in starts], [(1e-2 if n.startswith(("x0", "y0")) else 0.1) for n in starts])
        out_vrs = [y.vr for y in outputs]
        moved = 0
        for p in ("F", "w", *starts):
            p0 = s.getReal([vr[p]])[0]
            h = 1e-4 * max(1.0, abs(p0))
            s.setReal([vr[p]], [p0 + h])
            plus = s.getReal(out_vrs)
            s.setReal([vr[p]], [p0 - h])
            minus = s.getReal(out_vrs)
            s.setReal([vr[p]], [p0])
            dd = s.getDirectionalDerivative(out_vrs, [vr[p]], [1.0])
            for j, y in enumerate(outputs):
                fd = (plus[j] - minus[j]) / (2 * h)
                assert abs(dd[j] - fd) <= 1e-6 * max(1.0, abs(fd)), (y.name, p, dd[j], fd)
                moved += fd != 0.0
        assert moved > 0, f"{name}: no output moves with its parameters"
        s.exitInitializationMode()
        s.terminate()
    finally:
        s.freeInstance()


@pytest.mark.parametrize("name", NAMES)
def test_fuzz_smoke_in_the_c_host(tmp_path, name):
    """12 random sequences on the FMU and the TMDInerter (state handed across FMUs is refused)."""
    other = "TMDInerter" if name != "TMDInerter" else "BaseOscillator"
    check(run_fuzz(tmp_path, 12, 120, seed=31, names=(name, other)), 12)
