"""A compiled, stiffly accurate Rosenbrock integrator (RODAS4) with event-respecting steps.

Method: RODAS4 of Hairer & Wanner (Solving ODEs II, Sect. IV.7), order 4 with an embedded order-3
error estimate, L-stable and stiffly accurate, in the formulation

    G = I / (h gamma) - J(t0, y0)
    G K_i = f(t0 + alpha_i h, y0 + sum_j A_ij K_j) + sum_j C_ij / h K_j + gamma_i h df/dt
    y1 = y0 + sum_i M_i K_i,     err = sum_i E_i K_i

The model is an argument: :func:`make_integrator` builds the compiled integrator of a model from
its right-hand side, Jacobian, switching functions and mode function (an
:class:`~pyfmu_wrapper.physics.models.OdeModel`, or any object with the same attributes), so a new
model needs no edit here. The Jacobians of this package's models come from the physics kernels:
analytic for the coupled system and the TMD subsystem (held against the complex-step derivative in
the tests), by the complex-step derivative otherwise; all are exact, so the method keeps its order
on the stiff friction branch.

Non-smooth points. The dry-friction law is smooth but has a slope of df (2/pi) s (6.4e6 N s/m
for df = 10 N) in a band |xd - yd| < ~1/s; the play chain has kinks at |d| = eps. A large step
that jumps across the friction band, or over a contact switch, is linearised at the wrong
branch (the physics notes warn that it can land "stuck" and be wrong). Each accepted step is
therefore checked for sign changes of the switching functions of the physics layer; a step that
jumps across one is retaken, shortened to end just past the estimated crossing, so that the
next step starts on the right branch with the right Jacobian.

Always advancing. A state within SURFACE_TOL * atol of a contact surface (or within the friction
band of a reversal) is on it, in that surface's mode, and is integrated with the ordinary error
control: a gear chain resting on its contact at d + eps ~ -1e-20 is not retaken onto the surface
again and again (which stalled the integrator). Minimum step: retakes shorter than 100 hmin are not
made (the step is judged by its error estimate alone); an error-test rejection below hmin =
1e-14 max(1, |t1|) ends the call with STEP_UNDERFLOW. At most ``max_steps`` steps (accepted,
rejected and retaken) per call, else STEP_CAP. The callers turn a status into an error naming
the time, the state and the mode (:func:`failure_message`), never a hang.

Dense output. Within a step, x(t) is the cubic Hermite interpolant of (x, xd) at both ends
(fourth-order accurate, and xd is part of the state, so it costs no extra evaluation); the
maximum of |x| over each period is taken from it, not from samples.
"""

from __future__ import annotations

import math
import types
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._jit import njit
from .hermite import hermite_absmax, hermite_state  # noqa: F401 (names the template's code uses: its globals)
from .rodas_method import ALPHA, COEF_A, COEF_C, COEF_E, COEF_M, GAMMA, GAMMAI, lu_factor, lu_solve  # noqa: F401 (names the template's code uses: its globals)

FloatArray = NDArray[np.float64]
FloatSeq = Sequence[float] | NDArray[np.float64]

if TYPE_CHECKING:
    # the template's model names, bound per model by make_integrator (never defined in this module)
    _NSWITCH: int
    _NMODES: int
    _SWITCH_TOL_INDEX: tuple[int, ...]
    _model_rhs: Callable[..., None]
    _model_jacobian: Callable[..., None]
    _model_switching: Callable[..., None]
    _model_mode: Callable[..., int]

STAT_STEPS, STAT_REJECTED, STAT_EVENTS, STAT_FAILED = 0, 1, 2, 3

#: status codes returned by :func:`integrate`
OK, STEP_UNDERFLOW, STEP_CAP = 0, 1, 2
#: default cap on accepted + rejected steps in one call of :func:`integrate`
DEFAULT_MAX_STEPS = 1_000_000
#: a switching function within this fraction of the absolute tolerance of its state is "on" its
#: surface: the state is in the surface's mode and no step is retaken to land on it again
SURFACE_TOL = 1e-3


