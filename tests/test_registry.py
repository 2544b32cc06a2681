"""The parameter registry and everything derived from it; the cubic TMD spring k3 end to end.

Derived artefacts held against ``physics/registry.py``: the parameter classes (fields, defaults,
bounds), the kernels' packed indices, the FMU variable tables, the master's FMU start values,
the scenario map parameters, the Modelica defaults and declarations (``test_modelica.py`` runs the
generator check and compiles them) and ``docs/parameters.md``.

k3 checks, each against something independent:
* k3 = 0 gives, bit for bit, the values of the same kernels compiled in the same run with the cubic
  term taken out (the spring k u and its slope k of commit 85cdaf1, the last commit without k3);
* the energy kernel (with its k3 (x-y)^4 / 4 term) is consistent with the right-hand side:
  dE/dt along the flow equals input minus dissipated power;
* the hardening shift of the upper resonance peak against a one-harmonic balance estimate.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import types

import numba
import numpy as np
import pytest
from scipy.optimize import brentq, minimize_scalar

from pyfmu_wrapper.fmi.varspec import INTEGER
from pyfmu_wrapper.generate import docs as docs_gen
from pyfmu_wrapper.models.base_tmd.cosim import fmu_parameters
from pyfmu_wrapper.models.base_tmd.fmus.variables import BASE_OSCILLATOR, TMD_INERTER
from pyfmu_wrapper.models.solve import steady_state
from pyfmu_wrapper.physics import jacobians as Jac
from pyfmu_wrapper.physics import kernels as K
from pyfmu_wrapper.physics import params as P
from pyfmu_wrapper.physics import registry
from pyfmu_wrapper.physics.params import BaseParams, ParameterError, TMDParams, pack, paper_case
from pyfmu_wrapper.scenario.schema import MAP_PARAMETERS

BASE = BaseParams()


# --- derived artefacts ------------------------------------------------------------------------


@pytest.mark.parametrize("cls, sub", [(BaseParams, "base"), (TMDParams, "tmd")])
def test_parameter_classes_follow_the_registry(cls, sub):
    names = [f.name for f in dataclasses.fields(cls) if f.name != "source"]
    assert names == [p.name for p in registry.fields(sub)]
    obj = cls()
    for p in registry.fields(sub):
        assert getattr(obj, p.name) == p.default, p.name


@pytest.mark.parametrize("cls, sub", [(P.BaseParams, "base"), (P.TMDParams, "tmd")])
def test_the_declared_fields_are_the_registry_rows_in_order(cls, sub):
    """The parameter classes are plain dataclasses written out; their fields, in order, their types and
    defaults are the registry's rows (the defaults are read from the registry, the names are not)."""
    declared = {k: v for k, v in cls.__annotations__.items() if k != "source"}
    assert list(declared) == [p.name for p in registry.fields(sub)]
    for p in registry.fields(sub):
        assert declared[p.name] == ("InerterModel" if p.kind == "enum" else "float"), p.name


@pytest.mark.parametrize(
    "par", [p for p in registry.PARAMETERS if p.field and p.kind == "real"], ids=lambda p: f"{p.subsystem}.{p.name}"
)
def test_every_bound_of_the_registry_is_enforced(par):
    cls = BaseParams if par.subsystem == "base" else TMDParams
    kw = {"inerter": "play", "play_gap": 1e-4} if par.subsystem == "tmd" else {}
    with pytest.raises(ParameterError, match=par.name):
        cls(**{**kw, par.name: float("nan")}, source="test.yaml:3")
    if par.minimum is not None:
        bad = par.minimum if par.strict else par.minimum - 1.0
        with pytest.raises(ParameterError, match=rf"{par.name} \({par.symbol}\) must be >"):
            cls(**{**kw, par.name: bad})


