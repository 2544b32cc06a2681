"""The shear-frame model unit (models/frame_model/) held against independent results: the paper's
model (a 1-storey frame is the paper's base oscillator to 1e-12: equations, Jacobian, exact response,
steady states) and the structure's matrices of physics/frame.py, (K - w^2 (M + B) + i w C) X = F,
for TMDs on any storey with the inerter to the same storey, another storey or the ground."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pyfmu_wrapper.models.frame_model import UNIT, FrameParams, frame_pack, storey_index
from pyfmu_wrapper.models.solve import exact_amplitude, exact_response, simulate, steady_state
from pyfmu_wrapper.physics import frame as ref
from pyfmu_wrapper.physics.jacobians import coupled_jacobian
from pyfmu_wrapper.physics.kernels import rhs
from pyfmu_wrapper.physics.params import BaseParams, ParameterError, TMDParams, pack, paper_case
from pyfmu_wrapper.physics.unit import ModelError
from pyfmu_wrapper.solvers.monolithic import SolverSettings

BASE = BaseParams()
ONE = FrameParams.uniform(1, BASE.mass, BASE.stiffness, BASE.damping, force_amplitude=BASE.force_amplitude)
#: every configuration of the paper's TMD: ideal inerter, play, friction, cubic spring, all of them
CONFIGS = {
    "ideal": paper_case(1, damping=10.0),
    "play": paper_case(1, inerter="play", play_gap=1e-4, damping=10.0),
    "friction": paper_case(1, friction_force=10.0),
    "cubic": paper_case(2, cubic_stiffness=2e6, damping=5.0),
    "full": paper_case(1, inerter="play", play_gap=1e-4, damping=10.0, friction_force=10.0, cubic_stiffness=1e6),
    "none": TMDParams(mass=10.0, stiffness=4000.0, damping=20.0, inertance=0.0, inerter="none"),
}


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_one_storey_frame_has_the_papers_equations_and_jacobian(name):
    tmd = CONFIGS[name]
    rng = np.random.default_rng(7)
    p_paper, p_frame = pack(BASE, tmd, 19.0), frame_pack(ONE, tmd, 19.0)
    u = np.zeros(1)
    for _ in range(20):
        z = rng.normal(size=6) * np.array([1e-2, 0.2, 1e-2, 0.2, 2e-4, 1e-2])
        t = float(rng.uniform(0.0, 1.0))
        a, b = np.empty(6), np.empty(6)
        rhs(t, z, p_paper, a)
        UNIT.ode.rhs(t, z, p_frame, u, b)
        assert np.max(np.abs(a - b)) <= 1e-12 * np.max(np.abs(a))
        Ja, fa = np.empty((6, 6)), np.empty(6)
        Jb, fb = np.empty((6, 6)), np.empty(6)
        coupled_jacobian(t, z, p_paper, Ja, fa)  # the paper's hand-derived Jacobian
        UNIT.ode.jacobian(t, z, p_frame, u, Jb, fb, np.empty(6, complex), np.empty(6, complex))
        assert np.max(np.abs(Ja - Jb)) <= 1e-12 * np.max(np.abs(Ja))
        assert np.max(np.abs(fa - fb)) <= 1e-12 * max(np.max(np.abs(fa)), 1e-300)


def test_one_storey_frame_has_the_papers_exact_response_and_steady_states():
    w = np.linspace(15.0, 25.0, 41)
    tmd = CONFIGS["ideal"]
    assert np.max(np.abs(exact_amplitude(ONE, tmd, w) / exact_amplitude(BASE, tmd, w) - 1)) < 1e-12
    # periodic steady states by shooting, each model integrated with its own Jacobian (the paper's
    # hand-derived one, the frame's complex-step one: equal to rounding, test above). The linear one
    # agrees to 1e-12; with the friction's 1e6 slope the two Newton paths land 2e-12 apart, 1e-3 of
    # the solver's own tolerance.
    for name, tol in (("ideal", 1e-12), ("friction", 1e-10)):
        for omega in (18.0, 21.0):
            a = steady_state(BASE, CONFIGS[name], omega).amplitude
            b = steady_state(ONE, CONFIGS[name], omega).amplitude
            assert abs(b / a - 1) < tol, (name, omega, a, b)


def _unit_displacements(frame: FrameParams, Z: np.ndarray) -> np.ndarray:
    """The unit's complex amplitudes in physics/frame.py's order: storeys 1..n, then the TMD."""
    idx = [storey_index(i, frame.n) for i in range(1, frame.n + 1)] + [2]
    return Z[:, idx]


ATTACHMENTS = [
    # (storeys, TMD storey, inerter terminal (-1: same storey, 0: ground), loaded storey)
    (3, 3, -1, 3),
    (3, 3, 2, 3),
    (3, 3, 0, 3),
    (3, 2, 3, 1),
    (10, 10, -1, 10),
    (10, 10, 8, 5),
    (20, 20, 0, 20),
]


@pytest.mark.parametrize(("n", "storey", "to", "loaded"), ATTACHMENTS)
def test_frame_exact_response_is_the_structures(n, storey, to, loaded):
    """The unit's linear system, read off its right-hand side, gives every storey's and the TMD's
    complex amplitude of (K - w^2 (M + B) + i w C) X = F, the inerter in B between its terminals."""
    frame = FrameParams.uniform(
        n, 100.0, 1.2e5 * n / 3, 100.0, force_amplitude=200.0, force_storey=loaded, tmd_storey=storey, inerter_to=to
    )
    tmd = TMDParams(mass=10.0, stiffness=3500.0, damping=20.0, inerter="ideal", inertance=5.0)
    structure = ref.ShearFrame.uniform(n, 100.0, 1.2e5 * n / 3, 100.0, force_amplitude=200.0, force_storey=loaded)
    lin = ref.LinearTMD(storey, 10.0, 3500.0, 20.0, 5.0, inerter_to=None if to < 0 else to)
    w = np.linspace(5.0, 40.0, 71)
    ours = _unit_displacements(frame, exact_response(frame, tmd, w))
    theirs = ref.frequency_response(structure, lin, w)
    assert np.max(np.abs(ours - theirs)) < 1e-10 * np.max(np.abs(theirs))


@pytest.mark.parametrize("to", [-1, 2, 0])
def test_frame_steady_state_by_integration_is_the_exact_response(to):
    """The monolithic solver's periodic steady state (integrated, shooting), not the exact path."""
    frame = FrameParams.uniform(3, 100.0, 1.2e5, 100.0, force_amplitude=200.0, tmd_storey=3, inerter_to=to)
    tmd = TMDParams(mass=10.0, stiffness=3500.0, damping=20.0, inerter="ideal", inertance=5.0)
    lin = ref.LinearTMD(3, 10.0, 3500.0, 20.0, 5.0, inerter_to=None if to < 0 else to)
    structure = ref.ShearFrame.uniform(3, 100.0, 1.2e5, 100.0, force_amplitude=200.0)
    for omega in (12.0, 17.0, 22.0):
        ss = steady_state(frame, tmd, omega, settings=SolverSettings())
        exact = ref.top_amplitude(structure, lin, [omega])[0]
        assert ss.converged and abs(ss.amplitude / exact - 1) < 1e-5, (omega, ss.amplitude, exact)


