"""The doStep contract is declared once (pyfmu_wrapper/fmi/contract.py) and the compiled stub keeps it.

The C sources define none of its constants (they include the header the build generates from the
table), and the built FMU accepts and refuses steps exactly at the table's limits: the longest
step MAX_STEP and the time slack TIME_SLACK h (a test ties C and Python).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import fmpy
import pytest
from _fmu_support import built_fmus
from fmpy.fmi2 import FMU2Slave

from pyfmu_wrapper.fmi import contract

SRC = Path(__file__).resolve().parents[1] / "fmu" / "src"


def test_c_sources_define_none_of_the_contract():
    for f in sorted(SRC.glob("*.[ch]")):
        for name in contract.C_CONSTANTS:
            assert not re.search(rf"#define\s+{name}\b", f.read_text()), f"{f.name} defines {name}"
    header = contract.c_header()
    for name, value in contract.C_CONSTANTS.items():
        assert f"#define {name} {value}" in header
    # the literals are the Python values, exactly
    assert float(contract.C_CONSTANTS["PYFMU_MAX_STEP"]) == contract.MAX_STEP
    assert float(contract.C_CONSTANTS["PYFMU_TIME_SLACK"]) == contract.TIME_SLACK
    assert int(contract.C_CONSTANTS["PYFMU_NATIVE_OK"], 16) == contract.NATIVE_OK


@pytest.fixture()
def trivial(tmp_path):
    fmu = built_fmus()["Trivial"]
    md = fmpy.read_model_description(str(fmu))
    d = tmp_path / "trivial"
    fmpy.extract(str(fmu), str(d))
    log = []

    s = FMU2Slave(guid=md.guid, unzipDirectory=str(d), modelIdentifier="Trivial", instanceName="contract")
    from fmpy.fmi2 import fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

    cb = fmi2CallbackFunctions()
    cb.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: log.append(msg.decode()))
    s.instantiate(callbacks=cb)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    yield s, log, cb
    s.terminate()
    s.freeInstance()


def _step(s, t, h) -> int:
    """fmi2DoStep's status, from the raw function (fmpy's wrapper raises on an error status)."""
    import ctypes

    f = s.dll.fmi2DoStep
    f.argtypes, f.restype = [ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int], ctypes.c_int
    return f(s.component, t, h, 1)


def test_longest_step_is_the_tables(trivial):
    s, log, _ = trivial
    too_long = math.nextafter(contract.MAX_STEP, math.inf)
    assert _step(s, 0.0, too_long) == 3
    assert f"{contract.MAX_STEP:g} s this FMU accepts" in log[-1]
    assert _step(s, 0.0, contract.MAX_STEP) == 0  # exactly the limit: accepted


def test_time_slack_is_the_tables(trivial):
    s, log, _ = trivial
    h = 1.0
    assert _step(s, 0.0, h) == 0  # the FMU's time is now 1.0
    off = contract.TIME_SLACK * h
    assert _step(s, 1.0 + 1.5 * off, h) == 3  # beyond the slack: refused
    assert "expected currentCommunicationPoint" in log[-1]
    assert _step(s, 1.0 + 0.5 * off, h) == 0  # within it: accepted (the host's time is taken)


def test_log_categories_are_the_tables(trivial):
    """One declaration of the log categories: the stub logs under no other (source scan), the model
    description lists exactly them, and fmi2SetDebugLogging accepts each and refuses any other."""
    import ctypes

    used = set()
    for f in sorted(SRC.glob("*.c")):
        used |= set(re.findall(r"logmsg\(\s*[^,]+,\s*[^,]+,\s*\"(\w+)\"", f.read_text()))
    assert used and used <= set(contract.LOG_CATEGORIES), used - set(contract.LOG_CATEGORIES)
    md = fmpy.read_model_description(str(built_fmus()["Trivial"]))
    assert tuple(c.name for c in md.logCategories) == contract.LOG_CATEGORIES
    s, log, _ = trivial
    f = s.dll.fmi2SetDebugLogging
    f.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_size_t, ctypes.POINTER(ctypes.c_char_p)]
    f.restype = ctypes.c_int
    for cats in ([c] for c in contract.LOG_CATEGORIES):
        arr = (ctypes.c_char_p * 1)(*(c.encode() for c in cats))
        assert f(s.component, 1, 1, arr) == 0, cats
    arr = (ctypes.c_char_p * 1)(b"logEverything")
    assert f(s.component, 1, 1, arr) == 3
    assert "unknown log category logEverything" in log[-1]


@pytest.mark.parametrize(
    "field, value",
    [
        ("causality", "inptu"),
        ("variability", "continous"),
        ("initial", "exactly"),
        ("dependencies_kind", ("dependant",)),
    ],
)
def test_a_misspelt_declaration_is_refused_where_it_is_written(field, value):
    """Causality, variability, initial and dependency kinds are FMI's words: a misspelt one would write
    a model description every importer rejects, so the declaration itself refuses it, naming the variable."""
    from pyfmu_wrapper.fmi.varspec import Variable

    kw = dict(name="v", vr=1, type="Real", causality="input", variability="continuous", description="d", start=0.0)
    if field == "dependencies_kind":
        kw.update(causality="output", start=None, depends_on=("x",), dependencies_kind=value)
    else:
        kw[field] = value
    with pytest.raises(ValueError, match=rf"^v: .*{value if isinstance(value, str) else value[0]}"):
        Variable(**kw)
