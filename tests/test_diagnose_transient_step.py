"""Tests of the transient simulation's step as tables: the split of the kernels' right-hand side into
a linear part and the nonlinear link forces, RK4 of it as tables, the grid filters per fit block, and
the integrator built on them against the one stepping the right-hand side itself."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
#: every model kind the transient fit simulates: (effects, SI parameters)
KINDS = {
    "ideal": ((), []),
    "viscous": (("viscous",), [10.0]),
    "friction": (("friction",), [5.0, 1000.0]),
    "cubic": (("cubic",), [3e6]),
    "play": (("play",), [1e-4]),
    "friction+cubic": (("friction", "cubic"), [5.0, 1000.0, 3e6]),
    "friction+play": (("friction", "play"), [5.0, 1000.0, 1e-4]),
    "cubic+play": (("cubic", "play"), [3e6, 1e-4]),
}
#: typical sizes of the states x, xd, y, yd, d, dd (m, m/s): the play chain's d spans its gap
SCALE = np.array([2e-3, 2e-2, 4e-3, 4e-2, 2e-4, 2e-2])


def _model(kind: str, p0: np.ndarray | None = None) -> np.ndarray:
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams, pack

    p0 = pack(BaseParams(**BASE), TMDParams(**TMD)) if p0 is None else p0
    eff, th = KINDS[kind]
    mdl = apply(p0, eff, np.array(th, float))
    assert not isinstance(mdl, str)
    return mdl.p


def _rhs(z: np.ndarray, f: float, p: np.ndarray) -> np.ndarray:
    from pyfmu_wrapper.physics.kernels import rhs_fext

    out = np.empty(6)
    rhs_fext(z, f, p, out)
    return out


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_split_is_the_kernels_right_hand_side(kind):
    """rhs_fext(z, f) = A z + b f + E g(z) (:func:`linear_split`, g the nonlinear link forces of
    :func:`link_nonlinear`) on 200 random states and forces, to 1e-13 of the right-hand side's size,
    for every model kind; on states where the play chain is engaged and where it is free."""
    from pyfmu_wrapper.diagnose.system.transient_sim import _PROJ, linear_split
    from pyfmu_wrapper.physics.kernels import link_nonlinear

    p = _model(kind)
    A, b, E = linear_split(p)
    rng = np.random.default_rng(7)
    engaged = 0
    for _ in range(200):
        z = rng.normal(size=6) * SCALE
        f = float(rng.normal(0.0, 100.0))
        g = np.array(link_nonlinear(*(_PROJ @ z), p), float)
        engaged += g[1] != 0.0
        want = _rhs(z, f, p)
        got = A @ z + b * f + E @ g
        assert np.max(np.abs(got - want)) <= 1e-13 * np.max(np.abs(want)), (z, got - want)
    if "play" in kind:
        assert 20 < engaged < 180  # both sides of the gap were checked


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_step_tables_are_rk4_of_the_right_hand_side(kind):
    """The tables' step (:func:`step_tables`, each stage's nonlinear forces at its projections) is
    classical RK4 of :func:`rhs_fext` (:func:`_rk4_step`) to 1e-13 of the state's size, on 100
    random states and forces, and the accelerations row gives rhs_fext's xdd, ydd; a linear model's
    tables are :func:`rk4_affine`'s matrices."""
    from pyfmu_wrapper.diagnose.system.transient_sim import _rk4_step, rk4_affine, step_tables
    from pyfmu_wrapper.physics.kernels import link_nonlinear

    p = _model(kind)
    h = 1.0 / 1600.0
    tabs = step_tables(p, h)
    assert tabs is not None
    stp, prj, acc, nq, ng = tabs
    ns = stp.shape[0]
    assert ng == (0 if kind in ("ideal", "viscous") else (2 if "play" in kind else 1))
    rng = np.random.default_rng(11)
    for _ in range(100):
        z = rng.normal(size=6) * SCALE
        fs = rng.normal(0.0, 100.0, size=3)
        x = np.zeros(stp.shape[1])
        x[:ns], x[ns : ns + 3] = z[:ns], fs
        for i in range(4 if ng else 0):
            lim = ns + 3 + i * ng
            pv = np.zeros(4)
            pv[:nq] = prj[i, :, :lim] @ x[:lim]
            x[lim : lim + ng] = link_nonlinear(*pv, p)[:ng]
        want = _rk4_step(z, fs[0], fs[1], fs[2], p, h)
        assert np.max(np.abs(stp @ x - want[:ns]) / SCALE[:ns]) < 1e-13
        cols = [*range(ns + 1), *range(ns + 3, ns + 3 + ng)]
        assert np.allclose(acc @ x[cols], _rhs(z, fs[0], p)[[1, 3]], rtol=1e-13, atol=1e-12)
    if ng == 0:
        lin = rk4_affine(p, h)
        assert np.allclose(stp, lin[:4][:, [0, 1, 2, 3, 6, 7, 8]], rtol=1e-12, atol=1e-15)