def _integrate_template(
    z: FloatArray,
    t0: float,
    t1: float,
    p: FloatArray,
    u: FloatArray,
    rtol: float,
    atol: FloatArray,
    h: float,
    hmax: float,
    sample_times: FloatArray,
    samples: FloatArray,
    friction_band: float,
    stats: NDArray[np.int64],
    max_steps: int = DEFAULT_MAX_STEPS,
) -> tuple[float, float, int, float]:
    """Integrate the model from t0 to t1 in place on z; return (next step size, max |z[0]|, status, t).

    (The template of :func:`make_integrator`: the model's functions are the globals ``_model_*``
    and its constants ``_NSWITCH``, ``_NMODES``, ``_SWITCH_TOL_INDEX``; it is never compiled itself.)

    status is OK (0) when t1 was reached, else the failure code and t the time reached, with z the
    state there (:func:`failure_message` turns them into a sentence naming time, state and mode):

    * STEP_UNDERFLOW: the error test rejected steps down to the minimum step
      hmin = 1e-14 max(1, |t1|) (the resolution of t);
    * STEP_CAP: more than ``max_steps`` steps (accepted, rejected and retaken) in this call.

    Surfaces. A step whose end point has a switching function of the other sign than its start is
    retaken, shortened to end just past the estimated crossing, unless the start or the end lies
    on the surface: within SURFACE_TOL * atol of the state the function depends on (the model's
    ``switch_tolerance``; friction: within friction_band = 1/s [m/s]). A state on a surface is in that surface's mode (a gear
    chain resting on its contact, a grazing contact, a TMD stuck to the base): it is integrated
    with the ordinary error control and never retaken to land on the surface again. Retakes shorter
    than 100 hmin are not made (the step is then judged by its error estimate alone).

    sample_times (sorted, inside [t0, t1]) are filled into rows of samples by dense output.
    stats accumulates [steps, rejected, event retakes, failed].
    """
    n = z.shape[0]
    J = np.empty((n, n))
    G = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    K = np.empty((6, n))
    f0 = np.empty(n)
    f1 = np.empty(n)
    ft = np.empty(n)
    fs = np.empty(n)
    ys = np.empty(n)
    ynew = np.empty(n)
    g0 = np.empty(_NSWITCH)
    g1 = np.empty(_NSWITCH)
    zc = np.empty(n, dtype=np.complex128)
    oc = np.empty(n, dtype=np.complex128)
    t = t0
    span = t1 - t0
    hmin = 1e-14 * max(1.0, abs(t1))
    if h <= 0.0 or h > hmax:
        h = min(hmax, span * 1e-3)
    _model_rhs(t, z, p, u, f0)
    xmax = abs(z[0])
    isample = 0
    nsample = sample_times.shape[0]
    while isample < nsample and sample_times[isample] <= t:
        for i in range(n):
            samples[isample, i] = z[i]
        isample += 1
    # the last accepted step size in each mode of the model: on entering a mode the step starts
    # from what worked there before instead of being rejected down to it
    hmode = np.full(_NMODES, hmax)
    rejected_last = False
    # surface tolerances: by the caller's band (-1: friction) or by the tolerance of a state
    gtol = np.empty(_NSWITCH)
    for k in range(_NSWITCH):
        di = _SWITCH_TOL_INDEX[k]
        if di < 0:
            gtol[k] = friction_band
        else:
            gtol[k] = SURFACE_TOL * atol[di] if n > di else 0.0
    ncalls = 0
    _model_switching(z, p, g0)
    mode_prev = _model_mode(g0)
    while t < t1:
        _model_switching(z, p, g0)
        mode = _model_mode(g0)
        if mode != mode_prev:
            h = min(h, hmode[mode])
        hs = h
        final = False
        if t + hs >= t1 - 1e-12 * abs(span):
            hs = t1 - t
            final = True
        _model_jacobian(t, z, p, u, J, ft, zc, oc)
        while True:
            ncalls += 1
            if ncalls > max_steps:
                stats[STAT_FAILED] += 1
                return h, xmax, STEP_CAP, t
            # G = I/(h gamma) - J
            for i in range(n):
                for j in range(n):
                    G[i, j] = -J[i, j]
                G[i, i] += 1.0 / (hs * GAMMA)
            if not lu_factor(G, piv):
                hs *= 0.5
                stats[STAT_REJECTED] += 1
                final = False
                continue
            for st in range(6):
                if st == 0:
                    for i in range(n):
                        fs[i] = f0[i]
                else:
                    for i in range(n):
                        acc = z[i]
                        for j in range(st):
                            acc += COEF_A[st, j] * K[j, i]
                        ys[i] = acc
                    _model_rhs(t + ALPHA[st] * hs, ys, p, u, fs)
                for i in range(n):
                    acc = fs[i] + GAMMAI[st] * hs * ft[i]
                    for j in range(st):
                        acc += COEF_C[st, j] / hs * K[j, i]
                    K[st, i] = acc
                krow = K[st]
                lu_solve(G, piv, krow)
            enorm = 0.0
            finite = True
            for i in range(n):
                acc = z[i]
                e = 0.0
                for j in range(6):
                    acc += COEF_M[j] * K[j, i]
                    e += COEF_E[j] * K[j, i]
                ynew[i] = acc
                sc = atol[i] + rtol * max(abs(z[i]), abs(acc))
                r = e / sc
                enorm += r * r
                if not (math.isfinite(acc) and math.isfinite(e)):
                    finite = False
            enorm = math.sqrt(enorm / n) if finite else 1e10
            # events first: a step that jumps across a switching surface is retaken shorter (its
            # error estimate is meaningless across the kink, so do not let it drive rejections)
            if finite:
                _model_switching(ynew, p, g1)
            else:
                for k in range(_NSWITCH):
                    g1[k] = g0[k]
            theta = 1.0
            for k in range(_NSWITCH):
                if g0[k] * g1[k] < 0.0:
                    if abs(g0[k]) <= gtol[k] or abs(g1[k]) <= gtol[k]:
                        continue  # starts or ends on the surface: in its mode, nothing to land on
                    th = g0[k] / (g0[k] - g1[k])
                    if th < theta:
                        theta = th
            if theta < 0.9 and hs * theta > hmin * 100:
                hs = hs * theta * 1.001 + hmin
                stats[STAT_EVENTS] += 1
                final = False
                continue
            if enorm > 1.0:
                rejected_last = True
                stats[STAT_REJECTED] += 1
                hs *= max(0.2, 0.9 * enorm ** (-0.25))
                final = False
                if hs < hmin:
                    stats[STAT_FAILED] += 1
                    return h, xmax, STEP_UNDERFLOW, t
                continue
            break
        # accepted
        _model_rhs(t + hs, ynew, p, u, f1)
        xmax = max(xmax, hermite_absmax(z[0], f0[0], ynew[0], f1[0], hs))
        while isample < nsample and sample_times[isample] <= t + hs:
            theta_s = (sample_times[isample] - t) / hs
            hermite_state(z, f0, ynew, f1, hs, theta_s, samples[isample])
            isample += 1
        t = t1 if final else t + hs
        for i in range(n):
            z[i] = ynew[i]
            f0[i] = f1[i]
        stats[STAT_STEPS] += 1
        hmode[mode] = hs
        mode_prev = mode
        # (a PI controller was tried: fewer rejections but more steps in total on the rattling gear)
        fac = min(6.0, max(0.2, 0.9 * max(enorm, 1e-10) ** (-0.25)))
        if rejected_last:
            fac = min(fac, 1.0)
        rejected_last = False
        h = min(hmax, hs * fac)
        if final:
            break
    return h, xmax, OK, t


