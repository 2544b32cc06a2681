"""Transient records: fits of the candidate effects (:mod:`.transient_effects`). Parameters are fitted by
nonlinear least squares (``scipy.optimize.least_squares``, trust region, finite-difference
Jacobian) on the whitened simulation error of the training samples, the start state of every
record projected out (variable projection, :mod:`.transient_sim`). Their std is
``sqrt(diag((J^T J)^-1))`` of the whitened problem (the noise is measured, so no rescaling).
"""

from __future__ import annotations

import contextlib
import math
import os
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np

from .transient_effects import BOUNDS, TEFFECTS, Model, apply
from .transient_sim import simulate

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from numpy import ndarray

    from .transient_sim import TView

TOL = {"ftol": 1e-7, "xtol": 1e-6, "gtol": 1e-8}  #: least_squares stopping (relative change of the cost / step)
#: the process CPU time (``time.process_time``) past which every fit stops at its next Jacobian and
#: returns the best point reached (:func:`cpu_deadline`); None: no limit
_DEADLINE: list[float | None] = [None]


class OutOfTime(Exception):
    """The CPU deadline of :func:`cpu_deadline` passed during a fit."""


@contextlib.contextmanager
def cpu_deadline(t: float | None) -> Iterator[None]:
    """Within the block, every :func:`fit` stops when the process CPU time passes ``t``: at its next
    Jacobian, with the best point reached (``TFit.cut``); a linearisation fails. Nested blocks keep
    the earlier deadline."""
    old = _DEADLINE[0]
    _DEADLINE[0] = t if old is None or t is None else min(old, t)
    try:
        yield
    finally:
        _DEADLINE[0] = old


def past_deadline() -> bool:
    d = _DEADLINE[0]
    return d is not None and time.process_time() > d


_POOL: list[ThreadPoolExecutor] = []
T = TypeVar("T")
R = TypeVar("R")


def pool() -> ThreadPoolExecutor:
    """The threads that simulate records side by side (one per core, at most 4)."""
    if not _POOL:
        _POOL.append(ThreadPoolExecutor(max_workers=max(1, min(4, os.cpu_count() or 1))))
    return _POOL[0]


def pmap(fn: Callable[[T], R], items: Sequence[T], sizes: Sequence[float]) -> list[R]:
    """[fn(x) for x in items], run in :func:`pool`'s threads, the largest first (``sizes``: the work of
    each; the longest jobs started first end the batch sooner than in the given order)."""
    order = sorted(range(len(items)), key=lambda k: -sizes[k])
    futs = {k: pool().submit(fn, items[k]) for k in order}
    return [futs[k].result() for k in range(len(items))]


def residual(
    v: TView, mdl: Model, mask: ndarray, z0: ndarray | None = None, sim: ndarray | None = None
) -> ndarray | None:
    """Whitened simulation error (n_out, 4) of record v (simulated from z0, default ``v.z0``; ``sim``:
    that simulation already made, not changed) with the start state projected out on the samples of
    ``mask`` (NaN for channels not recorded); None when the simulation blows up."""
    y = simulate(v, mdl.p, z0, force_gain=mdl.gain) if sim is None else sim.copy()
    if y is None:
        return None
    y[:, 0] += mdl.offset[0]
    y[:, 1] += mdl.offset[1]
    e = (v.meas - y) / v.sigma
    if v.phi is not None:
        A = (v.phi / v.sigma[None, :, None])[:, v.has, :][mask].reshape(-1, 4)
        b = e[:, v.has][mask].ravel()
        d = np.linalg.lstsq(A, b, rcond=None)[0]
        e = e - np.einsum("nck,k->nc", v.phi / v.sigma[None, :, None], d)
    return e


def start_update(v: TView, mdl: Model, mask: ndarray) -> None:
    """Fold the projected start state into the simulation's start state (one pass)."""
    y = simulate(v, mdl.p, force_gain=mdl.gain)
    if y is None or v.phi is None:
        return
    y[:, 0] += mdl.offset[0]
    y[:, 1] += mdl.offset[1]
    e = (v.meas - y) / v.sigma
    A = (v.phi / v.sigma[None, :, None])[:, v.has, :][mask].reshape(-1, 4)
    d = np.linalg.lstsq(A, e[:, v.has][mask].ravel(), rcond=None)[0]
    v.z0[:4] += 1e-3 * d


