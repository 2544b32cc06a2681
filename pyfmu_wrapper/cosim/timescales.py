"""A co-simulated system's own time scales, and the communication step they allow.

The co-simulation exchanges the structure's motion and the absorber's impulse once per communication
step h. The forcing period alone does not bound h: a light base, a stiff link or a heavy inerter makes
the structure (and each of its parts, as the master splits it) oscillate much faster than the forcing,
and an explicit exchange is then inaccurate or unstable (a base of 0.001 kg is 292 % off at 96 steps per
period; Case 1 at 0.5 rad/s diverges). Each system lists the angular frequencies [rad/s] a step has to
resolve, each with the parameters that set it (:meth:`~.system.CosimSystem.time_scales`; the paper's
pair: :func:`pyfmu_wrapper.models.base_tmd.cosim.structure_frequencies`).

:func:`steps_for_structure` turns the fastest of them into communication steps per forcing period
(omega_fast h <= :data:`STEP_SCALE`); :func:`choose_steps` combines it with the accuracy model
and refuses a step count above the cap with a sentence naming the parameters that set it."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .system import CosimSystem, Scale

#: largest omega_fast h of a communication step (omega_fast: the fastest structure frequency);
#: calibrated in docs/cosimulation.md ("Steps from the structure's time scales"): a 0.001 kg base
#: at omega_fast h = 0.6 is 2.5e-4 off, at 1.2 1.4e-3 off, so 0.5 keeps the first step near the
#: accuracy asked for and its half (the coupling-error check) stable
STEP_SCALE = 0.5


def fastest(system: CosimSystem) -> Scale:
    """The fastest of the system's time scales."""
    return max(system.time_scales(), key=lambda s: s.omega)


def steps_for_structure(system: CosimSystem, omega: float, scale: float = STEP_SCALE) -> float:
    """Communication steps per forcing period (2 pi/omega) for omega_fast h <= scale (a float, may be inf)."""
    w = fastest(system).omega
    if not math.isfinite(w):
        return math.inf
    return 2.0 * math.pi / float(omega) * w / scale


class StepChoice(NamedTuple):
    steps: int  #: communication steps per period (0 when refused)
    limited_by: str  #: "accuracy", "structure" or "fixed"
    refused: str | None  #: why no step count within the cap works (names the parameters), else None


def round_steps(n: float) -> int:
    """A step count rounded up to a multiple of 8 (at least 32)."""
    return max(32, int(math.ceil(n / 8.0) * 8))


def choose_steps(system: CosimSystem, omega: float, accuracy_steps: int, cap: int, fixed: bool = False) -> StepChoice:
    """Steps per period: the larger of ``accuracy_steps`` (the accuracy model, or the user's fixed
    count when ``fixed``) and the structure's (:func:`steps_for_structure`); refused (``refused``
    says why) when the structure needs more than ``cap``. A fixed count is kept as it is (the
    coupling-error check then reports whether it is enough)."""
    if fixed:
        return StepChoice(int(accuracy_steps), "fixed", None)
    need = steps_for_structure(system, omega)
    if need > cap:
        s = fastest(system)
        shown = f"{need:.3g}" if math.isfinite(need) else "infinitely many"
        return StepChoice(
            0,
            "structure",
            f"{s.what} is {s.omega:.4g} rad/s: it needs {shown} communication steps per forcing period "
            f"at omega = {omega:.4g} rad/s (more than max_steps_per_period = {cap}); use the monolithic engine",
        )
    n_struct = round_steps(need)
    if n_struct > accuracy_steps:
        return StepChoice(min(n_struct, cap), "structure", None)
    return StepChoice(int(accuracy_steps), "accuracy", None)


def refusal(system: CosimSystem, omegas: object, cap: int) -> str | None:
    """Why the co-simulation refuses some frequency of ``omegas`` [rad/s] for this system (the sentence of
    :func:`choose_steps` at the lowest frequency, where the most steps are needed, with how many of the
    frequencies it refuses), or None when it refuses none. For a caller that would rather refuse a whole
    run up front (exit 2) than report the points not converged."""
    w = np.asarray(omegas, dtype=float).ravel()
    if w.size == 0:
        return None
    refused = [x for x in w if steps_for_structure(system, float(x)) > cap]
    if not refused:
        return None
    why = choose_steps(system, float(min(refused)), 0, cap).refused
    return f"{len(refused)} of {w.size} frequencies (up to {max(refused):.4g} rad/s): {why}"


def parameter_text(name: str, value: float, unit: str) -> str:
    """A parameter as a time scale's sentence names it: ``base.mass (M) = 100 kg``."""
    return f"{name} = {value:.4g} {unit}"


def ratio_sqrt(num: float, den: float) -> float:
    """sqrt(num / den) [rad/s] of a stiffness over a mass, inf for a massless part that is stiff, 0 for one that
    is not."""
    if den <= 0.0:
        return math.inf if num > 0.0 else 0.0
    r = num / den
    return math.sqrt(r) if math.isfinite(r) else math.inf
