"""Transient records: the candidate effects as changes of the simulated model, and their fits.

Every candidate is a change of the model that :mod:`.transient_sim` simulates with the measured
force: the vocabulary of the system diagnosis (:mod:`.effects`) plus every parameter of the
nominal model (M, K, C, m, k, c, I; dry friction df through ``friction``). Parameters are fitted by
nonlinear least squares (``scipy.optimize.least_squares``, trust region, finite-difference
Jacobian) on the whitened simulation error of the training samples, the start state of every
record projected out (variable projection, :mod:`.transient_sim`). Their std is
``sqrt(diag((J^T J)^-1))`` of the whitened problem (the noise is measured, so no rescaling).
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ...physics.params import P_C, P_I, P_K, P_M, P_MODEL, P_c, P_ci, P_df, P_eps, P_k, P_k3, P_ki, P_m, P_s
from .transient_sim import fastest_rate, simulate

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_sim import TView

#: the play candidate's gear contact (a nuisance of the model; stiff enough that the contact is short
#: against the motion, soft enough for an explicit step of ~1/1000 of the TMD period)
PLAY_KI, PLAY_CI = 2.0e6, 20.0
#: a nominal's dry friction is regularised as df (2/pi) atan(s v) with s = FRICTION_RATE x (the
#: nominal's fastest modal rate) x m / (df 2/pi); the friction candidate fits its slope s within
#: FRICTION_SLOPE (a transition velocity of 0.2 mm/s at most is resolved: the explicit step's cost)
FRICTION_RATE = 20.0
FRICTION_SLOPE = (10.0, 5000.0)
#: effect -> (parameter names, units, scale of each parameter)
TEFFECTS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "viscous": (("delta_damping",), ("N s/m",)),
    "friction": (("friction_force", "friction_slope"), ("N", "s/m")),
    "play": (("play_gap",), ("m",)),
    "mass_split": (("delta_inertance",), ("kg",)),
    "cubic": (("cubic_stiffness",), ("N/m^3",)),
    "force_error": (("force_gain_error",), ("1",)),
    "sensor_offset": (("x_offset", "y_offset"), ("m", "m")),
    "base_mass": (("delta_mass",), ("kg",)),
    "base_stiffness": (("delta_stiffness",), ("N/m",)),
    "base_damping": (("delta_damping",), ("N s/m",)),
    "tmd_stiffness": (("delta_stiffness",), ("N/m",)),
    "tmd_mass": (("delta_mass",), ("kg",)),
    "inertance": (("delta_inertance",), ("kg",)),
}
TOL = {"ftol": 1e-7, "xtol": 1e-6, "gtol": 1e-8}  #: least_squares stopping (relative change of the cost / step)
#: bounds of the fit (SI)
BOUNDS = {
    "friction.friction_force": (0.0, np.inf),
    "friction.friction_slope": FRICTION_SLOPE,
    "play.play_gap": (0.0, np.inf),
}
LABELS = {
    "tmd_mass": "TMD mass m off the nominal",
    "inertance": "inertance I off the nominal (m unchanged)",
}


def scales(p: ndarray, stroke: float, xscale: float) -> dict[str, tuple[float, ...]]:
    """Typical size of each parameter (the fit works in units of these)."""
    return {
        "viscous": (0.1 * p[P_c] + 1.0,),
        "friction": (1.0, 1000.0),
        "play": (1e-4,),
        "mass_split": (0.1,),
        "cubic": (0.1 * p[P_k] / max(stroke, 1e-6) ** 2,),
        "force_error": (0.01,),
        "sensor_offset": (0.01 * xscale, 0.01 * xscale),
        "base_mass": (0.01 * p[P_M],),
        "base_stiffness": (0.01 * p[P_K],),
        "base_damping": (0.1 * p[P_C],),
        "tmd_stiffness": (0.01 * p[P_k],),
        "tmd_mass": (0.01 * p[P_m],),
        "inertance": (0.1,),
    }


@dataclass
class Model:
    """A candidate model: the kernels' parameter vector, a force gain and sensor offsets."""

    p: ndarray
    gain: float = 1.0
    offset: tuple[float, float] = (0.0, 0.0)


