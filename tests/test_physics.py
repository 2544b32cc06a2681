"""Physics layer: parameters, kernels, exact frequency response against closed forms and the paper."""

import math

import numpy as np
import pytest

from pyfmu_wrapper.models.solve import exact_amplitude, exact_response
from pyfmu_wrapper.physics import jacobians as Jac
from pyfmu_wrapper.physics import kernels as K
from pyfmu_wrapper.physics.params import BaseParams, ParameterError, TMDParams, pack, paper_case

BASE = BaseParams()
#: TMD configurations the Jacobian tests run through: every inerter model, friction, cubic spring
JACOBIAN_CASES = [
    paper_case(1, damping=10, friction_force=10),
    paper_case(3, damping=10, friction_force=10, inerter="play", play_gap=1e-4),
    paper_case(2, inerter="play", play_gap=0.0),
    TMDParams(mass=10, inertance=0, inerter="none", friction_force=5),
    paper_case(1, damping=10, cubic_stiffness=3e6),
    paper_case(2, damping=10, friction_force=10, inerter="play", play_gap=1e-4, cubic_stiffness=-2e5),
]


def closed_form_x(omega, M=100.0, Kb=4e4, C=100.0, F=200.0, m=9.0, k=4e3, c=0.0, link=0.0):
    """Independent 2-DOF closed form: link = extra dynamic stiffness of the inerter branch.

    (-w^2 M + i w C + K + z) X - z Y = F ;  -z X + (-w^2 m + z) Y = 0, z = k + i w c + link.
    """
    w = np.asarray(omega, dtype=float)
    z = k + 1j * w * c + link
    a11 = -(w**2) * M + 1j * w * C + Kb + z
    a22 = -(w**2) * m + z
    return F * a22 / (a11 * a22 - z * z)


@pytest.mark.parametrize("case", [1, 2, 3])
@pytest.mark.parametrize("c", [0.0, 10.0, 56.38])
def test_exact_frf_ideal_inerter_matches_closed_form(case, c):
    tmd = paper_case(case, damping=c)
    w = np.linspace(15, 25, 41)
    I = tmd.inertance
    ref = np.abs(closed_form_x(w, m=tmd.mass, c=c, link=-(w**2) * I))
    np.testing.assert_allclose(exact_amplitude(BASE, tmd, w), ref, rtol=1e-10, atol=1e-15)


def test_exact_frf_series_inerter_spring_matches_closed_form():
    ki, ci = 2e5, 3.0  # soft mesh so the series compliance matters
    tmd = paper_case(2, damping=10.0, inerter="play", mesh_stiffness=ki, mesh_damping=ci, play_gap=0.0)
    w = np.linspace(15, 25, 41)
    zi = -(w**2) * tmd.inertance
    zs = ki + 1j * w * ci
    link = 1.0 / (1.0 / zi + 1.0 / zs)
    ref = np.abs(closed_form_x(w, m=tmd.mass, c=10.0, link=link))
    np.testing.assert_allclose(exact_amplitude(BASE, tmd, w), ref, rtol=1e-9)


@pytest.mark.parametrize("case", [1, 2, 3])
def test_series_with_stiff_mesh_tends_to_ideal_inerter(case):
    w = np.linspace(15, 25, 101)
    ideal = exact_amplitude(BASE, paper_case(case, damping=10.0), w)
    errs = []
    for ki in (2e9, 2e11):
        ser = exact_amplitude(
            BASE, paper_case(case, damping=10.0, inerter="play", mesh_stiffness=ki, mesh_damping=0.0, play_gap=0.0), w
        )
        errs.append(np.max(np.abs(ser / ideal - 1)))
    # the series compliance error falls as 1/ki: 100x stiffer -> 100x closer
    assert errs[1] < 1e-6
    assert errs[0] / errs[1] == pytest.approx(100, rel=0.01)


def test_fig2_iratio_zero_peaks():
    """Paper Fig. 2 / physics notes: Iratio = 0, c = 0: peaks 17.08 and 23.41 rad/s, 0.1171 and 0.0854 m."""
    tmd = TMDParams(mass=10.0, inertance=0.0, inerter="none")
    w = np.linspace(15, 25, 200001)
    a = exact_amplitude(BASE, tmd, w)
    lo, hi = w < 20, w > 20
    i1, i2 = np.argmax(np.where(lo, a, 0)), np.argmax(np.where(hi, a, 0))
    assert w[i1] == pytest.approx(17.08, abs=0.005) and a[i1] == pytest.approx(0.1171, abs=5e-5)
    assert w[i2] == pytest.approx(23.41, abs=0.005) and a[i2] == pytest.approx(0.0854, abs=5e-5)