def test_filter_blocks_are_the_grid_filter_stepped_through_a_block():
    """:func:`filter_blocks` gives the Simpson block means and the block's end state of the grid
    filters (:func:`filter_grid`'s first-order-hold step, run point by point here as
    :func:`_integrate` runs it) to 1e-12, over 5 blocks of a random input, for a 4th-order
    Butterworth, a 2nd-order Bessel and an unfiltered channel."""
    from pyfmu_wrapper.diagnose.acquisition import Chain
    from pyfmu_wrapper.diagnose.system.transient_sim import filter_blocks, filter_grid

    chains = {
        "xdd": Chain("xdd", type="butterworth", order=4, cutoff_hz=400.0),
        "ydd": Chain("ydd", type="bessel", order=2, cutoff_hz=150.0),
    }
    n_sub, h, nb = 14, 1.0 / 8000.0, 5
    filt = filter_grid(chains, h)
    nord, phi, g1, g2, cc, dd, ee = filt
    _, Phi, M, r, rho, _ = filter_blocks(filt, n_sub)
    u = np.random.default_rng(3).normal(size=(nb * n_sub + 1, 4))
    w = np.where(np.arange(n_sub + 1) % 2 == 1, 4.0, 2.0) / (3 * n_sub)
    w[0] = w[-1] = 1.0 / (3 * n_sub)
    for c in range(4):
        m = nord[c]
        s = ee[c, :m] * u[0, c]
        for i in range(nb):
            seg = u[i * n_sub : (i + 1) * n_sub + 1, c]
            ys, st = [], s
            for k in range(n_sub + 1):
                if k:
                    st = phi[c, :m, :m] @ st + g1[c, :m] * seg[k - 1] + g2[c, :m] * seg[k]
                ys.append(cc[c, :m] @ st + dd[c] * seg[k] if m else seg[k])
            mean_blk = r[c, :m] @ s + rho[c] @ seg
            end_blk = Phi[c, :m, :m] @ s + M[c, :, :m].T @ seg
            assert abs(mean_blk - w @ np.array(ys)) <= 1e-12 * max(1.0, float(np.max(np.abs(ys))))
            assert np.allclose(end_blk, st, rtol=1e-12, atol=1e-12)
            s = st
    assert nord.tolist() == [0, 0, 4, 2]


def _dataset(path, changes, fs=512.0, T=12.0):
    """A forced and a free-decay record of the truth with ``changes``, accelerations behind a 400 Hz
    Butterworth, 1 % noise."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(0)
    filt = {"filter": {"type": "butterworth", "order": 4, "cutoff_hz": 150.0}}
    acq = {"xdd": filt, "ydd": filt}
    recs = []
    for i, (kind, kw) in enumerate((("random", {"f_lo": 1.0, "f_hi": 8.0}), ("decay", {}))):
        t = np.arange(0.0, T, 1.0 / (8 * fs))
        F = force_signal(kind, rng, T, 100.0, **kw)
        z0 = np.array([0.005, 0.0, 0.01, 0.0]) if kind == "decay" else None
        sig = Truth(BASE, TMD, T, **changes).simulate(F, t, z0)
        if kind == "decay":
            sig.pop("force")
        noise = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}
        write_record(path / f"r{i}.csv", measure(sig, t, 8, rng, noise, acq))
        recs.append({"file": f"r{i}.csv", "kind": "decay" if kind == "decay" else "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": acq}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


def test_table_integrator_gives_the_right_hand_side_integrators_numbers(tmp_path, monkeypatch):
    """:func:`simulate` through :func:`_integrate_tables` against :func:`_integrate` stepping
    :func:`rhs_fext` itself (LINEAR_STEP off), on a forced and a decaying record behind a grid filter:
    the same fit-sample means to 1e-9 of the noise std for every smooth kind and a play chain without a
    gap (eps = 0, engaged throughout). With a gap the play model's flywheel bounces between the gap's
    faces and its simulation is chaotic: a start state moved by 1e-14 relative moves the old
    integrator's own answer by far more than 1e-9 std, so there only the step is compared
    (test_step_tables_are_rk4_of_the_right_hand_side)."""
    import pyfmu_wrapper.diagnose.system.transient_sim as S
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
    from pyfmu_wrapper.physics.params import P_eps

    monkeypatch.setattr(S, "STICK", False)  # (the stick check is the table integrator's alone)
    d = TransientDiagnosis(load_dataset(_dataset(tmp_path, {"df": 5.0})))
    for v in d.views:
        v.z0 = np.array([1e-3, 0.0, 2e-3, 0.0, 0.0, 0.0])
        sig = np.array([v.raw_noise.get(c, 1.0) / math.sqrt(v.q) for c in S.CHANNELS])
        for kind in ("ideal", "viscous", "friction", "cubic", "friction+cubic", "play"):
            p = _model(kind, d.p_nom)
            if kind == "play":
                p[P_eps] = 0.0
            monkeypatch.setattr(S, "LINEAR_STEP", True)
            y = S.simulate(v, p)
            monkeypatch.setattr(S, "LINEAR_STEP", False)
            ref = S.simulate(v, p)
            assert y is not None and ref is not None
            dev = np.max(np.abs(y - ref)[:, v.has] / sig[v.has])
            assert dev < 1e-9, (v.name, kind, dev)
            assert np.max(np.abs(ref[:, v.has]) / sig[v.has]) > 10.0  # the response stands above the noise


@pytest.mark.parametrize("ftype", ["butterworth", "bessel"])
def test_hold_response_in_modal_form_is_the_solve(ftype):
    """:func:`hold_response` in the grid step's eigenvectors gives C (z - phi)^-1 (g1 + g2 z) solved at
    every frequency to 1e-11 of the response's size, for filters of order 1-8 and grid steps from
    1/20 to 1/2 of the cut-off's period."""
    from pyfmu_wrapper.diagnose.acquisition import Chain
    from pyfmu_wrapper.diagnose.system.transient_sim import hold_response

    for order in range(1, 9):
        c = Chain("xdd", type=ftype, order=order, cutoff_hz=400.0)
        for h in (1.0 / 8000.0, 1.0 / 1600.0, 1.0 / 800.0):
            w = 2 * math.pi * np.linspace(0.0, 0.5 / h, 301)
            got = hold_response(c, h, w)
            phi, g1, g2, cc, _ = c.foh_step(h)
            z = np.exp(1j * w * h)
            A = z[:, None, None] * np.eye(order)[None] - phi[None]
            b = g1[None, :] + g2[None, :] * z[:, None]
            want = np.linalg.solve(A, b[:, :, None])[:, :, 0] @ cc
            assert np.max(np.abs(got - want)) < 1e-11 * np.max(np.abs(want)), (order, h)


