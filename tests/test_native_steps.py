"""The native FMUs' doStep beyond the ordinary step (pyfmu_wrapper/fmi/native.py): steps longer than
the native step's piece (:data:`~pyfmu_wrapper.fmi.contract.NATIVE_MAX_STEP`), and failures named
as the Python-hosted FMU names them.

- A TMD step of 2.5 s (three pieces) and of 1.7 s (two) gives the Python-hosted FMU's outputs bit
  for bit: the Python slave takes long steps in pieces in Python, the native step in compiled code,
  with the same piece boundaries and the same integrator.
- An integrator that cannot proceed (rtol = 1e-30, atol = 1e-300: no step meets them) stops both
  FMUs at the same time in the same state: the native message carries the Python message's cause,
  time and state (to the digit), and the FMU is left at the start of the step (its outputs read as
  before the step).
- A base whose state overflows in a step (x0 = 1e308 on a 1 g base, one 1 s step) names the cause
  and the state it started from.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from _fmu_support import built_fmus
from fmpy.fmi1 import FMICallException
from test_fmu_ranges import Logged

from pyfmu_wrapper.fmi.contract import NATIVE_MAX_STEP
from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick

PLAY = dict(m=9.0, I=1.0, k=4.0e3, c=10.0, df=10.0, inerter=2, eps=1e-4, ki=2e7)


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    native = {p.stem: p for p in build_native_fmus(pick(PROJECT_FMUS), out_dir=tmp_path_factory.mktemp("native"))}
    return {"native": native, "hosted": built_fmus()}


def _run_long_steps(fmu, tmp_path, tag):
    f = Logged(fmu, tmp_path, tag)
    s, vr = f.s, f.vr
    try:
        f.start(dict(PLAY, y0=0.003))
        t, out = 0.0, []
        for h in (2.5, 1e-3, 1.7, 0.3):
            x = 1e-3 * np.sin(3.0 * t)
            s.setReal([vr["x"], vr["xd"], vr["xdd"]], [x, 3e-3 * np.cos(3.0 * t), -9.0 * x])
            s.doStep(t, h)
            t += h
            out += s.getReal([vr["force"], vr["y"], vr["yd"], vr["inerter_force"]])
        return out, f.text()
    finally:
        s.terminate()
        s.freeInstance()


def test_long_tmd_steps_equal_the_python_hosted_fmu(builds, tmp_path):
    assert 2 * NATIVE_MAX_STEP < 2.5 and NATIVE_MAX_STEP < 1.7
    native, log = _run_long_steps(builds["native"]["TMDInerter"], tmp_path, "native")
    hosted, _ = _run_long_steps(builds["hosted"]["TMDInerter"], tmp_path, "hosted")
    assert "at most" not in log  # no long step refused
    assert native == hosted
    assert all(np.isfinite(native)) and native[1] != 0.0


def _failed_step(fmu, tmp_path, tag):
    f = Logged(fmu, tmp_path, tag)
    s, vr = f.s, f.vr
    try:
        f.start(dict(PLAY, y0=0.003, rtol=1e-30, atol=1e-300))
        before = s.getReal([vr["y"], vr["force"]])
        s.setReal([vr["x"]], [1e-3])
        with pytest.raises(FMICallException):
            s.doStep(0.0, 1e-3)
        return f.text(), before
    finally:
        s.freeInstance()


def test_integrator_failure_named_as_in_the_python_hosted_fmu(builds, tmp_path):
    nat, _ = _failed_step(builds["native"]["TMDInerter"], tmp_path, "native")
    hos, _ = _failed_step(builds["hosted"]["TMDInerter"], tmp_path, "hosted")
    pat = r"integrator stopped at t = (\S+) s: (the step size fell below [^;]*); state (y = [^;(]*)"
    m_n, m_h = re.search(pat, nat), re.search(pat, hos)
    assert m_n and m_h, (nat, hos)
    assert m_n.group(1) == m_h.group(1)  # the same time
    assert m_n.group(2) == m_h.group(2)  # the same cause
    assert m_n.group(3).strip() == m_h.group(3).strip()  # the same state, every digit
    assert "doStep from t = 0 s" in nat and "left at the start of the step" in nat


def test_native_tmd_left_at_the_start_of_a_failed_step(builds, tmp_path):
    f = Logged(builds["native"]["TMDInerter"], tmp_path, "state")
    s, vr = f.s, f.vr
    try:
        f.start(dict(PLAY, y0=0.003, rtol=1e-30, atol=1e-300))
        with pytest.raises(FMICallException):
            s.doStep(0.0, 1e-3)
        # the state kept is the start state: an FMU state taken now restores to y = y0
        assert s.getReal([vr["y"]]) == [0.003]
    finally:
        s.freeInstance()


def test_native_base_overflow_names_its_cause_and_start(builds, tmp_path):
    f = Logged(builds["native"]["BaseOscillator"], tmp_path, "base")
    s = f.s
    try:
        f.start(dict(M=1e-3, C=0.0, x0=1e308))
        with pytest.raises(FMICallException):
            s.doStep(0.0, 1.0)
        text = f.text()
    finally:
        s.freeInstance()
    assert "doStep of 1 s from t = 0 s: the state is not finite at its end (from x = 1e+308, xd = 0)" in text