@pytest.mark.parametrize("ratio", [0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99])
def test_fig2_antiresonance_stays_at_20(ratio):
    m, I = 10 * (1 - ratio), 10 * ratio
    tmd = TMDParams(mass=m, inertance=I, inerter="ideal" if I > 0 else "none")
    w = np.linspace(19.5, 20.5, 20001)
    a = exact_amplitude(BASE, tmd, w)
    assert w[np.argmin(a)] == pytest.approx(20.0, abs=1e-4)
    assert a.min() < 1e-8


def test_fig2_iratio_one_single_peak():
    tmd = TMDParams(mass=0.0, inertance=10.0, inerter="ideal")
    w = np.linspace(15, 25, 10001)
    a = exact_amplitude(BASE, tmd, w)
    i = np.argmax(a)
    # the damped peak of the bare base: w_n sqrt(1 - 2 zeta^2), zeta = 0.025
    assert w[i] == pytest.approx(20.0 * math.sqrt(1 - 2 * 0.025**2), abs=2e-3)
    # F / (C w_n) = 200 / (100 * 20) = 0.1 m
    assert a[i] == pytest.approx(0.1, rel=1e-3)
    # single peak: monotonic on either side
    assert np.all(np.diff(a[:i]) > 0) and np.all(np.diff(a[i + 1 :]) < 0)


def test_jacobian_complex_step_matches_finite_differences():
    z = np.array([0.01, 0.1, 0.02, -0.05, 2e-4, 0.3])
    for tmd in (
        paper_case(1, damping=10, friction_force=10),
        paper_case(3, damping=10, friction_force=10, inerter="play", play_gap=1e-4),
        TMDParams(mass=10, inertance=0, inerter="none", friction_force=5),
    ):
        p = pack(BASE, tmd, 19.0)
        J = np.zeros((6, 6))
        Jac.jacobian(0.1, z, p, J)
        Jf = np.zeros((6, 6))
        for j in range(6):
            h = 1e-7 * max(1.0, abs(z[j]))
            a, b = np.zeros(6), np.zeros(6)
            zp, zm = z.copy(), z.copy()
            zp[j] += h
            zm[j] -= h
            K.rhs(0.1, zp, p, a)
            K.rhs(0.1, zm, p, b)
            Jf[:, j] = (a - b) / (2 * h)
        assert np.max(np.abs(J - Jf)) <= 1e-6 * np.max(np.abs(J))


def test_link_forces_follow_the_physical_signs():
    """Passive convention: the links push the TMD towards the base and oppose relative motion."""
    tmd = paper_case(1, damping=10.0, friction_force=5.0)
    p = pack(BASE, tmd)
    # base displaced up relative to TMD: spring pulls TMD up (+), base down (force on base, -x)
    assert K.static_link_force(0.01, 0.0, 0.0, 0.0, p) == pytest.approx(40.0)
    # relative velocity +1: damper 10 N and friction ~5 N
    assert K.static_link_force(0.0, 1.0, 0.0, 0.0, p) == pytest.approx(15.0, abs=1e-5)
    assert K.friction_force(1e-6, 5.0, 1e6) == pytest.approx(5.0 * 2 / math.pi * math.atan(1.0))


def test_chain_force_contact_modes():
    tmd = paper_case(1, inerter="play", play_gap=1e-4, mesh_stiffness=2e7, mesh_damping=0.01)
    p = pack(BASE, tmd)
    assert K.chain_force(5e-5, 1.0, p) == 0.0  # inside the gap
    assert K.chain_force(2e-4, 0.0, p) == pytest.approx(2e7 * 1e-4)  # compression
    assert K.chain_force(-2e-4, 0.0, p) == pytest.approx(-2e7 * 1e-4)  # extension
    assert K.chain_force(1e-4 + 1e-9, -10.0, p) == 0.0  # separating: no tension through a contact
    assert [K.contact_state(d, p) for d in (2e-4, 0.0, -2e-4)] == [1, 0, -1]


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(mass=-1.0), "mass"),
        (dict(inertance=float("nan")), "inertance"),
        (dict(play_gap=-1e-4, inerter="play"), "play_gap"),
        (dict(mass=0.0, inertance=0.0, inerter="none"), "mass"),
        (dict(inerter="gearbox"), "inerter"),
        (dict(inertance=2.0, inerter="none"), "inertance"),
        (dict(friction_slope=0.0), "friction_slope"),
        (dict(damping="ten"), "damping"),
    ],
)
def test_bad_tmd_parameters_are_refused_by_name(kwargs, field):
    with pytest.raises(ParameterError, match=field):
        TMDParams(**kwargs, source="case.yaml:3 tmd")


def test_parameter_error_names_its_source():
    with pytest.raises(ParameterError, match=r"mass \(M\).*-5.*from case.yaml:7 base"):
        BaseParams(mass=-5, source="case.yaml:7 base")