def test_start_state_of_the_wrong_length_is_refused_by_name():
    frame = FrameParams.uniform(3, 100.0, 1.2e5, 100.0)
    with pytest.raises(ModelError, match=r"start state of model 'frame' must have 10 entries .*got shape \(6,\)"):
        steady_state(frame, CONFIGS["ideal"], 20.0, z0=np.zeros(6))
    with pytest.raises(ModelError, match="must have 6 entries"):
        simulate(BASE, CONFIGS["ideal"], 20.0, 0.1, z0=np.zeros(10))


def test_frame_parameters_are_checked():
    with pytest.raises(ParameterError, match="storeys must be 1 to 20, got 21"):
        FrameParams.uniform(21, 100.0, 1e5, 10.0)
    with pytest.raises(ParameterError, match="stiffness of storey 2 must be a finite number > 0"):
        FrameParams((100.0, 100.0), (1e5, 0.0), (1.0, 1.0))
    with pytest.raises(ParameterError, match="inerter_to must be an integer storey -1..3, got 4"):
        FrameParams.uniform(3, 100.0, 1e5, 10.0, inerter_to=4)
    assert replace(ONE, tmd_storey=1).terminal == 1 and replace(ONE, inerter_to=0).terminal == 0


@pytest.mark.parametrize("structure", [BASE, FrameParams.uniform(3, 100.0, 1.2e5, 100.0)], ids=["base", "frame3"])
def test_a_detached_tmd_settles_by_shooting(structure):
    """A curve without TMD (the TMD detached: no links) integrated to its steady state: the floating
    TMD's states are not shot for (their period map has the eigenvalue 1), so Newton converges to the
    structure's own exact response (before: 3000 periods, not converged, NaN)."""
    from pyfmu_wrapper.scenario.tmdspec import detached_tmd

    tmd = detached_tmd(CONFIGS["ideal"])
    for omega in (12.0, 18.0):
        ss = steady_state(structure, tmd, omega)
        exact = exact_amplitude(structure, tmd, [omega])[0]
        assert ss.converged and ss.periods < 50 and abs(ss.amplitude / exact - 1) < 1e-5