def apply(p_nom: ndarray, effects: tuple[str, ...], theta: ndarray) -> Model | str:
    """The model with the effects at parameters theta (in SI, concatenated in effect order), or the
    reason it is not physical (m, M, K, k <= 0, I, c, C, df, gap < 0, 1 + a <= 0)."""
    p = p_nom.copy()
    mdl = Model(p)
    i = 0
    for e in effects:
        th = theta[i : i + len(TEFFECTS[e][0])]
        i += len(th)
        if e == "viscous":
            p[P_c] += th[0]
        elif e == "friction":
            if th[0] < 0:
                return f"friction force df < 0 ({th[0]:.3g} N)"
            p[P_df], p[P_s] = th[0], th[1]
        elif e == "play":
            if th[0] < 0:
                return f"play gap < 0 ({th[0]:.3g} m)"
            p[P_MODEL], p[P_ki], p[P_ci], p[P_eps] = 2.0, PLAY_KI, PLAY_CI, th[0]
        elif e == "mass_split":
            p[P_I] += th[0]
            p[P_m] -= th[0]
        elif e == "cubic":
            p[P_k3] += th[0]
        elif e == "force_error":
            mdl.gain = 1.0 + th[0]
        elif e == "sensor_offset":
            mdl.offset = (float(th[0]), float(th[1]))
        elif e == "base_mass":
            p[P_M] += th[0]
        elif e == "base_stiffness":
            p[P_K] += th[0]
        elif e == "base_damping":
            p[P_C] += th[0]
        elif e == "tmd_stiffness":
            p[P_k] += th[0]
        elif e == "tmd_mass":
            p[P_m] += th[0]
        elif e == "inertance":
            p[P_I] += th[0]
    if p[P_df] > 0 and "friction" not in effects:  # a nominal's friction: the slope an explicit step resolves
        p[P_s] = min(p_nom[P_s], FRICTION_RATE * fastest_rate(p_nom) * max(p[P_m], 1e-9) / (p[P_df] * 2 / math.pi))
    for idx, name in ((P_M, "M"), (P_K, "K"), (P_m, "m"), (P_k, "k")):
        if p[idx] <= 0:
            return f"{name} <= 0 ({p[idx]:.3g})"
    for idx, name in ((P_C, "C"), (P_c, "c"), (P_I, "I")):
        if p[idx] < 0:
            return f"{name} < 0 ({p[idx]:.3g})"
    if int(p[P_MODEL]) == 2 and p[P_I] <= 0:
        return "play needs an inertance I > 0"
    if mdl.gain <= 0:
        return f"1 + a <= 0 ({mdl.gain:.3g})"
    return mdl


def residual(v: TView, mdl: Model, mask: ndarray) -> ndarray | None:
    """Whitened simulation error (n_out, 4) of record v with the start state projected out on the
    samples of ``mask`` (NaN for channels not recorded); None when the simulation blows up."""
    y = simulate(v, mdl.p, force_gain=mdl.gain)
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