def test_packed_indices_are_the_registry_order():
    tmd = paper_case(2, damping=3.0, friction_force=4.0, inerter="play", play_gap=5e-5, cubic_stiffness=7.0)
    p = pack(BASE, tmd, 19.5)
    assert p.shape == (registry.N_PARAMS,)
    for i, par in enumerate(registry.PARAMETERS):
        owner = BASE if par.subsystem == "base" else tmd
        want = (
            19.5
            if par.name == "omega"
            else float(int(getattr(owner, par.name)) if par.kind == "enum" else getattr(owner, par.name))
        )
        assert p[i] == want, par.name
        assert registry.PACK_INDEX[f"{par.subsystem}.{par.name}"] == i
    assert (P.P_k3, P.P_k, P.P_MODEL, P.P_W) == (
        registry.PACK_INDEX["tmd.cubic_stiffness"],
        registry.PACK_INDEX["tmd.stiffness"],
        registry.PACK_INDEX["tmd.inerter"],
        registry.PACK_INDEX["base.omega"],
    )


@pytest.mark.parametrize("spec, sub", [(BASE_OSCILLATOR, "base"), (TMD_INERTER, "tmd")])
def test_fmu_parameters_follow_the_registry(spec, sub):
    for par in registry.of(sub):
        v = spec.by_name(par.fmu_name)
        assert (v.vr, v.causality, v.start) == (par.fmu_vr, "parameter", par.default), par.name
        assert v.type == (INTEGER if par.kind == "enum" else "Real")
        # every output depends initially on every model parameter
    for out in spec.of("output"):
        if out.name in ("force", "inerter_force"):
            assert set(p.fmu_name for p in registry.of(sub)) <= set(out.initial_depends_on)


def test_master_start_values_cover_every_registry_parameter():
    tmd = paper_case(1, cubic_stiffness=123.0)
    vals = fmu_parameters(BASE, tmd, 18.0, np.zeros(6))
    for par in registry.PARAMETERS:
        key = f"{par.subsystem}.{par.fmu_name}"
        assert key in vals, key
    assert vals["tmd.k3"] == 123.0 and vals["base.w"] == 18.0


def test_map_parameters_and_docs_are_derived():
    assert "cubic_stiffness" in MAP_PARAMETERS and "inerter" not in MAP_PARAMETERS
    assert set(MAP_PARAMETERS) - {"inertance_ratio"} == {p.name for p in registry.fields("tmd") if p.mappable}
    assert docs_gen.main(["--check"]) == 0, "run `python -m pyfmu_wrapper.generate.docs`"


# --- k3 = 0 is the model without the cubic term, bit for bit ----------------------------------------
# Both sides are compiled and evaluated in this run, so the comparison holds on every processor: the
# cubic term must add exactly nothing at k3 = 0 (k u + 0 u^3 = k u in IEEE arithmetic, fused or not).


def _recompiled(kernel, **callees):
    """``kernel`` (a compiled function of physics/) compiled afresh, with the functions it calls by
    the names in ``callees`` replaced (the technique of ``solvers.rodas.make_integrator``)."""
    py = kernel.py_func
    fn = types.FunctionType(py.__code__, {**py.__globals__, **callees}, py.__name__, py.__defaults__, py.__closure__)
    return numba.njit(fn)


@numba.njit
def _linear_spring(u, p):
    """The TMD spring of the kernels before k3 (commit 85cdaf1): k u."""
    return p[P.P_k] * u


@numba.njit
def _linear_stiffness(u, p):
    """Its slope: k (85cdaf1's Jacobian took p[P_k] as the spring's gradient)."""
    return p[P.P_k]


@functools.cache
def _kernels_without_the_cubic_term():
    """(rhs, coupled_jacobian) of physics/, compiled with the spring k u instead of k u + k3 u^3:
    rhs -> rhs_fext -> tmd_link -> static_link_force -> spring_force; coupled_jacobian -> spring_stiffness."""
    static = _recompiled(K.static_link_force, spring_force=_linear_spring)
    link = _recompiled(K.tmd_link, static_link_force=static)
    rhs = _recompiled(K.rhs, rhs_fext=_recompiled(K.rhs_fext, tmd_link=link))
    return rhs, _recompiled(Jac.coupled_jacobian, spring_stiffness=_linear_stiffness)


