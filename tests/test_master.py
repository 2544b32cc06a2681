"""Co-simulation master: connection graph and algebraic loops, stepping schemes held against the
monolithic solver (time series, FRC, observed order), adaptive step, SSP export.

Every configuration type (viscous, ideal inerter, dry friction, play, full model) is
co-simulated and compared with :mod:`pyfmu_wrapper.solvers.monolithic`:
* FRC: the largest relative amplitude difference over a few frequencies <= 0.5 % at the default step;
* time series: two periods from the same start state, max |x_cosim - x_mono| <= 0.5 % of max |x|;
* order: the time-series error when the communication step is halved shrinks at the scheme's
  documented order (observed order asserted).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pyfmu_wrapper.cosim.settings import CosimSettings, steps_for_accuracy
from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.master import Master, build_graph
from pyfmu_wrapper.master.graph import Connection, GraphError
from pyfmu_wrapper.models import solve as mono
from pyfmu_wrapper.models.base_tmd import UNIT
from pyfmu_wrapper.models.base_tmd.cosim import (
    CONNECTIONS,
    fmu_parameters,
    impulse_connections,
    make_master,
    steady_state,
)
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick
from pyfmu_wrapper.physics.params import BaseParams, TMDParams

BASE = BaseParams()
CONFIGS = {
    "viscous": TMDParams(mass=10.0, inertance=0.0, inerter="none", damping=56.38),
    "ideal_inerter": TMDParams(damping=10.0),
    "dry_friction": TMDParams(friction_force=10.0),
    "play": TMDParams(inerter="play", play_gap=1e-4),
    "full": TMDParams(inerter="play", play_gap=1e-4, damping=10.0, friction_force=10.0),
}
#: FRC frequencies per configuration (rad/s): cheap, off and near the resonances
FRC_OMEGAS = {
    "viscous": [16.0, 19.0, 21.5],
    "ideal_inerter": [17.0, 20.0, 23.0],
    "dry_friction": [17.0, 20.0, 23.0],
    "play": [16.0, 17.0],
    "full": [17.0, 19.0],
}


@pytest.fixture(scope="module")
def fmus():
    p = ensure_fmus(pick(PROJECT_FMUS))
    return {"base": p["BaseOscillator"], "tmd": p["TMDInerter"]}


@pytest.fixture(scope="module")
def masters(fmus):
    made = {}

    def get(tmd, coupling="impulse", scheme="loop", order=2):
        key = (coupling, scheme, order, float(tmd.mass) if coupling == "impulse" else 0.0)
        if key not in made:
            made[key] = make_master(BASE, tmd, scheme, order, fmus=fmus, coupling=coupling)
        m = made[key]
        m.scheme = scheme if coupling == "force" else "jacobi"
        m.set_order(order)
        return m

    yield get
    for m in made.values():
        m.close()


# --- graph -------------------------------------------------------------------------------------


def test_graph_finds_the_inerter_loop(fmus):
    from fmpy import read_model_description

    mds = {k: read_model_description(str(v)) for k, v in fmus.items()}
    g = build_graph(mds, CONNECTIONS)
    assert g.loops == [["base.f_link", "base.xdd", "tmd.force", "tmd.xdd"]]
    assert {c.dst for c in g.loop_connections()[0]} == {"tmd.xdd", "base.f_link"}
    # the momentum (impulse) coupling has no algebraic loop
    assert build_graph(mds, impulse_connections(TMDParams())).loops == []
    # without the acceleration link there is no loop either
    assert build_graph(mds, [c for c in CONNECTIONS if "xdd" not in c]).loops == []
    with pytest.raises(GraphError, match="not an input"):
        build_graph(mds, ["base.x -> tmd.force"])
    with pytest.raises(GraphError, match="no variable"):
        build_graph(mds, ["base.nope -> tmd.x"])
    with pytest.raises(GraphError, match="more than one source"):
        build_graph(mds, ["base.x -> tmd.x", "base.xd -> tmd.x"])
    assert Connection.parse("a.y -> b.u") == Connection("a.y", "b.u")


def test_master_is_generic(fmus):
    """Any FMUs and connection list: two base oscillators pushing on each other through a link
    force taken from the other's acceleration (an algebraic loop the master must solve)."""
    conns = ["a.xdd -> b.f_link", "b.xdd -> a.f_link"]
    with Master(
        {"a": fmus["base"], "b": fmus["base"]}, conns, {"a.F": 200.0, "b.F": 0.0, "a.w": 20.0}, scheme="loop"
    ) as m:
        assert len(m.graph.loops) == 1
        m.initialize()
        m.run(0.05, step=1e-3)
        # coupling equations hold: f_link of each equals the other's acceleration
        assert m.get("b.f_link") == pytest.approx(m.get("a.xdd"), rel=1e-9, abs=1e-12)
        assert m.get("a.f_link") == pytest.approx(m.get("b.xdd"), rel=1e-9, abs=1e-12)