_INTEGRATORS: dict = {}


def make_integrator(model: Any, cache: bool | None = None) -> Any:
    """The compiled integrator of ``model`` (built once per model name; on disk by numba's cache).

    model supplies ``name`` (a Python identifier), ``rhs``, ``jacobian``, ``switching``, ``mode``
    (numba-compiled functions), ``n_switches``, ``n_modes`` and ``switch_tolerance`` (see
    :mod:`pyfmu_wrapper.physics.models`). The result is called as
    ``integrate(z, t0, t1, p, u, rtol, atol, h, hmax, sample_times, samples, friction_band, stats,
    max_steps=DEFAULT_MAX_STEPS)`` and returns (next step size,
    max |z[0]|, status, t) (see the template's doc).

    Each model's integrator is the template's code with the model's functions as its globals and a
    name of its own (``integrate_<name>``), so numba caches it in a file of its own and inlines the
    model's calls as direct calls (the numbers are those of a hand-specialised integrator).

    cache: keep the compiled integrator in numba's on-disk cache. The cache is keyed to this
    package's compiled layer (see :mod:`pyfmu_wrapper._jit`), so by default (None) only a model
    whose functions are all defined in this package is cached; a model of another package (or of
    a test) is compiled afresh in each process, never loaded stale.
    """
    name = str(model.name)
    if not name.isidentifier():
        raise ValueError(f"make_integrator: model name {name!r} is not a Python identifier")
    hit = _INTEGRATORS.get(name)
    if hit is not None:
        if hit[0] is not model:
            raise ValueError(f"make_integrator: two different models are named {name!r}")
        return hit[1]
    tol_index = tuple(int(k) for k in model.switch_tolerance)
    if len(tol_index) != int(model.n_switches):
        raise ValueError(
            f"make_integrator: model {name!r} has {model.n_switches} switching functions but "
            f"{len(tol_index)} entries in switch_tolerance"
        )
    g = dict(globals())
    g.update(
        _model_rhs=model.rhs,
        _model_jacobian=model.jacobian,
        _model_switching=model.switching,
        _model_mode=model.mode,
        _NSWITCH=int(model.n_switches),
        _NMODES=int(model.n_modes),
        _SWITCH_TOL_INDEX=tol_index,
    )
    tpl = _integrate_template
    fn = types.FunctionType(tpl.__code__, g, f"integrate_{name}", tpl.__defaults__)
    fn.__qualname__ = f"integrate_{name}"
    fn.__doc__ = tpl.__doc__
    fn.__module__ = tpl.__module__
    if cache is None:
        pkg = __name__.split(".")[0] + "."
        funcs = (model.rhs, model.jacobian, model.switching, model.mode)
        cache = all(str(getattr(getattr(f, "py_func", f), "__module__", "")).startswith(pkg) for f in funcs)
    compiled = njit(cache=bool(cache))(fn)
    _INTEGRATORS[name] = (model, compiled)
    return compiled


