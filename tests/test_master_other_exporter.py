"""The master on FMUs that another exporter built: PythonFMU (pip ``pythonfmu``, in the test extras)
packs two Python classes into FMI 2.0 co-simulation FMUs with its own binaries, here a sine source
and an explicit-Euler integrator, ``sine.y -> integrator.u``.

Independent numbers: with a zero-order hold (Jacobi, order 0), the integrator receives sin(t_k) over
each step, so after N steps x is the left Riemann sum h * sum_{k<N} sin(k h), exactly (to rounding);
and that sum approaches the integral 1 - cos(T) at first order in h (the error halves with h).
"""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import pytest

from pyfmu_wrapper.master.master import Master

SINE = """
import math
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Sine(Fmi2Slave):
    description = "y = sin(t) at the communication points"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.y = 0.0
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.y = math.sin(current_time + step_size)
        return True
"""

INTEGRATOR = """
from pythonfmu import Fmi2Causality, Fmi2Slave, Real


class Integrator(Fmi2Slave):
    description = "x' = u, explicit Euler over each communication step"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.u = 0.0
        self.x = 0.0
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("x", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.x += step_size * self.u
        return True
"""


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    d = tmp_path_factory.mktemp("pythonfmu")
    out = {}
    for name, src in (("Sine", SINE), ("Integrator", INTEGRATOR)):
        script = d / f"{name}.py"
        script.write_text(src)
        cmd = [sys.executable, "-m", "pythonfmu", "build", "-f", str(script), "-d", str(d / "out")]
        subprocess.run(cmd, check=True, capture_output=True, cwd=d)
        out[name] = d / "out" / f"{name}.fmu"
    return out


def _final_x(fmus: dict[str, Path], h: float, t_end: float) -> tuple[float, int]:
    m = Master(
        {"sine": fmus["Sine"], "integrator": fmus["Integrator"]},
        ["sine.y -> integrator.u"],
        {},
        scheme="jacobi",
        order=0,
        record=["integrator.x", "sine.y"],
    )
    try:
        m.initialize(0.0, {})
        r = m.run(t_end, step=h)
        assert abs(r["sine.y"][-1] - math.sin(t_end)) < 1e-12
        return float(r["integrator.x"][-1]), r.steps
    finally:
        m.close()


def test_master_on_pythonfmu_fmus_gives_the_exact_discrete_sum(fmus):
    t_end = 2.0
    errors = []
    for h in (0.01, 0.005):
        x, steps = _final_x(fmus, h, t_end)
        n = round(t_end / h)
        assert steps == n
        riemann = h * math.fsum(math.sin(k * h) for k in range(n))
        assert x == pytest.approx(riemann, rel=1e-12, abs=1e-14)
        errors.append(abs(x - (1.0 - math.cos(t_end))))
    assert errors[1] == pytest.approx(errors[0] / 2, rel=0.02)  # first order in h