ZERO_K3_TMD = {
    "friction": paper_case(1, damping=10.0, friction_force=10.0),
    "full_play": paper_case(2, damping=10.0, friction_force=10.0, inerter="play", play_gap=1e-4),
    "ideal": paper_case(3, damping=6.45),
    "none": TMDParams(mass=10.0, inertance=0.0, inerter="none", damping=56.38),
}
#: states: both friction directions, the play chain engaged in compression, in extension and free
ZERO_K3_STATES = [
    [0.011, -0.13, 0.017, 0.21, 1.3e-4, 0.05],
    [-0.02, 0.4, 0.013, -0.35, -1.7e-4, -0.8],
    [0.003, 0.07, -0.009, 0.071, 0.4e-4, 0.02],
]


@pytest.mark.parametrize("name", sorted(ZERO_K3_TMD))
def test_zero_cubic_term_equals_the_kernels_without_it_bit_for_bit(name):
    """rhs and the hand-derived Jacobian (J and dF/dt) at k3 = 0 equal, bit for bit, those of the same
    kernels compiled in this run without the cubic term; and with k3 = 1e6 they do not (the
    recompiled kernels really lack the term)."""
    rhs0, jac0 = _kernels_without_the_cubic_term()
    tmd = ZERO_K3_TMD[name]
    assert tmd.cubic_stiffness == 0.0
    p = pack(BASE, tmd, 19.0)
    for t, z in zip((0.3, 0.0, 1.7), np.array(ZERO_K3_STATES)):
        out, ref = np.zeros(6), np.zeros(6)
        K.rhs(t, z, p, out)
        rhs0(t, z, p, ref)
        assert np.array_equal(out, ref), (t, z, out - ref)
        J, ft, J0, ft0 = np.zeros((6, 6)), np.zeros(6), np.zeros((6, 6)), np.zeros(6)
        Jac.coupled_jacobian(t, z, p, J, ft)
        jac0(t, z, p, J0, ft0)
        assert np.array_equal(J, J0) and np.array_equal(ft, ft0), (t, z, J - J0)
    p3 = pack(BASE, dataclasses.replace(tmd, cubic_stiffness=1e6), 19.0)
    out, ref = np.zeros(6), np.zeros(6)
    K.rhs(0.3, z, p3, out)
    rhs0(0.3, z, p3, ref)
    assert out[1] != ref[1]


# --- k3 in the physics ------------------------------------------------------------------------


@pytest.mark.parametrize("k3", [4e6, -3e5])
def test_cubic_spring_force_and_energy_balance(k3):
    """Spring force k u + k3 u^3; dE/dt along the flow = input - dissipated (energy kernel has k3 u^4/4)."""
    tmd = paper_case(1, damping=10.0, cubic_stiffness=k3)
    p = pack(BASE, tmd, 19.0)
    u = 0.013
    assert K.spring_force(u, p) == pytest.approx(4e3 * u + k3 * u**3, rel=1e-15)
    assert Jac.spring_stiffness(u, p) == pytest.approx(4e3 + 3 * k3 * u**2, rel=1e-15)
    z = np.array([0.011, -0.13, -0.017, 0.21, 0.0, 0.0])
    f = np.zeros(6)
    K.rhs(0.3, z, p, f)
    h = 1e-7
    dE = (K.energy(z + h * f, p) - K.energy(z - h * f, p)) / (2 * h)
    pin, pd = K.power_balance(0.3, z, p)
    assert dE == pytest.approx(pin - pd, rel=1e-6, abs=1e-9)
    p0 = pack(BASE, paper_case(1, damping=10.0), 19.0)
    assert K.energy(z, p) - K.energy(z, p0) == pytest.approx(0.25 * k3 * (z[0] - z[2]) ** 4, rel=1e-9)


def test_cubic_spring_is_not_linear():
    assert not paper_case(1, cubic_stiffness=1.0).is_linear and paper_case(1).is_linear


