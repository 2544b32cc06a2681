"""The compiled matrix exponential (solvers/expm.py) against scipy's and against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.linalg

from pyfmu_wrapper.physics.linear import base_augmented_matrix
from pyfmu_wrapper.physics.params import BaseParams, TMDParams, pack
from pyfmu_wrapper.solvers.expm import expm


@pytest.mark.parametrize("n", [1, 2, 5, 7])
@pytest.mark.parametrize("scale", [1e-3, 0.3, 3.0, 40.0])
def test_random_matrices_agree_with_scipy(n, scale):
    rng = np.random.default_rng(n * 1000 + int(scale * 10))
    a = rng.normal(size=(n, n)) * scale / n
    e = np.empty((n, n))
    expm(a, e)
    r = scipy.linalg.expm(a)
    assert np.max(np.abs(e - r)) <= 1e-13 * max(1.0, scale) * np.max(np.abs(r))


def test_limits_zero_rotation_and_not_finite():
    e = np.empty((3, 3))
    assert expm(np.zeros((3, 3)), e) == 0
    assert np.array_equal(e, np.eye(3))  # exp(0) = I exactly
    w, h = 25.0, 0.37  # a rotation: exp([[0, -w], [w, 0]] h) = [[cos, -sin], [sin, cos]](w h)
    r = np.empty((2, 2))
    expm(np.array([[0.0, -w], [w, 0.0]]) * h, r)
    c, s = math.cos(w * h), math.sin(w * h)
    assert np.max(np.abs(r - np.array([[c, -s], [s, c]]))) < 1e-14
    assert expm(np.array([[np.inf]]), r[:1, :1].copy()) == -1


def test_base_flow_equals_scipy_and_undamped_closed_form():
    p = pack(BaseParams(damping=0.0, force_amplitude=0.0), TMDParams(), 17.0)
    a = np.empty((7, 7))
    base_augmented_matrix(p, a)
    for h in (1e-4, 3e-3, 0.2, 1.0):
        e = np.empty((7, 7))
        expm(a * h, e)
        assert np.max(np.abs(e - scipy.linalg.expm(a * h))) < 1e-13 * np.max(np.abs(e))
        wn = math.sqrt(4.0e4 / 100.0)  # undamped base: x(h) = x0 cos(wn h) + xd0 sin(wn h) / wn
        assert e[0, 0] == pytest.approx(math.cos(wn * h), abs=1e-13)
        assert e[0, 1] == pytest.approx(math.sin(wn * h) / wn, abs=1e-14)
