"""The integrator takes the model as an argument.

* ``solvers/`` names no physics system by id: the imports and identifiers of every solver module
  are scanned, without exemption (the FMUs build their integrators with make_integrator too);
* a model that the solver has never seen (a linear oscillator, written here) integrated by
  :func:`~pyfmu_wrapper.solvers.rodas.make_integrator` matches its exact solution, lands its steps
  on the switching function's zeros at the exact times and reports the exact maximum: a new model
  needs no edit of the solver.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numba
import numpy as np
import pytest

import pyfmu_wrapper
from pyfmu_wrapper.solvers import rodas

SOLVERS = Path(pyfmu_wrapper.__file__).resolve().parent / "solvers"
#: names that identify a system by id, or switch on one
ID_NAMES = ("SYS_", "system_rhs", "system_switching", "system_jacobian", "system_dfdt", "SYSTEM_SIZE")


def _by_id(name: str) -> bool:
    return any(name == n or name.startswith(n) for n in ID_NAMES)


def test_solvers_import_no_physics_system_by_id():
    offences = []
    for path in sorted(SOLVERS.glob("*.py")):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                for alias in node.names:
                    if _by_id(alias.name):
                        offences.append(f"{path.name}:{node.lineno}: imports {alias.name}")
            elif isinstance(node, ast.Name) and _by_id(node.id):
                offences.append(f"{path.name}:{node.lineno}: uses {node.id}")
            elif isinstance(node, ast.Attribute) and _by_id(node.attr):
                offences.append(f"{path.name}:{node.lineno}: uses .{node.attr}")
    assert not offences, offences


def test_the_integrator_module_imports_nothing_of_physics():
    tree = ast.parse((SOLVERS / "rodas.py").read_text())
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            mod = node.module or ""
            assert "physics" not in mod, f"rodas.py:{node.lineno} imports {mod}"
            assert not (node.level == 2 and mod.startswith("physics")), node.lineno
        elif isinstance(node, ast.Import):
            assert not any("physics" in a.name for a in node.names), node.lineno


# -- a model the solver has never seen: x'' = -w^2 x, switching function g = x --------------------

W = 3.0


@numba.njit
def _osc_rhs(t, z, p, u, out):
    out[0] = z[1]
    out[1] = -p[0] * p[0] * z[0]


@numba.njit
def _osc_jac(t, z, p, u, J, ft, zc, oc):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[0] * p[0]
    J[1, 1] = 0.0
    ft[0] = 0.0
    ft[1] = 0.0


@numba.njit
def _osc_switching(z, p, g):
    g[0] = z[0]


@numba.njit
def _osc_mode(g):
    return 0


class _Oscillator:
    name = "test_linear_oscillator"
    rhs, jacobian, switching, mode = _osc_rhs, _osc_jac, _osc_switching, _osc_mode
    n_switches, n_modes = 1, 1
    switch_tolerance = (-1,)
    state_names = ("x", "v")

    @staticmethod
    def describe(z, p, atol, band):
        return "smooth"


def _integrate(t1, sample_times, rtol=1e-10):
    integrate = rodas.make_integrator(_Oscillator)
    z = np.array([1.0, 0.0])  # x = cos(W t)
    samples = np.zeros((sample_times.size, 2))
    stats = np.zeros(4, dtype=np.int64)
    p = np.array([W])
    h, xmax, status, t = integrate(
        z, 0.0, t1, p, np.zeros(1), rtol, np.full(2, 1e-12), 0.0, 0.2, sample_times, samples, 0.0, stats
    )
    return z, xmax, status, t, samples, stats


def test_new_model_matches_its_exact_solution():
    t1 = 10.0
    ts = np.linspace(0.0, t1, 201)
    z, xmax, status, t, samples, stats = _integrate(t1, ts)
    assert status == rodas.OK and t == t1
    # end state and dense output against x = cos(W t), v = -W sin(W t)
    assert z[0] == pytest.approx(math.cos(W * t1), abs=1e-7)
    assert z[1] == pytest.approx(-W * math.sin(W * t1), abs=3e-7)
    assert np.max(np.abs(samples[:, 0] - np.cos(W * ts))) < 1e-6  # Hermite dense output, 4th order
    # the maximum |x| over the run is the amplitude, 1
    assert xmax == pytest.approx(1.0, abs=1e-9)
    # the zeros of the switching function x were landed on: each retake shortens a step to end
    # just past a zero at t = (k + 1/2) pi / W
    n_zeros = int(t1 * W / math.pi + 0.5)
    assert n_zeros == 10
    assert stats[rodas.STAT_EVENTS] >= n_zeros


def test_steps_land_just_past_the_exact_event_times():
    # integrate in pieces up to each exact zero of x: at the zero the state is (0, -+W)
    t_zero = 0.5 * math.pi / W
    z, _, status, t, _, _ = _integrate(t_zero, np.zeros(0), rtol=1e-12)
    assert status == rodas.OK
    assert abs(z[0]) < 1e-9 and z[1] == pytest.approx(-W, rel=1e-9)


def test_the_model_is_an_argument_not_a_table_entry():
    # the same model object gives the same compiled integrator; another model of the same name is refused
    assert rodas.make_integrator(_Oscillator) is rodas.make_integrator(_Oscillator)

    class Other(_Oscillator):
        pass

    with pytest.raises(ValueError, match="two different models"):
        rodas.make_integrator(Other)
    with pytest.raises(ValueError, match="not a Python identifier"):
        rodas.make_integrator(type("Bad", (_Oscillator,), {"name": "bad name"}))