@dataclass
class TFit:
    effects: tuple[str, ...]
    theta: ndarray
    std: ndarray
    ok: bool = True
    reason: str = ""
    chi2: dict = field(default_factory=dict)  #: "train" / "test" -> float; "dof_*"
    resid: list = field(default_factory=list)  #: whitened residual per record (n_out, 4)
    z0: dict = field(default_factory=dict)  #: record name -> fitted start state of a free decay
    #: ``fit(linearise=True)``: (stacked whitened residual, its Jacobian in the scaled unknowns, row offsets)
    lin: tuple = ()
    cut: bool = False  #: stopped at the CPU deadline (:func:`cpu_deadline`) before it converged


def _stack(views: list[TView], mdl: Model, masks: list[ndarray]) -> tuple[ndarray, list[ndarray]] | None:
    out, full = [], []
    for v, m in zip(views, masks):
        e = residual(v, mdl, m)
        if e is None:
            return None
        full.append(e)
        out.append(e[:, v.has][m].ravel())
    return np.concatenate(out), full


def chi2_of(views: list[TView], full: list[ndarray], masks: list[ndarray]) -> tuple[float, int]:
    """(sum of squares, count) of the whitened residuals on the masked samples of every record."""
    s, n = 0.0, 0
    for v, e, m in zip(views, full, masks):
        x = e[:, v.has][m]
        s += float(np.sum(x**2))
        n += int(x.size)
    return s, n


def chi2_var_of(views: list[TView], masks: list[ndarray]) -> float:
    """var of the chi-square on the masked samples when the residual is pure noise: 2 n per record
    times its factor for the noise's correlation (:func:`.transient_sim.chi2_variance_factor`)."""
    return float(sum(2.0 * int(v.has.sum()) * int(m.sum()) * v.chi2_var for v, m in zip(views, masks)))


#: the friction candidate's second start slope [s/m] (its first: the scale, 1000 s/m): a stick-slip truth
#: fitted from 1000 s/m alone stopped at 256 s/m, z = 32 (seed 77 tr000, a decay and a sweep), the
#: regularised law's viscous-like local minimum; f5 (tests' make, 5 N) went to 2.2e4 from either
FRICTION_STEEP = 3.0e4