def _harmonic_balance_amplitude(w, tmd: TMDParams) -> float:
    """One-harmonic balance: the cubic term acts as k + (3/4) k3 U^2, U = |X - Y| (single branch)."""
    M, Kb, C, F = BASE.mass, BASE.stiffness, BASE.damping, BASE.force_amplitude
    m, I, c = tmd.mass, tmd.inertance, tmd.damping

    def frf(ke):
        Mm = np.array([[M + I, -I], [-I, m + I]])
        Km = np.array([[Kb + ke, -ke], [-ke, ke]])
        Cm = np.array([[C + c, -c], [-c, c]])
        return np.linalg.solve(-w * w * Mm + 1j * w * Cm + Km, np.array([F, 0.0]))

    def ke(U):
        return tmd.stiffness + 0.75 * tmd.cubic_stiffness * U * U

    def g(U):
        X = frf(ke(U))
        return abs(X[0] - X[1]) - U

    grid = np.linspace(0.0, 0.3, 301)
    vals = [g(U) for U in grid]
    roots = [brentq(g, grid[i], grid[i + 1], xtol=1e-15) for i in range(300) if vals[i] * vals[i + 1] < 0]
    assert len(roots) == 1, "harmonic balance: not a single-valued branch"
    return abs(frf(ke(roots[0]))[0])


def test_hardening_shift_of_the_upper_peak_matches_harmonic_balance():
    """Case 1, c = 56.38: k3 = 2e5 N/m^3 moves the upper peak up by ~0.6 rad/s; the simulated
    peak (Newton shooting) lies within 5 % of that shift of the harmonic-balance peak."""
    peaks = {}
    for k3 in (0.0, 2e5):
        tmd = paper_case(1, damping=56.38, cubic_stiffness=k3)
        sim = minimize_scalar(
            lambda w, tmd=tmd: -steady_state(BASE, tmd, w).amplitude,
            bounds=(21.0, 25.0),
            method="bounded",
            options=dict(xatol=1e-4),
        )
        hb = minimize_scalar(
            lambda w, tmd=tmd: -_harmonic_balance_amplitude(w, tmd),
            bounds=(21.0, 25.0),
            method="bounded",
            options=dict(xatol=1e-4),
        )
        peaks[k3] = (sim.x, -sim.fun, hb.x, -hb.fun)
    shift = peaks[2e5][0] - peaks[0.0][0]
    assert shift > 0.5  # hardening
    assert abs(peaks[0.0][0] - peaks[0.0][2]) < 1e-3  # linear: both are the exact FRF peak
    assert abs(peaks[2e5][0] - peaks[2e5][2]) <= 0.05 * shift, peaks
    assert peaks[2e5][1] == pytest.approx(peaks[2e5][3], rel=2e-3)


def test_cubic_spring_in_the_fmus_matches_the_monolithic_solver():
    """The TMDInerter FMU takes k3 from the registry: two periods co-simulated (default coupling)
    against the monolithic solver from the same start, within 0.5 % of max |x|; and the effect of
    k3 on that run is far larger than the agreement (so the FMU did not ignore it)."""
    import math

    from pyfmu_wrapper.fmubuild.build import ensure_fmus
    from pyfmu_wrapper.models import solve as mono
    from pyfmu_wrapper.models.base_tmd.cosim import make_master
    from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick

    paths = ensure_fmus(pick(PROJECT_FMUS))
    fmus = {"base": paths["BaseOscillator"], "tmd": paths["TMDInerter"]}
    w = 19.0
    T = 2 * math.pi / w
    runs = {}
    for k3 in (0.0, 2e6):
        tmd = paper_case(1, damping=10.0, cubic_stiffness=k3)
        z0 = mono.initial_guess(BASE, tmd, w)
        m = make_master(BASE, tmd, "loop", 2, fmus=fmus, coupling="impulse")
        try:
            m.initialize(0.0, fmu_parameters(BASE, tmd, w, z0))
            res = m.run(2 * T, step=T / 200)
        finally:
            m.close()
        _, st = mono.simulate(BASE, tmd, w, 2 * T * (1 + 1e-9), z0, sample_times=res.t, rtol=1e-10)
        runs[k3] = (np.asarray(res["base.x"]), st[:, 0])
    x_co, x_mono = runs[2e6]
    err = np.max(np.abs(x_co - x_mono)) / np.max(np.abs(x_mono))
    effect = np.max(np.abs(runs[0.0][1] - x_mono)) / np.max(np.abs(x_mono))
    print(f"k3 FMU: err {err:.2e}, effect {effect:.2e}")
    assert err <= 5e-3 and effect >= 20 * err, (err, effect)


