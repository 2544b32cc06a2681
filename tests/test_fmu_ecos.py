"""Another vendor's master: Ecos (pip ``ecospy``, a C++ co-simulation engine) loads both FMUs from a
copy in a temporary folder, couples them as this project's master does (base.x, xd, xdd ->
tmd.x, xd, xdd; tmd.force -> base.f_link) and runs Case 1 (m = 9 kg, I = 1 kg, c = 10 N.s/m) at
17 and 20 rad/s; the steady amplitude of x is held against the monolithic solver.

Tolerance: Ecos steps all models with a fixed communication step and hands each input the value
its source had at the start of the step (zero-order hold, no algebraic-loop iteration). That
coupling is first order in the step: measured -2.8 % (17 rad/s) and +0.5 % (20 rad/s) at
h = 1 ms, -0.29 % and +0.06 % at h = 0.1 ms (ten times smaller: first order). The default test
runs h = 1 ms and allows 4 %; the slow test runs h = 0.1 ms and allows 0.4 %. (This project's own
master, with interpolated inputs and the loop solved, is within 2e-5 at 1 ms.)
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from _ecos_support import ecos_simulation
from _fmu_support import built_fmus

from pyfmu_wrapper.models import solve as mono
from pyfmu_wrapper.physics.params import BaseParams, TMDParams


@pytest.fixture(scope="module")
def copies(tmp_path_factory):
    root = tmp_path_factory.mktemp("ecos")
    return {n: Path(shutil.copy(p, root / p.name)) for n, p in built_fmus().items()}


def ecos_amplitude(fmus, omega, h, periods=25, window=3):
    """max |x| over the last `window` periods of an Ecos run from the monolithic linear start state."""
    base, tmd = BaseParams(), TMDParams(damping=10.0)
    z0 = mono.initial_guess(base, tmd, omega)
    sim = ecos_simulation(fmus, base, tmd, omega, z0, h)
    try:
        T = 2 * math.pi / omega
        sim.step_until((periods - window) * T)
        xs = []
        while sim.get_time() < periods * T - 0.5 * h:
            sim.step(1)
            xs.append(sim.get_real("base::x"))
        sim.terminate()
    finally:
        sim.free()
    return float(np.max(np.abs(xs))), mono.steady_state(base, tmd, omega).amplitude


@pytest.mark.parametrize("omega", [17.0, 20.0])
def test_ecos_case1_against_monolithic(copies, omega, capfd):
    amp, ref = ecos_amplitude(copies, omega, 1e-3)
    assert abs(amp / ref - 1) <= 0.04, (amp, ref)
    out = capfd.readouterr()
    assert "fmi2Error" not in out.out + out.err and "Traceback" not in out.out + out.err


@pytest.mark.slow
@pytest.mark.parametrize("omega", [17.0, 20.0])
def test_ecos_case1_first_order_at_smaller_step(copies, omega):
    amp, ref = ecos_amplitude(copies, omega, 1e-4)
    assert abs(amp / ref - 1) <= 0.004, (amp, ref)
