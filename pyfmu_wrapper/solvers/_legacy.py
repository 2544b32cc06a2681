"""Compatibility (temporary): ``integrate(system, ...)`` by kernels system id, for the FMU code.

fmi/native.py and fmi/slaves.py still call ``rodas.integrate(SYS_BASE | SYS_TMD, z, ...)`` and
``rodas.failure_message(status, SYS_..., ...)``; this module maps the ids to the models of
:mod:`pyfmu_wrapper.physics.models` and their integrators of
:func:`~pyfmu_wrapper.solvers.rodas.make_integrator`. It is the one module of ``solvers/`` that
knows system ids (tests/test_solver_model_arg.py holds it to that); delete it when fmi/ builds its
integrators with ``make_integrator(models.BASE)`` / ``make_integrator(models.TMD)`` itself.
"""
from __future__ import annotations

from .._jit import njit
from ..physics import models as _models
from ..physics.kernels import SYS_BASE, SYS_TMD
from .rodas import DEFAULT_MAX_STEPS, SURFACE_TOL, make_integrator

_integrate_base = make_integrator(_models.BASE)
_integrate_tmd = make_integrator(_models.TMD)


def model_of(system: int):
    """The :class:`~pyfmu_wrapper.physics.models.OdeModel` of a kernels system id."""
    try:
        return _models.BY_SYSTEM_ID[int(system)]
    except KeyError:
        raise ValueError(f"unknown system id {system!r} (known: {sorted(_models.BY_SYSTEM_ID)})") from None


@njit(cache=True)
def integrate(system, z, t0, t1, p, u, rtol, atol, h, hmax, sample_times, samples, friction_band, stats,
              max_steps=DEFAULT_MAX_STEPS, surface_tol=SURFACE_TOL):
    """The integrator of the FMU subsystem with kernels system id ``system``: SYS_BASE or SYS_TMD
    (see rodas.make_integrator; the coupled system is make_integrator(models.COUPLED), not here, so
    that the FMU code compiles only its two integrators)."""
    if system != SYS_BASE and system != SYS_TMD:
        raise ValueError("rodas.integrate(system, ...): system must be SYS_BASE or SYS_TMD; the coupled "
                         "system's integrator is make_integrator(physics.models.COUPLED)")
    if system == SYS_BASE:
        return _integrate_base(z, t0, t1, p, u, rtol, atol, h, hmax, sample_times, samples, friction_band,
                               stats, max_steps, surface_tol)
    return _integrate_tmd(z, t0, t1, p, u, rtol, atol, h, hmax, sample_times, samples, friction_band,
                          stats, max_steps, surface_tol)