def test_grid_force_keeps_the_load_cells_noise_where_it_is(tmp_path, monkeypatch):
    """A 4 kHz swept sine whose RK4 grid is coarser than its samples: the simulated response to the
    force channel's white noise has the rms of the fine-grid limit (grid points at every sample) within
    15 % (point values of the force on the coarse grid folded the noise from up to 2 kHz onto the
    structure's band: 3-3.7x the rms here), and the response to the smooth force itself is the fine
    grid's to 0.05 of the channels' noise std (the coarse RK4 step's own error, 0.023 std, the same
    with point values: the local means cost no accuracy)."""
    import pyfmu_wrapper.diagnose.system.transient_sim as S
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis

    fs, T = 4000.0, 20.0
    rng = np.random.default_rng(3)
    t = np.arange(0.0, T, 1.0 / (4 * fs))
    F = force_signal("sweep_lin", rng, T, 150.0, f0=1.5, f1=5.5)
    sig = Truth(BASE, TMD, T).simulate(F, t)
    noise = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.0}
    tmp_path.mkdir(exist_ok=True)
    write_record(tmp_path / "sweep.csv", measure(sig, t, 4, rng, noise))
    doc = {
        "level": "system",
        "nominal": {"base": BASE, "tmd": TMD},
        "records": [{"file": "sweep.csv", "kind": "transient"}],
    }
    (tmp_path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    d = TransientDiagnosis(load_dataset(tmp_path))
    (v,) = d.views
    n_sub = S.refinement(v, d.p_nom)
    assert v.q * v.dt / n_sub > 2 * v.dt  # the grid's steps span several samples
    sig_ch = np.array([v.raw_noise[c] / math.sqrt(v.q) for c in S.CHANNELS])
    smooth = v.force.copy()
    white = np.random.default_rng(1).normal(0.0, 1.0, smooth.size)
    out = {}
    for lab, f in (("smooth", smooth), ("white", white)):
        for n in (n_sub, 2 * v.q):
            v.force, v.fcache = f, {}
            monkeypatch.setattr(S, "refinement", lambda vv, pp, n=n: n)
            y = S.simulate(v, d.p_nom)
            assert y is not None
            out[lab, n] = y[v.skip :]
    ratio = out["white", n_sub].std(axis=0) / out["white", 2 * v.q].std(axis=0)
    assert np.all(np.abs(ratio - 1.0) < 0.15), ratio
    dev = np.max(np.abs(out["smooth", n_sub] - out["smooth", 2 * v.q]) / sig_ch)
    assert dev < 0.05, dev
    assert np.max(np.abs(out["smooth", n_sub]) / sig_ch) > 100.0  # the response stands far above the noise