def fit(
    views: list[TView],
    p_nom: ndarray,
    effects: tuple[str, ...],
    train: list[ndarray],
    test: list[ndarray] | None,
    sc: dict[str, tuple[float, ...]],
    starts: list[ndarray] | None = None,
    max_nfev: int = 40,
) -> TFit:
    """Fit the effects' parameters on the ``train`` samples; chi-squares on train and test.

    The start state of a free-decay record (its whole response) is fitted with the parameters, as
    four more unknowns (units of 1 mm, 1 mm/s); other records' start states are projected out
    linearly and refreshed under the fitted model before a second pass."""
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
    phis = [v.phi for v in views]
    cache: dict[str, Any] = {}

    def one(i: int, mdl: Model, u: ndarray) -> ndarray | None:
        v = views[i]
        if i in dec:
            k = npar + 4 * dec.index(i)
            v.z0 = saved[i].copy()
            v.z0[:4] += 1e-3 * u[k : k + 4]
        e = residual(v, mdl, train[i])
        return None if e is None else e[:, v.has][train[i]].ravel()

    def fun(u: ndarray) -> ndarray:
        key = u.tobytes()
        if cache.get("key") == key:
            return cache["f"]
        mdl = apply(p_nom, effects, u[:npar] * scale)
        f = np.full(n_res, BAD)
        if not isinstance(mdl, str):
            for i in range(len(views)):
                r = one(i, mdl, u)
                if r is None:
                    f[:] = BAD
                    break
                f[offs[i] : offs[i + 1]] = r
        cache.update(key=key, f=f)
        return f

    def jac(u: ndarray) -> ndarray:
        f0 = fun(u).copy()
        J = np.zeros((n_res, u.size))
        mdl0 = apply(p_nom, effects, u[:npar] * scale)
        for j in range(u.size):
            h = 1e-3 * max(1.0, abs(u[j]))
            up = u.copy()
            up[j] += h
            if j < npar:
                J[:, j] = (fun(up) - f0) / h
            elif not isinstance(mdl0, str):
                i = dec[(j - npar) // 4]
                r = one(i, mdl0, up)
                if r is not None:
                    J[offs[i] : offs[i + 1], j] = (r - f0[offs[i] : offs[i + 1]]) / h
        return J

    for i in dec:
        views[i].phi = None  # a decay's start state is a fitted unknown, not projected
    try:
        if starts is None:
            starts = [
                np.clip(np.where(np.isfinite(lb[:npar]), 1.0, 0.0), lb[:npar], ub[:npar])
            ]  # bounded: at its scale
        starts = [np.concatenate([u0, np.zeros(4 * len(dec))]) for u0 in starts]
        best = None
        if not starts[0].size:
            mdl = apply(p_nom, (), np.zeros(0))
            assert not isinstance(mdl, str)
            st = _stack(views, mdl, train)
            if st is None:
                return TFit(effects, np.zeros(0), np.zeros(0), ok=False, reason="the nominal simulation blows up")
            return _finish(views, effects, np.zeros(0), np.zeros(0), st[1], train, test)
        for u0 in starts:
            try:
                r = least_squares(
                    fun, u0, jac=jac, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=max_nfev, **TOL
                )
            except (ValueError, np.linalg.LinAlgError):
                continue
            if best is None or r.cost < best.cost:
                best = r
        if best is not None and len(dec) < len(views):  # the others' start states under the fitted model
            m1 = apply(p_nom, effects, best.x[:npar] * scale)
            if not isinstance(m1, str):
                for i, (v, m) in enumerate(zip(views, train)):
                    if i not in dec:
                        start_update(v, m1, m)
                cache.clear()
                with contextlib.suppress(ValueError, np.linalg.LinAlgError):
                    best = least_squares(
                        fun, best.x, jac=jac, bounds=(lb, ub), method="trf", x_scale=1.0, max_nfev=10, **TOL
                    )
        if best is not None:
            fun(best.x)  # leaves the decays' fitted start states in the views for the chi-squares
        return _conclude(views, p_nom, effects, train, test, scale, best, n_res, BAD)
    finally:
        for v, z, ph in zip(views, saved, phis):
            v.z0, v.phi = z, ph


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
        f.chi2.update(test=c_te, dof_test=n_te)
    return f


def z_of(chi2: float, dof: int) -> float:
    """(chi2 - dof) / sqrt(2 dof): the chi-square's distance from the noise in std."""
    return (chi2 - dof) / math.sqrt(2.0 * max(dof, 1))