def contact_mode(model: Any, z: FloatSeq, p: FloatArray, atol: FloatSeq, friction_band: float) -> str:
    """Name the mode of state z of ``model`` (its ``describe``): e.g. gear contact (engaged in
    compression / extension, free, or on a contact surface within the surface tolerance) and
    friction (stuck or sliding)."""
    return model.describe(z, p, atol, friction_band)


def failure_reason(status: int, max_steps: int = DEFAULT_MAX_STEPS) -> str:
    """Why an integrator of :func:`make_integrator` stopped, from its status (the words of every
    message that names it, the native FMUs' included)."""
    return {
        STEP_UNDERFLOW: "the step size fell below the resolution of t (error test failed at the minimum step)",
        STEP_CAP: f"the cap of {max_steps} steps per call was reached",
    }.get(int(status), f"status {status}")


def failure_message(
    status: int,
    model: Any,
    t: float,
    z: FloatSeq,
    p: FloatArray,
    atol: FloatSeq,
    friction_band: float,
    max_steps: int = DEFAULT_MAX_STEPS,
) -> str:
    """A sentence naming why an integrator of :func:`make_integrator` stopped, at which time, in
    which state and mode."""
    why = failure_reason(status, max_steps)
    names = tuple(model.state_names)
    if len(names) != len(z):
        names = tuple(f"z{i}" for i in range(len(z)))
    state = ", ".join(f"{k} = {float(v):.17g}" for k, v in zip(names, z))
    mode = contact_mode(model, z, p, atol, friction_band)
    return f"integrator stopped at t = {float(t):.12g} s: {why}; state {state}; mode: {mode}"