def fit(
    views: list[TView],
    p_nom: ndarray,
    effects: tuple[str, ...],
    train: list[ndarray],
    test: list[ndarray] | None,
    sc: dict[str, tuple[float, ...]],
    starts: list[ndarray] | None = None,
    max_nfev: int = 40,
    z_start: dict[str, ndarray] | None = None,
    linearise: bool = False,
    ramp: bool = True,
) -> TFit:
    """Fit the effects' parameters on the ``train`` samples; chi-squares on train and test.

    The start state of a free-decay record (its whole response) is fitted with the parameters, as
    four more unknowns (units of 1 mm, 1 mm/s); other records' start states are projected out
    linearly and refreshed under the fitted model before a second pass. ``z_start``: record name ->
    start state a decay's fitted one begins from (:func:`warm_start`), else the view's.
    ``linearise``: no fit; at ``starts[0]`` (the forced records' start states chosen and refreshed
    under its model as a fit does) the residual and its Jacobian (``lin``: columns the parameters over
    their scales, then each decay's four start-state unknowns) and every record's start state (``z0``).
    ``ramp``: a model with dry friction and free decays whose start states are not a fit's own
    (``z_start`` None) begins from :func:`_decay_ramp`'s point instead of each start."""
    from scipy.optimize import least_squares

    scale = np.array([s for e in effects for s in sc[e]], float)
    npar = scale.size
    dec = [i for i, v in enumerate(views) if v.free_decay]
    lb = np.array([BOUNDS.get(f"{e}.{n}", (-np.inf, np.inf))[0] for e in effects for n in TEFFECTS[e][0]])
    ub = np.array([BOUNDS.get(f"{e}.{n}", (-np.inf, np.inf))[1] for e in effects for n in TEFFECTS[e][0]])
    lb, ub = (
        np.concatenate([lb / scale, [-np.inf] * 4 * len(dec)]),
        np.concatenate([ub / scale, [np.inf] * 4 * len(dec)]),
    )
    BAD = 1e6
    sizes = [int(v.has.sum()) * int(m.sum()) for v, m in zip(views, train)]
    offs = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    n_res = int(offs[-1])
    saved = [v.z0.copy() for v in views]
    #: the decays' start states that their fitted unknowns move from (``z_start``: a fit's own)
    base = [np.array(z_start[v.name]) if z_start and v.name in z_start else z.copy() for v, z in zip(views, saved)]
    phis = [v.phi for v in views]
    cache: dict[str, Any] = {}

    def start(i: int, u: ndarray) -> ndarray:
        """Record i's start state: a decay's from its fitted unknowns in u, the others' as held."""
        if i not in dec:
            return views[i].z0
        k = npar + 4 * dec.index(i)
        z = base[i].copy()
        z[:4] += 1e-3 * u[k : k + 4]
        return z

    def one(i: int, mdl: Model, u: ndarray) -> ndarray | None:
        e = residual(views[i], mdl, train[i], start(i, u))
        return None if e is None else e[:, views[i].has][train[i]].ravel()

    def fun(u: ndarray) -> ndarray:
        key = u.tobytes()
        if cache.get("key") == key:
            return cache["f"]
        mdl = apply(p_nom, effects, u[:npar] * scale)
        f = np.full(n_res, BAD)
        if not isinstance(mdl, str):
            for i in dec:  # the decays' fitted start states stay in the views (for the chi-squares)
                views[i].z0 = start(i, u)
            # the records in parallel threads (the integrator releases the GIL)
            rs = pmap(lambda i: one(i, mdl, u), range(len(views)), [v.n_out for v in views])
            for i, r in enumerate(rs):
                if r is None:
                    f[:] = BAD
                    break
                f[offs[i] : offs[i + 1]] = r
        cache.update(key=key, f=f)
        return f

    last: dict[str, Any] = {}  #: the newest Jacobian and its point (a fit stopped at the deadline)

    def jac(u: ndarray) -> ndarray:
        """Forward differences, every (column, record) simulation side by side in the threads: a
        parameter's column takes every record, a decay's start-state column only its own record."""
        if past_deadline():
            last["stop"] = u.copy()
            raise OutOfTime
        f0 = fun(u).copy()
        J = np.zeros((n_res, u.size))
        mdl0 = apply(p_nom, effects, u[:npar] * scale)
        steps = [1e-3 * max(1.0, abs(x)) for x in u]
        tasks: list[tuple[int, int, Model | str, ndarray]] = []
        for j in range(u.size):
            up = u.copy()
            up[j] += steps[j]
            if j < npar:
                mdl = apply(p_nom, effects, up[:npar] * scale)
                tasks += [(j, i, mdl, up) for i in range(len(views))]
            elif not isinstance(mdl0, str):
                tasks.append((j, dec[(j - npar) // 4], mdl0, up))

        def col(t: tuple[int, int, Model | str, ndarray]) -> ndarray | None:
            _, i, mdl, up = t
            return None if isinstance(mdl, str) else one(i, mdl, up)

        rs = pmap(col, tasks, [views[t[1]].n_out for t in tasks])
        bad = {t[0] for t, r in zip(tasks, rs) if r is None and t[0] < npar}
        for (j, i, _, _), r in zip(tasks, rs):
            if j in bad:  # a parameter step the model refuses or that blows up: the whole residual BAD
                J[:, j] = (BAD - f0) / steps[j]
            elif r is not None:
                J[offs[i] : offs[i + 1], j] = (r - f0[offs[i] : offs[i + 1]]) / steps[j]
        last["jac"] = J
        return J

    for i in dec:
        views[i].phi = None  # a decay's start state is a fitted unknown, not projected
    try:
        if starts is None:
            starts = [
                np.clip(np.where(np.isfinite(lb[:npar]), 1.0, 0.0), lb[:npar], ub[:npar])
            ]  # bounded: at its scale
            if "friction" in effects:  # and a Coulomb-like start: a steep slope (the link sticks)
                k = sum(len(TEFFECTS[e][0]) for e in effects[: effects.index("friction")]) + 1
                u1 = starts[0].copy()
                u1[k] = FRICTION_STEEP / scale[k]
                starts.append(u1)
        starts = [np.concatenate([np.clip(u0, lb[:npar], ub[:npar]), np.zeros(4 * len(dec))]) for u0 in starts]
        if npar:
            _rest_or_estimate(views, apply(p_nom, effects, starts[0][:npar] * scale), train, dec)
        if ramp and dec and not z_start and "friction" in effects and not linearise:
            ramped: list[ndarray] = []
            for u0 in starts:  # starts the ramp brings to one point are fitted once
                u = _decay_ramp(views, p_nom, effects, train, sc, u0, base, dec)
                if not any(np.allclose(u[:npar], w[:npar], rtol=RAMP_SAME, atol=RAMP_SAME) for w in ramped):
                    ramped.append(u)
            starts = ramped
        if linearise:
            try:
                return _linearised(views, p_nom, effects, train, starts[0], scale, fun, jac, start, offs, BAD)
            except OutOfTime:
                return TFit(effects, starts[0][:npar] * scale, np.full(npar, np.inf), ok=False, reason=CUT, cut=True)
        best = None
        if not starts[0].size:
            mdl = apply(p_nom, (), np.zeros(0))
            assert not isinstance(mdl, str)
            st = _stack(views, mdl, train)
            if st is None:
                return TFit(effects, np.zeros(0), np.zeros(0), ok=False, reason="the nominal simulation blows up")
            return _finish(views, effects, np.zeros(0), np.zeros(0), st[1], train, test)
        cut = False
        for u0 in starts:
            last.clear()  # a stop's Jacobian is this start's own, never an earlier start's
            try:
                r = least_squares(
                    fun, u0, jac=jac, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=max_nfev, **TOL
                )
            except (ValueError, np.linalg.LinAlgError):
                continue
            except OutOfTime:  # the best point reached: the newest accepted iterate (the Jacobian's point)
                cut = True
                u = last["stop"]
                r = SimpleNamespace(x=u, cost=0.5 * float(np.sum(fun(u) ** 2)), jac=last.get("jac"))
            if best is None or r.cost < best.cost:
                best = r
            if cut:
                break
        if best is not None and len(dec) < len(views) and not cut:  # the others' start states under the fitted model
            m1 = apply(p_nom, effects, best.x[:npar] * scale)
            if not isinstance(m1, str):
                for i, (v, m) in enumerate(zip(views, train)):
                    if i not in dec:
                        start_update(v, m1, m)
                cache.clear()
                try:
                    best = least_squares(
                        fun, best.x, jac=jac, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=10, **TOL
                    )
                except (ValueError, np.linalg.LinAlgError):
                    pass
                except OutOfTime:  # the first pass's optimum, its start states refreshed: no worse start
                    cut = True
        if best is not None:
            fun(best.x)  # leaves the decays' fitted start states in the views for the chi-squares
        out = _conclude(views, p_nom, effects, train, test, scale, best, n_res, BAD)
        out.z0 = {views[i].name: views[i].z0.copy() for i in dec}
        if cut:
            out.cut, out.reason = True, CUT
        return out
    finally:
        for v, z, ph in zip(views, saved, phis):
            v.z0, v.phi = z, ph


CUT = "stopped at the CPU budget before it converged"

#: :func:`_decay_ramp`'s windows of the free decays [periods of the nominal's slowest mode]
RAMP_PERIODS = (2.0, 4.0, 8.0, 16.0)
RAMP_NFEV = 20  #: trust-region evaluations per window of the ramp
#: CPU seconds of one window's fit in the ramp at most (0.2-0.6 s measured from the default starts; from the
#: friction restart's large start, whose stick-slip needs a fine grid, one window took 134 s on seed 9696
#: tr013): past it the window's fit stops with the point it reached (:func:`cpu_deadline`)
RAMP_CPU = 5.0
#: two starts whose ramped parameters agree to this (relative, and absolute in units of their scales) are one
RAMP_SAME = 1e-2


def _decay_ramp(
    views: list[TView],
    p_nom: ndarray,
    effects: tuple[str, ...],
    train: list[ndarray],
    sc: dict[str, tuple[float, ...]],
    u0: ndarray,
    base: list[ndarray],
    dec: list[int],
) -> ndarray:
    """The start u0 of :func:`fit` (scaled parameters, then each decay's start-state unknowns) moved by
    fits of the free decays alone on windows from their start growing by RAMP_PERIODS (each window's
    fit begins at the previous one's point; its training samples only). Why: a free decay with dry
    friction ends **stuck** at an offset x - y that its stick-slip history sets, and that offset stays
    for the rest of the record: the chi-square of the whole decay is a comb in the friction force and
    the start state (tr000 of seed 9494, a 2.54 N truth: the start state fitted at df 2.3 or 2.8 N
    leaves a chi-square 700-1500 times the one at 2.54 N, 7193 for 4680 samples). Over the first slip
    phase the response is smooth in both, and each longer window starts inside the next one's basin."""
    from .transient_window import slowest_period, window_views

    period = slowest_period(p_nom)
    if not math.isfinite(period):
        return u0
    npar = len(u0) - 4 * len(dec)
    scale = np.array([s for e in effects for s in sc[e]], float)
    dv = [views[i] for i in dec]
    u = u0.copy()
    for k in RAMP_PERIODS:
        ns = [min(v.n_out, int(round(k * period * v.fs))) for v in dv]
        if all(n >= v.n_out for n, v in zip(ns, dv)):
            break
        wv = [window_views([v], (n + 0.5) / v.n_out)[0] for n, v in zip(ns, dv)]
        masks = [train[i][:n] for i, n in zip(dec, ns)]
        if any(int(m[v.skip :].sum()) < 4 for m, v in zip(masks, wv)):
            continue
        zs = {}
        for j, i in enumerate(dec):
            z = base[i].copy()
            z[:4] += 1e-3 * u[npar + 4 * j : npar + 4 * j + 4]
            zs[views[i].name] = z
        with cpu_deadline(time.process_time() + RAMP_CPU):
            f = fit(wv, p_nom, effects, masks, None, sc, starts=[u[:npar]], max_nfev=RAMP_NFEV, z_start=zs, ramp=False)
        if not f.ok:
            break
        u[:npar] = f.theta / scale
        for j, i in enumerate(dec):
            u[npar + 4 * j : npar + 4 * j + 4] = (f.z0[views[i].name][:4] - base[i][:4]) / 1e-3
        if f.cut:
            break
    return u


def _linearised(
    views: list[TView],
    p_nom: ndarray,
    effects: tuple[str, ...],
    train: list[ndarray],
    u: ndarray,
    scale: ndarray,
    fun: Callable[[ndarray], ndarray],
    jac: Callable[[ndarray], ndarray],
    start: Callable[[int, ndarray], ndarray],
    offs: ndarray,
    BAD: float,
) -> TFit:
    """:func:`fit`'s residual and Jacobian at u (``linearise``)."""
    npar = scale.size
    theta = u[:npar] * scale
    mdl = apply(p_nom, effects, theta)
    if isinstance(mdl, str):
        return TFit(effects, theta, np.full(npar, np.inf), ok=False, reason=mdl)
    for v, m in zip(views, train):
        if v.phi is not None:  # a forced record (a decay's phi is None during the fit)
            start_update(v, mdl, m)
    f0 = fun(u).copy()
    if np.any(f0 == BAD):
        return TFit(effects, theta, np.full(npar, np.inf), ok=False, reason="the simulation blows up")
    J = jac(u)
    z0 = {v.name: start(i, u).copy() for i, v in enumerate(views)}
    return TFit(effects, theta, np.full(npar, np.nan), z0=z0, lin=(f0, J, offs))


def _rest_or_estimate(views: list[TView], mdl: Model | str, train: list[ndarray], dec: list[int]) -> None:
    """Start rule of a forced record, per candidate: simulated from rest or from the start state
    estimated under the nominal, whichever fits its training samples better at the fit's first
    point. The nominal's estimate absorbs what the nominal misses: a record starting at rest under
    a friction truth got 130 mm/s of TMD velocity, from which the friction model never recovered."""
    if isinstance(mdl, str):
        return
    for i, v in enumerate(views):
        if i in dec or not np.any(v.z0[:4]):
            continue
        est = v.z0.copy()
        e1 = residual(v, mdl, train[i])
        v.z0 = np.zeros_like(est)
        e0 = residual(v, mdl, train[i])
        c1 = np.inf if e1 is None else float(np.sum(e1[:, v.has][train[i]] ** 2))
        c0 = np.inf if e0 is None else float(np.sum(e0[:, v.has][train[i]] ** 2))
        if c1 <= c0:
            v.z0 = est


def _conclude(
    views: list[TView],
    p_nom: ndarray,
    effects: tuple[str, ...],
    train: list[ndarray],
    test: list[ndarray] | None,
    scale: ndarray,
    best: Any,
    n_res: int,
    BAD: float,
) -> TFit:
    if best is None or best.cost >= 0.5 * n_res * BAD**2 * 0.5:
        return TFit(effects, np.zeros(scale.size), np.full(scale.size, np.inf), ok=False, reason="fit failed")
    npar = scale.size
    theta = best.x[:npar] * scale
    mdl = apply(p_nom, effects, theta)
    if isinstance(mdl, str):
        return TFit(effects, theta, np.full(scale.size, np.inf), ok=False, reason=mdl)
    try:
        if best.jac is None:  # stopped at the deadline before a Jacobian
            raise np.linalg.LinAlgError
        cov = np.linalg.inv(best.jac.T @ best.jac)
        std = np.sqrt(np.clip(np.diag(cov)[:npar], 0, None)) * scale
    except np.linalg.LinAlgError:
        std = np.full(scale.size, np.inf)
    st = _stack(views, mdl, train)
    if st is None:
        return TFit(effects, theta, std, ok=False, reason="the fitted model's simulation blows up")
    return _finish(views, effects, theta, std, st[1], train, test)


def _finish(
    views: list[TView],
    effects: tuple[str, ...],
    theta: ndarray,
    std: ndarray,
    full: list[ndarray],
    train: list[ndarray],
    test: list[ndarray] | None,
) -> TFit:
    c_tr, n_tr = chi2_of(views, full, train)
    f = TFit(effects, theta, std, chi2={"train": c_tr, "dof_train": n_tr}, resid=full)
    if test is not None:
        c_te, n_te = chi2_of(views, full, test)
        f.chi2.update(test=c_te, dof_test=n_te, var_test=chi2_var_of(views, test))
    return f


def warm_start(f: TFit, sc: dict[str, tuple[float, ...]]) -> dict[str, Any]:
    """The fitted parameters of f and its decays' fitted start states, as the start (keywords of
    :func:`fit`) of fits of the same effects on fewer records (each record alone, the others without
    one): they sit near their optimum, a few steps instead of the whole way from the default start
    (a friction truth's decay took 13 trust-region steps from the nominal's start state, 4 from the
    fit's); empty when f failed."""
    if not f.ok or not np.all(np.isfinite(f.theta)):
        return {}
    return {"starts": [f.theta / np.array([s for e in f.effects for s in sc[e]], float)], "z_start": f.z0}


def z_of(chi2: float, dof: int, var: float | None = None) -> float:
    """(chi2 - dof) / std: the chi-square's distance from the noise in std (std = sqrt(var), by
    default sqrt(2 dof), the one of independent samples)."""
    return (chi2 - dof) / math.sqrt(max(2.0 * dof if var is None else var, 1.0))


def z_test(f: TFit) -> float:
    """The held-out z of a fit: its test chi-square against the noise, the noise's correlation
    accounted for (``var_test``)."""
    return z_of(f.chi2["test"], f.chi2["dof_test"], f.chi2.get("var_test"))
