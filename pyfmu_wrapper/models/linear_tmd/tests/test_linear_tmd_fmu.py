"""The linear TMD's FMU (models/linear_tmd/fmus/), added by following docs/adding-a-model.md: it
validates (fmpy, FMI 2.0 and 3.0), and its co-simulated trajectory is the monolithic solver's periodic
steady state; its input force moves the main mass as the model's equations say."""

from __future__ import annotations

import math

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.models import MODELS
from pyfmu_wrapper.models.catalog import SPECS, pick
from pyfmu_wrapper.models.linear_tmd import LinearTMDParams
from pyfmu_wrapper.models.linear_tmd.params import PARAMETERS
from pyfmu_wrapper.models.solve import steady_state
from pyfmu_wrapper.physics.params import TMDParams
from pyfmu_wrapper.solvers.monolithic import SolverSettings

S = LinearTMDParams.den_hartog(0.05, damping=2.0)
OMEGA = 18.5


@pytest.fixture(scope="module", params=[2, 3])
def fmu(request):
    return ensure_fmus(pick("LinearTMD"), fmi_version=request.param)["LinearTMD"]


def _starts(s: LinearTMDParams, omega: float, z0) -> dict:
    out = {p.fmu_name: getattr(s, p.name) for p in PARAMETERS}
    out.update(w=omega, x0=z0[0], xd0=z0[1], y0=z0[2], yd0=z0[3], rtol=1e-10, atol=1e-12)
    return out


def test_the_unit_holds_its_fmu():
    (fmu,) = MODELS.get("linear_tmd").fmus()
    assert fmu.name == "LinearTMD" and fmu.slave.__module__.endswith("models.linear_tmd.fmus.slave")
    assert SPECS["LinearTMD"] is fmu.spec


def test_fmpy_validates_it(fmu):
    assert validate_fmu(str(fmu)) == []
    md = fmpy.read_model_description(str(fmu))
    xdd = next(u for u in md.outputs if u.variable.name == "xdd")
    assert [d.name for d in xdd.dependencies] == ["f_ext"]


def test_its_orbit_is_the_monolithic_steady_state(fmu):
    """Started on the monolithic solver's periodic state (phase w t = 0), two periods of the FMU: the state
    after each period is the start again, and max |x| is the solver's amplitude (sampled at T/4000)."""
    ss = steady_state(S, TMDParams(), OMEGA, settings=SolverSettings())
    assert ss.converged
    period = 2 * math.pi / OMEGA
    r = fmpy.simulate_fmu(
        str(fmu),
        stop_time=2 * period,
        step_size=period / 4000,
        output_interval=period / 4000,
        start_values=_starts(S, OMEGA, ss.state),
        output=["x", "xd", "y", "yd"],
    )
    x = np.asarray(r["x"])
    assert abs(np.max(np.abs(x)) / ss.amplitude - 1) < 1e-5, (np.max(np.abs(x)), ss.amplitude)
    end = np.array([r[n][-1] for n in ("x", "xd", "y", "yd")])
    scale = np.array([ss.amplitude, OMEGA * ss.amplitude, ss.amplitude, OMEGA * ss.amplitude])
    assert np.max(np.abs(end - ss.state) / scale) < 1e-6, (end, ss.state)


def test_the_input_force_shifts_the_static_deflection(fmu):
    """F = 0 and a constant f_ext: the main mass settles at f_ext / K, the absorber with it (static
    equilibrium of the model's equations)."""
    s = LinearTMDParams(S.mass, S.stiffness, 8.0, 0.0, S.absorber_mass, S.absorber_stiffness, 1.0)
    f = 3.0
    sig = np.array([(0.0, f), (100.0, f)], dtype=[("time", np.float64), ("f_ext", np.float64)])
    r = fmpy.simulate_fmu(
        str(fmu), stop_time=30.0, output_interval=0.05, start_values=_starts(s, 10.0, np.zeros(4)), input=sig,
        output=["x", "y"],
    )  # fmt: skip
    assert abs(r["x"][-1] / (f / s.stiffness) - 1) < 1e-6 and abs(r["y"][-1] / (f / s.stiffness) - 1) < 1e-6
