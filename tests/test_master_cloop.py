"""The compiled stepping loop (pyfmu_wrapper/master/cloop.c) against the Python reference path.

Both take the same fixed communication steps of the same FMUs; the compiled loop repeats the
reference path's arithmetic operation for operation, so every recorded value must agree bit for
bit, on every scheme they share: Jacobi (orders 0-2, value connections), Gauss-Seidel, and the
two-phase stepping of rate connections (the impulse coupling, with the interface Jacobian and the
exact first moment). An FMU error stops the loop with the FMU's own message, as on the Python path.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pyfmu_wrapper.cosim.settings import CosimSettings
from pyfmu_wrapper.fmubuild.build import ensure_fmus
from pyfmu_wrapper.master import Master, MasterError, cloop
from pyfmu_wrapper.models.base_tmd import UNIT
from pyfmu_wrapper.models.base_tmd.cosim import fmu_parameters, make_master, steady_state
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick
from pyfmu_wrapper.models.solve import initial_guess
from pyfmu_wrapper.physics.params import BaseParams, TMDParams

BASE = BaseParams()
TMD = TMDParams(damping=10.0)
PLAY = TMDParams(inerter="play", play_gap=1e-4, damping=10.0, friction_force=10.0)


@pytest.fixture(scope="module")
def fmus():
    p = ensure_fmus(pick(PROJECT_FMUS))
    return {"base": p["BaseOscillator"], "tmd": p["TMDInerter"]}


def _run_both(make, init, t_end, h):
    out = []
    for compiled in (False, True):
        m = make()
        m.compiled = compiled
        try:
            init(m)
            r = m.run(t_end, step=h)
            out.append((r.t, r.values, m.timing()))
        finally:
            m.close()
    return out


@pytest.mark.parametrize(
    "coupling,scheme,order,tmd",
    [
        ("impulse", "jacobi", 2, TMD),
        ("impulse", "jacobi", 1, TMD),
        ("impulse", "jacobi", 0, TMD),
        ("impulse", "jacobi", 2, PLAY),
        ("force", "jacobi", 2, TMD),
        ("force", "jacobi", 0, TMD),
        ("force", "gauss-seidel", 2, TMD),
        ("force", "gauss-seidel", 1, TMD),
    ],
)
def test_compiled_loop_is_bit_identical_to_the_python_path(fmus, coupling, scheme, order, tmd):
    w = 18.0
    T = 2 * math.pi / w
    (t_py, y_py, tim_py), (t_c, y_c, tim_c) = _run_both(
        lambda: make_master(BASE, tmd, scheme, order, fmus=fmus, coupling=coupling),
        lambda m: m.initialize(0.0, fmu_parameters(BASE, tmd, w, initial_guess(BASE, tmd, w))),
        3 * T,
        T / 96,
    )
    assert t_py.shape == (3 * 96 + 1,)
    assert np.array_equal(t_py, t_c)
    assert np.array_equal(y_py, y_c), np.max(np.abs(y_py - y_c))
    assert np.all(np.isfinite(y_c)) and np.max(np.abs(y_c[:, 0])) > 1e-4  # a real response, not zeros
    # the compiled run took every step in C, the start-up steps iterated with rollback included,
    # and timed the FMUs in it
    assert tim_py["fmus"] == {} and tim_c["fmus"] and tim_c["python_seconds"] == 0.0
    calls = {k: v["calls"] for k, v in tim_c["fmus"].items()}
    started = 0 if order == 0 or scheme == "gauss-seidel" else order  # start-up steps: 3 takes, get + 2 sets
    for name, c in calls.items():
        # doStep + getReal (+ setReal, + derivatives) a step; a start-up step 3 times that and 3 state calls
        assert 2 * 3 * 96 <= c <= 4 * 3 * 96 + started * (2 * 4 + 3), (name, c)
    inside = sum(v["seconds"] for v in tim_c["fmus"].values())
    assert 0 < inside < tim_c["loop_seconds"]
    assert tim_c["master_seconds"] == pytest.approx(tim_c["loop_seconds"] - inside)


def test_generic_fmus_and_blocks(fmus):
    """Any FMUs and connections (two base oscillators, each forced by the other's velocity,
    Jacobi), and steps taken in several blocks equal one run of single steps."""
    conns = ["a.xd -> b.f_link", "b.xd -> a.f_link"]
    pars = {"a.F": 200.0, "b.F": 0.0, "a.w": 20.0}
    ref = Master({"a": fmus["base"], "b": fmus["base"]}, conns, pars, scheme="jacobi", compiled=False)
    blk = Master({"a": fmus["base"], "b": fmus["base"]}, conns, pars, scheme="jacobi", compiled=True)
    try:
        ref.initialize()
        blk.initialize()
        h = 1e-3
        rows = []
        for _ in range(120):
            ref.step(h)
            rows.append(ref.y.copy())
        rec_t, rec_y = np.zeros(120), np.zeros((120, blk.nsig))
        for a, b in ((0, 7), (7, 50), (50, 51), (51, 120)):
            blk.advance(b - a, h, rec_t[a:b], rec_y[a:b])
        assert np.array_equal(np.array(rows), rec_y)
        assert blk.t == ref.t and blk.steps == ref.steps == 120
        assert np.max(np.abs(rec_y)) > 0
    finally:
        ref.close()
        blk.close()


def test_compiled_loop_stops_with_the_fmus_own_message():
    """An FMU that cannot take a step (tolerances no step can meet) stops the compiled loop at
    once: the master raises the same error as on the Python path, with the FMU's own message,
    and stays at the start of the failed step."""
    tmd = TMDParams(friction_force=10.0)
    for compiled in (False, True):
        m = make_master(BASE, tmd, "loop", 0, coupling="impulse", fmu_build="python")  # order 0: no Python start-up
        m.compiled = compiled
        try:
            p = fmu_parameters(BASE, tmd, 20.0, initial_guess(BASE, tmd, 20.0), fmu_rtol=1e-30)
            p["tmd.atol"] = 1e-300
            m.initialize(0.0, p)
            with pytest.raises(
                MasterError,
                match=r"tmd: fmi2DoStep failed at t = 0 s, h = 0.001 s \(status \d\): .*"
                r"FmuStepError: doStep from t = 0 s: integrator stopped",
            ):
                m.run(0.01, step=1e-3)
            assert m.t == 0.0 and m.steps == 0
        finally:
            m.close()


def test_cosim_steady_state_same_on_both_paths(fmus):
    """The co-simulated steady state (Newton shooting over compiled periods) is the Python
    path's, bit for bit."""
    w = 19.0
    res = []
    for compiled in (False, True):
        m = make_master(BASE, TMD, fmus=fmus, coupling="impulse")
        m.compiled = compiled
        try:
            res.append(steady_state(UNIT, m, BASE, TMD, w, None, CosimSettings()))
        finally:
            m.close()
    assert res[0].converged and res[1].converged
    assert res[0].amplitude == res[1].amplitude
    assert res[0].periods == res[1].periods
    assert np.array_equal(res[0].state, res[1].state)


def test_plain_c_loop_baseline_runs_the_same_calls():
    """The benchmark's baseline (a plain C loop of fmi2SetReal / fmi2DoStep / fmi2GetReal over the
    same instances) advances the FMUs: a Trivial FMU's output follows its input."""
    p = ensure_fmus(pick((*PROJECT_FMUS, "Trivial")))  # built with the pair, as the FMU tests build it
    with Master(
        {"a": p["Trivial"], "b": p["Trivial"]},
        ["a.y -> b.u", "b.y -> a.u"],
        {"a.gain": 0.5, "b.gain": 0.5},
        scheme="jacobi",
        order=0,
    ) as m:
        m.initialize()
        m.advance(10, 1e-3)
        loop = m._compiled_loop()
        assert isinstance(loop, cloop.CompiledLoop)
        t0 = m.t
        assert loop.plain(100, 1e-3) > 0
        assert m.t == pytest.approx(t0 + 0.1)
        m.advance(5, 1e-3)  # the FMUs took the plain loop's steps: the master goes on from there
        assert m.t == pytest.approx(t0 + 0.105)