def test_every_registry_unit_has_its_si_exponents_in_the_model_description():
    """Every declared parameter's unit string reads by FMI's unit grammar (no table of unit strings)."""
    from pyfmu_wrapper.fmi.units import base_unit

    for par in registry.PARAMETERS:
        base_unit(par.unit, where=f"parameter {par.name}")


def test_linearisation_about_rest_is_the_small_amplitude_limit():
    """The exact linearisation of the cubic spring about rest is the linear spring (A identical to
    k3 = 0 to rounding); at F = 0.02 N the simulated cubic response equals it to 1e-6, at F = 200 N
    it does not (the nonlinearity is real)."""
    from pyfmu_wrapper.models.solve import exact_amplitude, linear_system

    tmd = paper_case(1, damping=10.0, cubic_stiffness=3e6)
    A3, b3 = linear_system(BASE, tmd, linearise=True)
    A0, b0 = linear_system(BASE, paper_case(1, damping=10.0))
    np.testing.assert_allclose(A3, A0, rtol=1e-14, atol=1e-14 * np.abs(A0).max())
    with pytest.raises(ParameterError, match="cubic_stiffness"):
        linear_system(BASE, tmd)
    small = BaseParams(force_amplitude=0.02)
    for w in (18.0, 22.0):
        lin = exact_amplitude(small, tmd, [w], linearise=True)[0]
        assert steady_state(small, tmd, w).amplitude == pytest.approx(lin, rel=1e-6)
        big_lin = exact_amplitude(BASE, tmd, [w], linearise=True)[0]
        assert abs(steady_state(BASE, tmd, w).amplitude / big_lin - 1) > 1e-2


def test_modelica_generated_blocks_follow_the_registry(tmp_path):
    """A hand edit inside a generated block of Systems.mo (dropping k3 from the TMD instance) is
    reported stale in that package copy and rewritten by the generator; the registry's TMD
    parameters all appear in the regenerated declarations."""
    import shutil

    from pyfmu_wrapper.generate import modelica as gen

    pkg = tmp_path / gen.PACKAGE
    shutil.copytree(gen.PACKAGE_DIR, pkg)
    sysmo = pkg / "Systems.mo"
    text = sysmo.read_text()
    assert gen.stale_files(pkg) == []
    assert text.count("slope = slope, I = I, k3 = k3);") == 1  # the ideal-inerter TMD instance
    sysmo.write_text(text.replace("slope = slope, I = I, k3 = k3);", "slope = slope, I = I);"))
    assert gen.stale_files(pkg) == ["Systems.mo"]
    gen.write(pkg)
    assert sysmo.read_text() == text and gen.stale_files(pkg) == []
    for par in registry.fields("tmd"):
        if par.modelica_name:
            assert f" {par.modelica_name} = {gen.PACKAGE}.Defaults.{par.modelica_name} " in text, par.name
    assert gen.main(["--check", "--dir", str(tmp_path / "nowhere")]) == 2


# --- the registry of model units ------------------------------------------------------------------

# The engines' pieces of the paper's model as they were before the model units (main 54ba3a5:
# solvers/monolithic.py and solvers/frequency_response.py), written out from the kernels. The test below
# holds the unit against them in the same run: the amplitudes themselves differ in their last bits from
# one processor to another (OpenBLAS picks its kernels by CPU), a same-run comparison does not.


