"""The monolithic solver on a structure of any registered model: each function finds the structure's
unit in :data:`~pyfmu_wrapper.models.MODELS` once and hands it to the solver of the same name
(:mod:`pyfmu_wrapper.solvers`, which takes the unit as an argument and knows no model).

The applications (``run-scenario``, the paper, the diagnosis) and the tests call these; a model's own
folder calls the solvers with its unit directly.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..physics.params import TMDParams
from ..solvers import frequency_response as fr
from ..solvers import monolithic as mono
from ..solvers import start as st
from ..solvers import sweep as sw
from . import MODELS


def steady_state(base: Any, tmd: TMDParams, omega: float, *args: Any, **kwargs: Any) -> mono.SteadyState:
    """:func:`pyfmu_wrapper.solvers.monolithic.steady_state` on the structure's model."""
    return mono.steady_state(MODELS.of(base), base, tmd, omega, *args, **kwargs)


def simulate(base: Any, tmd: TMDParams, omega: float, t_end: float, *args: Any, **kwargs: Any) -> Any:
    """:func:`pyfmu_wrapper.solvers.monolithic.simulate` on the structure's model."""
    return mono.simulate(MODELS.of(base), base, tmd, omega, t_end, *args, **kwargs)


def periodic_time_series(base: Any, tmd: TMDParams, omega: float, *args: Any, **kwargs: Any) -> Any:
    """:func:`pyfmu_wrapper.solvers.monolithic.periodic_time_series` on the structure's model."""
    return mono.periodic_time_series(MODELS.of(base), base, tmd, omega, *args, **kwargs)


def companion_start(base: Any, tmd: TMDParams, omega: float, *args: Any, **kwargs: Any) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.monolithic.companion_start` on the structure's model."""
    return mono.companion_start(MODELS.of(base), base, tmd, omega, *args, **kwargs)


def integrator_atol(base: Any, tmd: TMDParams, omega: float, settings: mono.SolverSettings) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.monolithic.integrator_atol` on the structure's model."""
    return mono.integrator_atol(MODELS.of(base), base, tmd, omega, settings)


def initial_guess(base: Any, tmd: TMDParams, omega: float) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.start.initial_guess` on the structure's model."""
    return st.initial_guess(MODELS.of(base), base, tmd, omega)


def linear_system(base: Any, tmd: TMDParams, linearise: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pyfmu_wrapper.solvers.frequency_response.linear_system` on the structure's model."""
    return fr.linear_system(MODELS.of(base), base, tmd, linearise)


def exact_response(base: Any, tmd: TMDParams, omegas: ArrayLike, linearise: bool = False) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.frequency_response.exact_response` on the structure's model."""
    return fr.exact_response(MODELS.of(base), base, tmd, omegas, linearise)


def exact_amplitude(base: Any, tmd: TMDParams, omegas: ArrayLike, linearise: bool = False) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.frequency_response.exact_amplitude` on the structure's model."""
    return fr.exact_amplitude(MODELS.of(base), base, tmd, omegas, linearise)


def exact_state(base: Any, tmd: TMDParams, omega: float, t: float = 0.0, linearise: bool = False) -> np.ndarray:
    """:func:`pyfmu_wrapper.solvers.frequency_response.exact_state` on the structure's model."""
    return fr.exact_state(MODELS.of(base), base, tmd, omega, t, linearise)


def sweep(base: Any, tmd: TMDParams, omegas: ArrayLike, *args: Any, **kwargs: Any) -> sw.SweepResult:
    """:func:`pyfmu_wrapper.solvers.sweep.sweep` on the structure's model."""
    return sw.sweep(MODELS.of(base), base, tmd, omegas, *args, **kwargs)
