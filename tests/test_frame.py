"""Shear frames with a TMD-inerter or TMDI (physics/frame.py), held against independent results:
the paper's base oscillator (the kernels' exact response), the closed-form modes of a uniform shear
frame, the static limit of springs in series, and the energy balance of the steady state."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.linalg import eigh

from pyfmu_wrapper.models.solve import exact_amplitude
from pyfmu_wrapper.physics.frame import LinearTMD, ShearFrame, frequency_response, matrices, top_amplitude
from pyfmu_wrapper.physics.params import BaseParams, paper_case

W = np.linspace(10.0, 30.0, 81)


@pytest.mark.parametrize("damping", [0.0, 10.0])
def test_one_storey_frame_is_the_papers_base_oscillator(damping):
    base = BaseParams()
    tmd = replace(paper_case(1), damping=damping)
    frame = ShearFrame((base.mass,), (base.stiffness,), (base.damping,), force_amplitude=base.force_amplitude)
    lin = LinearTMD(1, tmd.mass, tmd.stiffness, tmd.damping, tmd.inertance)
    ours, kernels = top_amplitude(frame, lin, W), exact_amplitude(base, tmd, W)
    assert np.max(np.abs(ours - kernels)) < 1e-12 * np.max(kernels)  # (c = 0: an exact zero at 20 rad/s)


@pytest.mark.parametrize("n", [1, 3, 10, 20])
def test_uniform_frame_modes_are_the_closed_form(n):
    """Undamped modes of a uniform shear frame fixed at the ground, free at the top:
    w_r = 2 sqrt(k/m) sin((2r - 1) pi / (2 (2n + 1)))."""
    m, k = 100.0, 1.2e5
    M, B, C, K, F = matrices(ShearFrame.uniform(n, m, k, 0.0))
    w = np.sqrt(eigh(K, M, eigvals_only=True))
    r = np.arange(1, n + 1)
    exact = 2 * np.sqrt(k / m) * np.sin((2 * r - 1) * np.pi / (2 * (2 * n + 1)))
    assert np.max(np.abs(w - exact) / exact) < 1e-12


def test_static_limit_is_springs_in_series():
    frame = ShearFrame((100.0, 120.0, 80.0), (1.2e5, 2e5, 9e4), (100.0, 50.0, 70.0), force_amplitude=200.0)
    tmd = LinearTMD(3, 10.0, 3500.0, 20.0, 5.0, inerter_to=2)
    X = frequency_response(frame, tmd, [1e-9])[0]
    top = 200.0 * sum(1 / k for k in (1.2e5, 2e5, 9e4))
    assert abs(X[2].real - top) / top < 1e-12 and abs(X[3].real - top) / top < 1e-12


@pytest.mark.parametrize("terminal", [None, 2, 0])
def test_steady_state_power_in_is_power_dissipated(terminal):
    """Average power of the force = average power of every damper (springs and inerters store only)."""
    frame = ShearFrame.uniform(3, 100.0, 1.2e5, 100.0, force_amplitude=200.0, force_storey=2)
    tmd = LinearTMD(3, 10.0, 3500.0, 20.0, 5.0, inerter_to=terminal)
    for w in (12.0, 19.3, 27.0):
        X = frequency_response(frame, tmd, [w])[0]
        V = 1j * w * X
        p_in = 0.5 * np.real(200.0 * np.conj(V[1]))
        rel = [V[0]] + [V[i] - V[i - 1] for i in (1, 2)] + [V[3] - V[2]]
        cs = [100.0, 100.0, 100.0, 20.0]
        p_out = 0.5 * sum(c * abs(v) ** 2 for c, v in zip(cs, rel))
        assert abs(p_in - p_out) / p_out < 1e-10


def test_tmdi_terminal_matters_and_vanishes_with_the_inerter():
    frame = ShearFrame.uniform(3, 100.0, 1.2e5, 100.0)
    at3 = LinearTMD(3, 10.0, 3500.0, 20.0, 5.0)
    at2 = replace(at3, inerter_to=2)
    ground = replace(at3, inerter_to=0)
    a3, a2, a0 = (top_amplitude(frame, t, W) for t in (at3, at2, ground))
    assert np.max(np.abs(a2 - a3) / a3) > 0.05 and np.max(np.abs(a0 - a3) / a3) > 0.05
    no_inerter = [top_amplitude(frame, replace(t, inertance=0.0), W) for t in (at3, at2, ground)]
    assert np.max(np.abs(no_inerter[1] - no_inerter[0])) == 0.0 and np.max(np.abs(no_inerter[2] - no_inerter[0])) == 0.0


@pytest.mark.parametrize(
    "bad",
    [
        dict(masses=(), stiffnesses=(), dampings=()),
        dict(masses=(1.0,) * 21, stiffnesses=(1.0,) * 21, dampings=(0.0,) * 21),
        dict(masses=(1.0, 0.0), stiffnesses=(1.0, 1.0), dampings=(0.0, 0.0)),
        dict(masses=(1.0,), stiffnesses=(1.0, 2.0), dampings=(0.0,)),
        dict(masses=(1.0,), stiffnesses=(1.0,), dampings=(-1.0,)),
        dict(masses=(1.0,), stiffnesses=(1.0,), dampings=(0.0,), force_storey=2),
    ],
)
def test_non_physical_frames_are_refused_naming_the_field(bad):
    with pytest.raises(ValueError, match="storey|masses|stiffnesses|dampings|force_storey"):
        ShearFrame(**bad)