def _pre_registry_atol(base, tmd, omega, atol_scale):
    """54ba3a5's monolithic._atol (with start.play_atol)."""
    xs = abs(base.force_amplitude) / max(base.stiffness, 1e-300)
    xs = xs if xs > 0 else 1e-3
    wn = max(omega, base.natural_frequency, 1.0)
    a = atol_scale * xs
    atol = np.array([a, a * wn, a, a * wn, a, a * wn])
    if P.has_gap(tmd):
        pen = max(abs(base.force_amplitude) / tmd.mesh_stiffness, 1e-12)
        atol[4] = min(atol[4], 1e-3 * max(tmd.play_gap, pen) + pen)
        atol[5] = atol[4] * math.sqrt(tmd.mesh_stiffness / tmd.inertance)
    return atol


def _pre_registry_active(tmd):
    """54ba3a5's monolithic._active_states."""
    return list(range(6)) if tmd.inerter == P.InerterModel.PLAY else [0, 1, 2, 3]


def _pre_registry_inerter_force(z, p):
    """54ba3a5's monolithic.companion_start: the inerter force P at state z."""
    f = np.empty(K.NSTATE)
    K.rhs(0.0, z, p, f)
    return K.inerter_force(z, f[1], p)


def _pre_registry_linear_system(base, tmd, linearise):
    """54ba3a5's frequency_response.linear_system: A, b read off rhs_fext (the complex-step Jacobian
    at rest with ``linearise``)."""
    p = pack(base, tmd)
    A = np.empty((K.NSTATE, K.NSTATE))
    if linearise:
        Jac.jacobian(0.0, np.zeros(K.NSTATE), p, A)
    else:
        fp, fm = np.empty(K.NSTATE), np.empty(K.NSTATE)
        for j in range(K.NSTATE):
            e = np.zeros(K.NSTATE)
            e[j] = 1.0
            K.rhs_fext(e, 0.0, p, fp)
            K.rhs_fext(-e, 0.0, p, fm)
            A[:, j] = 0.5 * (fp - fm)
    b = np.empty(K.NSTATE)
    K.rhs_fext(np.zeros(K.NSTATE), 1.0, p, b)
    return A, b


def _pre_registry_simulate(base, tmd, omega, t_end, n_samples):
    """54ba3a5's monolithic.simulate from rest: the coupled integrator called directly."""
    from pyfmu_wrapper.physics.models import COUPLED
    from pyfmu_wrapper.solvers.rodas import DEFAULT_MAX_STEPS, OK, make_integrator

    t = np.linspace(0.0, t_end, n_samples)
    out = np.zeros((t.size, K.NSTATE))
    T = 2 * math.pi / omega
    status = make_integrator(COUPLED)(
        np.zeros(K.NSTATE),
        0.0,
        float(t_end),
        pack(base, tmd, omega),
        np.zeros(1),
        1e-9,
        _pre_registry_atol(base, tmd, omega, 1e-7),
        T / 200,
        T / 20,
        t,
        out,
        1.0 / tmd.friction_slope,
        np.zeros(4, dtype=np.int64),
        DEFAULT_MAX_STEPS * max(1, math.ceil(t_end / T)),
    )[2]
    assert status == OK
    return out