def test_master_knows_fmi_and_coupling_only():
    """The generic master imports nothing of the TMD application: no module of
    pyfmu_wrapper/master/ imports outside the master package (physics, solvers, params, fmi,
    cosim), statically (every import statement, also inside functions) and at run time (a fresh
    interpreter importing the master loads no other project module); and no module reads fmpy's
    private ``_functions`` table."""
    import ast
    import subprocess
    import sys
    from pathlib import Path

    import pyfmu_wrapper.master as pkg

    files = sorted(Path(pkg.__file__).parent.glob("*.py"))
    assert {f.name for f in files} >= {"master.py", "instance.py", "schemes.py", "loop.py", "stepcontrol.py"}
    bad = []
    for f in files:
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.ImportFrom):
                mod = node.module or ""
                outside = node.level > 1 or (
                    node.level == 0 and mod.startswith("pyfmu_wrapper") and not mod.startswith("pyfmu_wrapper.master")
                )
                if outside:
                    bad.append(f"{f.name}:{node.lineno}: from {'.' * node.level}{mod} import ...")
            elif isinstance(node, ast.Import):
                bad += [
                    f"{f.name}:{node.lineno}: import {a.name}"
                    for a in node.names
                    if a.name.startswith("pyfmu_wrapper") and not a.name.startswith("pyfmu_wrapper.master")
                ]
            elif isinstance(node, ast.Attribute) and node.attr == "_functions":
                bad.append(f"{f.name}:{node.lineno}: fmpy private ._functions")
    assert not bad, bad
    code = (
        "import sys, pyfmu_wrapper.master; print(sorted(m for m in sys.modules if m.startswith('pyfmu_wrapper.')"
        " and not m.startswith('pyfmu_wrapper.master')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out


# --- against the monolithic solver ----------------------------------------------------------------


def _series_error(master, tmd, omega, n, periods=2):
    """max |x_cosim - x_mono| / max |x_mono| over `periods` periods from the linear guess, n steps per period."""
    z0 = mono.initial_guess(BASE, tmd, omega)
    master.initialize(0.0, fmu_parameters(BASE, tmd, omega, z0))
    T = 2 * math.pi / omega
    res = master.run(periods * T, step=T / n)
    _, st = mono.simulate(BASE, tmd, omega, periods * T * (1 + 1e-9), z0, sample_times=res.t, rtol=1e-10)
    x = st[:, 0]
    return float(np.max(np.abs(res["base.x"] - x)) / np.max(np.abs(x)))


@pytest.mark.parametrize("name", list(CONFIGS))
def test_frc_and_time_series_against_monolithic(name, masters):
    tmd = CONFIGS[name]
    settings = CosimSettings()  # default step (accuracy 1e-3 -> 96 steps per period)
    m = masters(tmd)
    diffs = []
    z = None
    for w in FRC_OMEGAS[name]:
        ref = mono.steady_state(BASE, tmd, w)
        ss = steady_state(UNIT, m, BASE, tmd, w, z, settings)
        assert ss.converged and ref.converged
        diffs.append(ss.amplitude / ref.amplitude - 1.0)
    assert max(abs(d) for d in diffs) <= 5e-3, diffs
    # time series at the default step
    n = settings.steps_for(tmd)
    assert _series_error(m, tmd, FRC_OMEGAS[name][0], n) <= 5e-3


#: documented order of the default scheme (impulse coupling, quadratic extrapolation): 3
@pytest.mark.parametrize("name", ["viscous", "ideal_inerter", "dry_friction", "play", "full"])
def test_observed_order_default_scheme(name, masters):
    tmd = CONFIGS[name]
    m = masters(tmd)
    w = FRC_OMEGAS[name][0]
    # play/full: one period, and coarser steps: below ~1e-4 the difference is set by the rattling
    # gear (contact times are sensitive to any perturbation), not by the coupling (docs/cosimulation.md)
    periods, n = (1, 12) if tmd.inerter == 2 else (2, 48)
    e1 = _series_error(m, tmd, w, n, periods)
    e2 = _series_error(m, tmd, w, 2 * n, periods)
    order = math.log2(e1 / e2)
    assert order >= 2.5, (e1, e2, order)


def test_ideal_inerter_loop_solved_and_naive(masters):
    """Force coupling: the algebraic loop (force <- xdd <- force) solved at every communication
    point by Newton with the FMUs' directional derivatives keeps third order; the naive schemes
    are recorded beside it (docs/cosimulation.md)."""
    tmd = CONFIGS["ideal_inerter"]
    w = 17.0
    ref = mono.steady_state(BASE, tmd, w).amplitude
    m = masters(tmd, "force", "loop", 2)
    n = steps_for_accuracy(1e-3, 2, "force")
    ss = steady_state(UNIT, m, BASE, tmd, w, None, CosimSettings(coupling="force", scheme="loop", steps_per_period=n))
    assert abs(ss.amplitude / ref - 1) <= 5e-3
    e1 = _series_error(m, tmd, w, 48)
    e2 = _series_error(m, tmd, w, 96)
    assert math.log2(e1 / e2) >= 2.5, (e1, e2)
    # naive: loop ignored and inputs held (Jacobi, zero-order hold): first order, far larger error
    mn = masters(tmd, "force", "jacobi", 0)
    e_naive = _series_error(mn, tmd, w, 96)
    e_naive2 = _series_error(mn, tmd, w, 192)
    assert e_naive > 10 * e2
    assert 0.7 <= math.log2(e_naive / e_naive2) <= 1.5


def test_adaptive_step_meets_the_tolerance(masters):
    tmd = CONFIGS["ideal_inerter"]
    m = masters(tmd, "force", "loop", 2)
    w = 18.0
    T = 2 * math.pi / w
    z0 = mono.initial_guess(BASE, tmd, w)
    errs = []
    for tol in (1e-4, 1e-6):
        m.initialize(0.0, fmu_parameters(BASE, tmd, w, z0))
        res = m.run(T, tol=tol, h0=T / 200)
        _, st = mono.simulate(BASE, tmd, w, T * (1 + 1e-9), z0, sample_times=res.t, rtol=1e-10)
        errs.append((np.max(np.abs(res["base.x"] - st[:, 0])) / np.max(np.abs(st[:, 0])), res.steps))
    (e_lo, n_lo), (e_hi, n_hi) = errs
    assert e_hi < e_lo and n_hi > n_lo
    assert e_hi < 1e-4


# --- SSP -------------------------------------------------------------------------------------------


def test_ssp_export_runs_in_fmpy(tmp_path):
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import read_ssd

    from pyfmu_wrapper.master.ssp import ssp_parameter_set
    from pyfmu_wrapper.models.base_tmd.cosim import export_tmd_system

    tmd = CONFIGS["ideal_inerter"]
    w = 18.0
    p = export_tmd_system(UNIT, tmp_path / "base_tmd.ssp", BASE, tmd, w, stop_time=0.5, step_size=1e-4)
    ssd = read_ssd(str(p))  # validated against the SSP 1.0 schema, OMSimulator's annotations included
    assert {c.name for c in ssd.system.elements} == {"base", "tmd"}
    assert len(ssd.system.connections) == 4
    ps = ssp_parameter_set(p)
    assert {q.name for q in ps.parameters} >= {"base.M", "base.w", "tmd.m", "tmd.I", "tmd.inerter"}
    h = 1e-4
    res = simulate_ssp(str(p), stop_time=0.5, step_size=h, parameter_set=ps)
    z0 = mono.initial_guess(BASE, tmd, w)
    t = res["time"] + h  # fmpy records the values after the step under the step's start time
    _, st = mono.simulate(BASE, tmd, w, 0.6, z0, sample_times=t)
    assert np.max(np.abs(res["base.x"] - st[:, 0])) <= 1e-2 * np.max(np.abs(st[:, 0]))


def test_ssp_carries_omsimulator_master_annotation_only_when_a_step_is_given(tmp_path):
    """OMSimulator needs its own annotation naming the master and its step (else "[NewSystem]
    internal error"); it is written, with the given step, only when a step is given, and a
    non-positive or non-finite step is refused."""
    import xml.etree.ElementTree as ET
    import zipfile

    from pyfmu_wrapper.models.base_tmd.cosim import export_tmd_system

    tmd, w = CONFIGS["ideal_inerter"], 18.0
    ns = {
        "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
        "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
    }
    with_step = export_tmd_system(UNIT, tmp_path / "a.ssp", BASE, tmd, w, stop_time=1.0, step_size=2.5e-4)
    root = ET.fromstring(zipfile.ZipFile(with_step).read("SystemStructure.ssd"))
    master = root.findall(
        "ssd:System/ssd:Annotations/*/oms:Annotations/oms:SimulationInformation/oms:FixedStepMaster", ns
    )
    assert len(master) == 1
    assert master[0].get("description") == "oms-ma" and float(master[0].get("stepSize")) == 2.5e-4
    assert (
        len(root.findall("ssd:DefaultExperiment/ssd:Annotations/*/oms:Annotations/oms:SimulationInformation", ns)) == 1
    )
    plain = export_tmd_system(UNIT, tmp_path / "b.ssp", BASE, tmd, w, stop_time=1.0)
    assert b"org.openmodelica" not in zipfile.ZipFile(plain).read("SystemStructure.ssd")
    for bad in (0.0, -1e-3, float("inf"), float("nan")):
        with pytest.raises(ValueError, match="step_size"):
            export_tmd_system(UNIT, tmp_path / "c.ssp", BASE, tmd, w, stop_time=1.0, step_size=bad)


def test_period_maximum_uses_the_hermite_interpolant_between_communication_points():
    """max |x| over a co-simulated period comes from the cubic Hermite interpolant of (x, xd) at
    the communication points (the same function as the monolithic solver's dense output): for
    x = A cos(w t - phi) with the peak between two points it equals A to 1e-6, where the points
    alone miss it by 5e-4 (N = 96)."""
    from pyfmu_wrapper.cosim.periods import Periods

    w, A, n = 20.0, 0.0123, 96
    T = 2 * math.pi / w
    phi = 0.5 * w * T / n

    class Clock:  # a stand-in master: x, xd of an exact harmonic at the communication points
        signals = ["base.x", "base.xd"]

        def __init__(self):
            self.t = 0.0
            self.y = np.array([A * math.cos(-phi), -A * w * math.sin(-phi)])

        nsig = 2

        def advance(self, n, h, rec_t, rec_y):  # the master's block of n steps, recorded
            for k in range(n):
                self.t += h
                self.y = np.array([A * math.cos(w * self.t - phi), -A * w * math.sin(w * self.t - phi)])
                rec_t[k], rec_y[k] = self.t, self.y

    run = Periods(Clock(), n, T, ("base.x", "base.xd"))
    a = run.period()
    assert abs(np.max(np.abs(run.x)) / A - 1) > 4e-4
    assert a == pytest.approx(A, rel=1e-6)