def test_exact_response_refuses_nonlinear_configuration():
    with pytest.raises(ParameterError, match="friction_force"):
        exact_response(BASE, paper_case(1, friction_force=1.0), [20.0])


@pytest.mark.parametrize(
    "tmd",
    [
        paper_case(1, damping=10, friction_force=10),
        paper_case(3, damping=10, friction_force=10, inerter="play", play_gap=1e-4),
        paper_case(2, inerter="play", play_gap=0.0),
        TMDParams(mass=10, inertance=0, inerter="none", friction_force=5),
        paper_case(2, damping=10, friction_force=10, inerter="play", play_gap=1e-4, cubic_stiffness=-2e5),
    ],
)
@pytest.mark.parametrize("d", [2e-4, -3e-4, 0.0])
def test_mounted_tmd_with_base_compliance_is_the_coupled_system(tmd, d):
    """The interface Jacobian (kappa = 1/M, xdd input = the base's acceleration without the link
    force) makes the TMD subsystem's rhs the coupled system's, exactly: the TMD then solves the
    base's equation of motion for xdd itself. With kappa = 0 and the coupled xdd as input it is the
    plain subsystem. Both held against the coupled kernel (rhs_fext) in every contact mode."""
    z = np.array([0.01, 0.1, 0.02, -0.05, d, 0.3])
    p = pack(BASE, tmd, 19.0)
    fext = K.excitation(0.3, p)
    full = np.zeros(6)
    K.rhs_fext(z, fext, p, full)
    xdd_free = (fext - BASE.damping * z[1] - BASE.stiffness * z[0]) / BASE.mass
    for kappa, xdd in ((1.0 / BASE.mass, xdd_free), (0.0, full[1])):
        u = np.array([0.3, z[0], 0, 0, z[1], 0, 0, xdd, 0, 0, kappa])
        out = np.zeros(4)
        K.system_rhs(K.SYS_TMD, 0.3, z[2:], p, u, out)
        np.testing.assert_allclose(out, full[2:], rtol=1e-13, atol=1e-13 * np.abs(full).max())
        force, chain, _ = K.tmd_outputs(z[2:], z[0], z[1], xdd, kappa, p)
        # the force on the base closes the base's equation: M xdd = fext - C xd - K x - force
        assert force == pytest.approx(
            fext - BASE.damping * z[1] - BASE.stiffness * z[0] - BASE.mass * full[1], rel=1e-12, abs=1e-12 * abs(fext)
        )


@pytest.mark.parametrize("tmd", JACOBIAN_CASES)
@pytest.mark.parametrize("scale", [(1, 1, 1, 1, 1, 1), (1, 1, 1, 1, -1, 1), (1, 1e-6, 1, 1e-6, 0.1, 1)])
def test_analytic_jacobian_matches_complex_step(tmd, scale):
    """The solver's analytic Jacobian and dF/dt against the complex-step derivative of rhs_fext."""
    z = np.array([0.01, 0.1, 0.02, -0.05, 2e-4, 0.3]) * np.array(scale)
    p = pack(BASE, tmd, 19.0)
    J1, J2, f1, f2 = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros(6), np.zeros(6)
    Jac.coupled_jacobian(0.3, z, p, J1, f1)
    Jac.system_jacobian(K.SYS_COUPLED, 0.3, z, p, np.zeros(1), J2)
    Jac.system_dfdt(K.SYS_COUPLED, 0.3, z, p, np.zeros(1), f2)
    np.testing.assert_allclose(J1, J2, rtol=1e-12, atol=1e-12 * np.abs(J2).max())
    np.testing.assert_allclose(f1, f2, rtol=1e-12, atol=1e-12 * np.abs(f2).max())


@pytest.mark.parametrize("tmd", JACOBIAN_CASES)
@pytest.mark.parametrize("scale", [(1, 1, 1, 1), (1, 1, -1, 1), (1, 1e-6, 0.1, 1)])
@pytest.mark.parametrize("kappa", [None, 0.0, 1.0 / 100.0])
def test_tmd_subsystem_jacobian_matches_complex_step(tmd, scale, kappa):
    z = np.array([0.02, -0.05, 2e-4, 0.3]) * np.array(scale)
    u = np.array([0.1, 0.01, 0.1, 0.5, 0.1, 0.5, -3.0, -3.0, 2.0, 1.0])  # x, xd, xdd Taylor inputs
    if kappa is not None:  # the mounting compliance slot (interface Jacobian)
        u = np.append(u, kappa)
    p = pack(BASE, tmd, 19.0)
    J1, J2 = np.zeros((4, 4)), np.zeros((4, 4))
    Jac.tmd_jacobian(0.3, z, p, u, J1)
    Jac.system_jacobian(K.SYS_TMD, 0.3, z, p, u, J2)
    np.testing.assert_allclose(J1, J2, rtol=1e-12, atol=1e-12 * np.abs(J2).max())
