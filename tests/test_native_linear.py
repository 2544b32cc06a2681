"""The native LinearTMD FMU (pyfmu_wrapper/models/linear_tmd/fmus/native.py): the same bits as the
Python-hosted LinearTMD, the exact response of a detached absorber's main mass, and the slave's refusals.

- Driven by an input force ramp through fmpy, every output at every step of the native FMU equals the
  Python-hosted FMU's (both call the compiled ``advance_linear`` and ``linear_outputs`` of its step.py).
- With the absorber detached (k = c = 0) the main mass is M xdd + C xd + K x = F cos(w t): x(2 s) is the
  exact forced response within 1e-7 of its amplitude (RODAS4 at rtol 1e-8).
- A mass of 0 is refused at initialisation in LinearTMDParams' words.
"""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from _fmu_support import damped_forced_response

from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.catalog import pick

OUTPUTS = ["x", "xd", "xdd", "y", "yd"]


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("linear")
    native = build_native_fmus(pick("LinearTMD"), root / "native", win64=False, aarch64=False)[0]
    hosted = ensure_fmus(pick("LinearTMD"), root / "python")["LinearTMD"]
    return {"native": str(native), "python": str(hosted)}


def _run(fmu: str, start: dict, stop: float = 2.0, ramp: bool = True) -> np.ndarray:
    inputs = np.array(
        [(0.0, 0.0), (1.0, 5.0 if ramp else 0.0), (2.0, -3.0 if ramp else 0.0)],
        dtype=[("time", float), ("f_ext", float)],
    )
    r = fmpy.simulate_fmu(
        fmu, stop_time=stop, step_size=1e-3, output_interval=1e-3, start_values=start, input=inputs, output=OUTPUTS
    )
    return np.array(r.tolist())


def test_native_linear_tmd_is_the_python_hosted_bit_for_bit(fmus):
    start = {"w": 17.0, "x0": 0.01, "c": 2.0}
    native, hosted = _run(fmus["native"], start), _run(fmus["python"], start)
    assert native.shape == (2001, 6)
    assert np.ptp(native[:, 4]) > 1e-3  # the absorber moves
    assert np.array_equal(native, hosted)


def test_detached_absorber_leaves_the_exact_forced_response(fmus):
    start = dict(M=10.0, K=4.0e3, C=5.0, F=10.0, w=17.0, x0=0.01, xd0=0.0)
    out = _run(fmus["native"], {**start, "k": 0.0, "c": 0.0}, ramp=False)
    exact, _ = damped_forced_response(out[-1, 0], **start)
    amplitude = 10.0 / math.hypot(4.0e3 - 10.0 * 17.0**2, 5.0 * 17.0)
    assert abs(out[-1, 1] - exact) <= 1e-7 * amplitude, (out[-1, 1], exact)


def test_native_configure_refuses_what_linear_tmd_params_refuses():
    """The compiled configure refuses exactly the values LinearTMDParams refuses (each row: NaN, inf, its
    bound and just inside it), with LinearTMDParams' words for that row (the native FMU's message)."""
    import ctypes

    from pyfmu_wrapper.fmi.contract import NATIVE_OK
    from pyfmu_wrapper.fmi.native_model import FIELD_CODE
    from pyfmu_wrapper.models.linear_tmd.fmus.native import field_messages, linear_functions
    from pyfmu_wrapper.models.linear_tmd.fmus.variables import LINEAR_TMD_FMU
    from pyfmu_wrapper.models.linear_tmd.params import PARAMETERS, LinearTMDParams
    from pyfmu_wrapper.physics.params import ParameterError

    nvr = max(v.vr for v in LINEAR_TMD_FMU.variables) + 1
    start = np.zeros(nvr)
    for v in LINEAR_TMD_FMU.variables:
        if v.start is not None:
            start[v.vr] = v.start
    ints, p, z, u = np.zeros(nvr, dtype=np.int32), np.zeros(64), np.zeros(4), np.zeros(4)
    conf = linear_functions()["configure"]
    f64 = ctypes.POINTER(ctypes.c_double)
    words = field_messages()
    refusals = 0
    for row in PARAMETERS:
        lo = 0.0 if row.minimum is None else row.minimum
        for value in (math.nan, math.inf, -math.inf, lo, lo - 1.0, lo + 1e-300, 3.0):
            reals = start.copy()
            reals[row.fmu_vr] = value
            rc = conf.ctypes(
                reals.ctypes.data_as(f64), ints.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)),
                p.ctypes.data_as(f64), z.ctypes.data_as(f64), u.ctypes.data_as(f64),
            )  # fmt: skip
            try:
                LinearTMDParams(**{r.name: reals[r.fmu_vr] for r in PARAMETERS})
                refused = None
            except ParameterError as e:
                refused = str(e)
            assert (rc != NATIVE_OK) == (refused is not None), (row.name, value, rc, refused)
            if refused:
                refusals += 1
                assert refused.startswith(words[rc - FIELD_CODE] + ", got"), (refused, words[rc - FIELD_CODE])
    assert refusals >= 3 * len(PARAMETERS)