def test_model_units_leave_the_papers_numbers_bit_identical():
    """The engines take the paper's model from its unit (models/base_tmd); every piece the unit hands
    them equals, bit for bit and computed in this run, what the engines used before the model units
    (main 54ba3a5, written out above): the equations, the packed parameters, the absolute tolerances,
    the states the shooting moves, the inerter force of the play start, the linear system of the exact
    response and of the linearisation about rest (and the amplitudes solved from them); and simulate
    gives, state for state, the integrator called as it was. So the steady states, which are the
    solver's code run on these pieces, are the paper's numbers of before."""
    from pyfmu_wrapper.models import MODELS
    from pyfmu_wrapper.models.solve import exact_amplitude, linear_system, simulate
    from pyfmu_wrapper.physics.models import COUPLED
    from pyfmu_wrapper.solvers.monolithic import SolverSettings

    unit = MODELS.of(BASE)
    assert unit.ode is COUPLED and unit.n_state(BASE) == K.NSTATE
    cases = {
        "ideal_c10": paper_case(1, damping=10.0),
        "friction": paper_case(1, friction_force=10.0, damping=5.0),
        "full": paper_case(1, inerter="play", play_gap=1e-4, damping=10.0, friction_force=10.0),
    }
    for name, tmd in cases.items():
        assert unit.active(BASE, tmd) == _pre_registry_active(tmd), name
        for w in (18.0, 21.0):
            p = pack(BASE, tmd, w)
            assert np.array_equal(unit.pack(BASE, tmd, w), p), (name, w)
            for scale in (SolverSettings().atol_scale, 1e-7):
                assert np.array_equal(unit.atol(BASE, tmd, w, scale), _pre_registry_atol(BASE, tmd, w, scale))
            for z in np.array(ZERO_K3_STATES):
                assert unit.inerter_force(z, p) == _pre_registry_inerter_force(z, p), (name, w, z)

    F = BASE.force_amplitude
    for tmd, linearise, omegas in (
        (cases["ideal_c10"], False, [15.0, 20.0, 25.0]),
        (paper_case(2, cubic_stiffness=1e6), True, [19.0]),
    ):
        A, b = linear_system(BASE, tmd, linearise=linearise)
        A0, b0 = _pre_registry_linear_system(BASE, tmd, linearise)
        assert np.array_equal(A, A0) and np.array_equal(b, b0), linearise
        Z0 = np.array([np.linalg.solve(1j * w * np.eye(K.NSTATE) - A0, b0 * F) for w in omegas])
        amp0 = np.abs(Z0[:, 0])  # as exact_amplitude takes it (numpy's complex abs of a strided column)
        assert np.array_equal(exact_amplitude(BASE, tmd, omegas, linearise=linearise), amp0), linearise

    _, z = simulate(BASE, cases["full"], 20.0, 1.0, n_samples=5)
    assert np.array_equal(z, _pre_registry_simulate(BASE, cases["full"], 20.0, 1.0, 5))
    assert np.max(np.abs(z[-1, :4])) > 1e-3  # a run that went somewhere


def test_the_registry_holds_every_model_and_finds_it_by_structure():
    from pyfmu_wrapper.models import MODELS, base_tmd, frame_model
    from pyfmu_wrapper.physics.unit import ModelError, Registry

    # the first two models, in registration order (a model added later needs no edit here)
    assert MODELS.names()[:2] == ("base_tmd", "frame") and len(set(MODELS.names())) == len(MODELS.names())
    assert MODELS.of(BASE) is base_tmd.UNIT and MODELS.get("frame") is frame_model.UNIT
    frame = frame_model.FrameParams.uniform(2, 100.0, 1e5, 10.0)
    assert MODELS.of(frame) is frame_model.UNIT
    with pytest.raises(ModelError, match="no registered model takes a TMDParams"):
        MODELS.of(TMDParams())
    with pytest.raises(ModelError, match="no model named 'x'; registered: base_tmd, frame"):
        MODELS.get("x")
    fresh = Registry()
    fresh.register(base_tmd.UNIT)
    with pytest.raises(ValueError, match="registered already"):
        fresh.register(base_tmd.UNIT)
    # a unit's own subsystem is declared in the parameter registry, beside base and tmd, and not packed
    # with the paper's array
    assert [p.name for p in registry.of("frame")][:4] == ["storeys", "mass", "stiffness", "damping"]
    assert all(p.subsystem in ("base", "tmd") for p in registry.PARAMETERS)
    with pytest.raises(ValueError, match="subsystem must be one of base, tmd, frame"):
        registry.of("bridge")
    for unit in MODELS.units():  # every unit's declared parameters carry unit, bounds and a description
        assert unit.parameters and all(p.unit and p.description for p in unit.parameters)
