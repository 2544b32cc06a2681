"""The coupled structure's own time scales, and the communication step they allow.

The co-simulation exchanges the base's motion and the TMD's impulse once per communication step h.
The forcing period alone does not bound h: a light base, a stiff link or a heavy inerter makes the
structure (and each of its two parts, as the master splits it) oscillate much faster than the
forcing, and an explicit exchange is then inaccurate or unstable (a base of 0.001 kg is 292 % off
at 96 steps per period; Case 1 at 0.5 rad/s diverges). :func:`structure_frequencies` lists the
angular frequencies [rad/s] that a step has to resolve, each with the parameters that set it:

* the natural frequencies of the coupled linearised structure: mass matrix
  [[M + I, -I], [-I, m + I]], stiffness [[K + k, -k], [-k, k]] (the play chain is taken as the
  ideal inerter: its mesh is resolved inside the TMD FMU; friction and the cubic term, which the
  linearisation at rest does not see, are left to the coupling-error check);
* the base as the master sees it, alone with the link held: sqrt((K + k) / M) (the TMD's
  reaction reaches it only once per step);
* the TMD alone on a base held still: sqrt(k / (m + I));
* the inerter against the base: sqrt(k I / ((m + I) M)), the TMD's spring seen through the
  inerter's share of the base's acceleration (large when I >> M).

:func:`steps_for_structure` turns the fastest of them into communication steps per forcing period
(omega_fast h <= :data:`STEP_SCALE`); :func:`choose_steps` combines it with the accuracy model
and refuses a step count above the cap with a sentence naming the parameters that set it.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from ..physics.params import BaseParams, InerterModel, TMDParams

#: largest omega_fast h of a communication step (omega_fast: the fastest structure frequency);
#: calibrated in docs/cosimulation.md ("Steps from the structure's time scales"): a 0.001 kg base
#: at omega_fast h = 0.6 is 2.5e-4 off, at 1.2 1.4e-3 off, so 0.5 keeps the first step near the
#: accuracy asked for and its half (the coupling-error check) stable
STEP_SCALE = 0.5


class Scale(NamedTuple):
    omega: float  #: angular frequency [rad/s]
    what: str  #: what it is, with the parameters (names, symbols, values) that set it


def _fmt(name: str, value: float, unit: str) -> str:
    return f"{name} = {value:.4g} {unit}"


def structure_frequencies(base: BaseParams, tmd: TMDParams) -> list[Scale]:
    """The angular frequencies [rad/s] of the coupled structure and of its two parts (module doc)."""
    M, K = float(base.mass), float(base.stiffness)
    m, k = float(tmd.mass), float(tmd.stiffness)
    inert = 0.0 if tmd.inerter == InerterModel.NONE else float(tmd.inertance)
    pars = {
        "M": _fmt("base.mass (M)", M, "kg"),
        "K": _fmt("base.stiffness (K)", K, "N/m"),
        "m": _fmt("tmd.mass (m)", m, "kg"),
        "k": _fmt("tmd.stiffness (k)", k, "N/m"),
        "I": _fmt("tmd.inertance (I)", inert, "kg"),
    }
    out: list[Scale] = []
    with np.errstate(all="ignore"):
        mass = np.array([[M + inert, -inert], [-inert, m + inert]])
        stiff = np.array([[K + k, -k], [-k, k]])
        try:
            lam = np.linalg.eigvals(np.linalg.solve(mass, stiff))
            w2 = float(np.max(np.abs(lam)))
        except np.linalg.LinAlgError:
            w2 = math.inf
        if not math.isfinite(w2):
            w2 = math.inf
    out.append(Scale(math.sqrt(w2), f"the coupled structure's highest natural frequency ({', '.join(pars.values())})"))
    out.append(
        Scale(
            _ratio_sqrt(K + k, M),
            f"the base alone, sqrt((K + k)/M) ({pars['M']}, {pars['K']}, {pars['k']})",
        )
    )
    out.append(
        Scale(_ratio_sqrt(k, m + inert), f"the TMD alone, sqrt(k/(m + I)) ({pars['k']}, {pars['m']}, {pars['I']})")
    )
    if inert > 0.0:
        out.append(
            Scale(
                _ratio_sqrt(k * inert, (m + inert) * M),
                f"the inerter against the base, sqrt(k I/((m + I) M)) ({pars['k']}, {pars['I']}, {pars['m']}, {pars['M']})",
            )
        )
    return out


def _ratio_sqrt(num: float, den: float) -> float:
    if den <= 0.0:
        return math.inf if num > 0.0 else 0.0
    r = num / den
    return math.sqrt(r) if math.isfinite(r) else math.inf


def fastest(base: BaseParams, tmd: TMDParams) -> Scale:
    """The fastest of :func:`structure_frequencies`."""
    return max(structure_frequencies(base, tmd), key=lambda s: s.omega)


def steps_for_structure(base: BaseParams, tmd: TMDParams, omega: float, scale: float = STEP_SCALE) -> float:
    """Communication steps per forcing period (2 pi/omega) for omega_fast h <= scale (a float, may be inf)."""
    w = fastest(base, tmd).omega
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


def choose_steps(
    base: BaseParams, tmd: TMDParams, omega: float, accuracy_steps: int, cap: int, fixed: bool = False
) -> StepChoice:
    """Steps per period: the larger of ``accuracy_steps`` (the accuracy model, or the user's fixed
    count when ``fixed``) and the structure's (:func:`steps_for_structure`); refused (``refused``
    says why) when the structure needs more than ``cap``. A fixed count is kept as it is (the
    coupling-error check then reports whether it is enough)."""
    if fixed:
        return StepChoice(int(accuracy_steps), "fixed", None)
    need = steps_for_structure(base, tmd, omega)
    if need > cap:
        s = fastest(base, tmd)
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


def refusal(base: Any, tmd: TMDParams, omegas: object, cap: int) -> str | None:
    """Why the co-simulation refuses some frequency of ``omegas`` [rad/s] for this configuration (the
    sentence of :func:`choose_steps` at the lowest frequency, where the most steps are needed, with
    how many of the frequencies it refuses), or None when it refuses none. For a caller that would
    rather refuse a whole run up front (exit 2) than report the points not converged. The time scales
    are the paper's pair's (a frame's co-simulation takes its steps from the accuracy asked for: None)."""
    w = np.asarray(omegas, dtype=float).ravel()
    if not isinstance(base, BaseParams) or w.size == 0:
        return None
    refused = [x for x in w if steps_for_structure(base, tmd, float(x)) > cap]
    if not refused:
        return None
    why = choose_steps(base, tmd, float(min(refused)), 0, cap).refused
    return f"{len(refused)} of {w.size} frequencies (up to {max(refused):.4g} rad/s): {why}"
