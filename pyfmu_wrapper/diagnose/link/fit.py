"""Refit candidate effects on training records and score them on held-out records.

* Fitting: variable projection. For fixed nonlinear parameters theta (log10 scale) the force law
  is linear in beta and solved by least squares; theta is found by a grid then Nelder-Mead.
* Uncertainty: covariance sigma^2 (J^T J)^-1 from the Jacobian in (beta, theta), sigma^2 from the
  training residual, inflated by (1 + rho) / (1 - rho) for the residual's lag-1 autocorrelation rho.
* Scoring: the held-out residual sum of squares, as BIC = n_eff ln(RSS/n) + p ln(n_eff), with one
  effective sample count n_eff for the dataset. The noise floor sigma_n is the robust scatter of
  sample-to-sample differences of the nominal residual.
* Gap: NRMSE = rms(residual) / rms(force); gap closed = 1 - G_after / G_before with the excess
  mean square over noise G = max(ms - sigma_n^2, 0) (so a perfect model closes 100 %).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.optimize import minimize

from .. import progress
from ..data import DataError
from .models import Effect, LinkData, basis, effect_list, report_params

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray

    from .models import Effect, LinkData

EXCESS_THRESHOLD = 0.15  #: nominal held-out rms above (1 + this) x noise floor -> gap is structural
BIC_THRESHOLD = 10.0  #: held-out BIC improvement needed to accept an effect (or a second one)
PAIR_SHARE = 0.25  #: a second effect must also close this share of the gap the first one leaves


@dataclass
class Fit:
    effects: tuple  #: effect names
    labels: tuple
    params: dict
    std: dict
    beta: np.ndarray
    theta: np.ndarray
    rss_train: float
    rss_test: float
    n_params: int
    pred: np.ndarray = field(repr=False)  #: predicted force on all samples
    bic: float = 0.0
    closed: float = 0.0
    nrmse_test: float = 0.0

    @property
    def name(self) -> str:
        return "+".join(self.effects)


def _log(x: float) -> float:
    """ln of a mean square; an exact fit (0) counts as 1e-300 (a perfect held-out prediction)."""
    return math.log(max(x, 1e-300))


def split_masks(ld: LinkData) -> tuple[ndarray, ndarray]:
    """(train, test) sample masks: yaml roles, else every third record (sorted by omega, amplitude)
    held out, else the last 40 % of a single record."""
    n = len(ld.records)
    roles = [r.role for r in ld.records]
    if any(roles):
        test_ids = [i for i, r in enumerate(roles) if r == "test"]
        train_ids = [i for i, r in enumerate(roles) if r != "test"]
    elif n >= 3:
        order = sorted(range(n), key=lambda i: (round(ld.records[i].omega or 0, 6), ld.records[i].amplitude or 0))
        test_ids = [order[k] for k in range(n) if k % 3 == 1]
        train_ids = [i for i in range(n) if i not in test_ids]
    elif n == 2:
        train_ids, test_ids = [0], [1]
    else:
        k = ld.starts[0] + int(0.6 * (ld.starts[1] - ld.starts[0]))
        idx = np.arange(ld.F.size)
        return idx < k, idx >= k
    if not test_ids:
        raise DataError(
            "every record has role 'train': mark at least one record 'role: test' (held out), "
            "or give no roles (records are then held out automatically)"
        )
    if not train_ids:
        raise DataError("every record has role 'test': at least one record must be for training")
    return ld.mask(train_ids), ld.mask(test_ids)


def _combined_basis(effects: Sequence[Effect], ld: LinkData, theta: ndarray) -> tuple[ndarray, ndarray]:
    offs, cols, k = [], [], 0
    removes_friction = False
    for e in effects:
        th = theta[k : k + len(e.theta0)]
        k += len(e.theta0)
        off, Phi = basis(e, ld, th)
        repl = e.name in ("friction", "compliant_friction") or (e.name == "play" and len(e.theta0) == 2)
        if not (repl and removes_friction):
            offs.append(off)
        removes_friction |= repl
        cols.append(Phi)
    return ld.F_nom + sum(offs), np.hstack(cols)


def _solve(y: ndarray, off: ndarray, Phi: ndarray, m: ndarray) -> tuple[ndarray, float]:
    A = Phi[m]
    sc = np.sqrt((A**2).mean(axis=0))
    sc[sc == 0] = 1.0
    beta = np.linalg.lstsq(A / sc, y[m] - off[m], rcond=None)[0] / sc
    r = y[m] - off[m] - A @ beta
    return beta, float(r @ r)


def _rho(r: ndarray) -> float:
    r = r - r.mean()
    den = float(r @ r)
    return 0.0 if den == 0 else float(np.clip((r[1:] @ r[:-1]) / den, 0.0, 0.98))


def fit_effects(effects: Sequence[Effect], ld: LinkData, train: ndarray, test: ndarray) -> Fit:
    """Fit a set of effects (1 or 2) on the training samples."""
    effects = tuple(effects)
    grids = [g for e in effects for g in e.theta0]

    def rss(theta: np.ndarray) -> float:
        off, Phi = _combined_basis(effects, ld, theta)
        return _solve(ld.F, off, Phi, train)[1]

    theta = np.zeros(0)
    if grids:
        # the grid point of least rss (the first of equal ones)
        best = min(((rss(np.array(th)), np.array(th)) for th in itertools.product(*grids)), key=lambda vt: vt[0])
        theta = best[1]
        lo = np.array([min(g) - 0.5 for g in grids])
        hi = np.array([max(g) + 0.5 for g in grids])
        res = minimize(
            lambda th: rss(np.clip(th, lo, hi)),
            theta,
            method="Nelder-Mead",
            options=dict(xatol=0.01, fatol=1e-9 * best[0], maxiter=60 * len(grids)),
        )
        theta = np.clip(res.x, lo, hi) if res.fun < best[0] else theta
    off, Phi = _combined_basis(effects, ld, theta)
    beta, rss_tr = _solve(ld.F, off, Phi, train)
    pred = off + Phi @ beta
    r = ld.F - pred
    rss_te = float(r[test] @ r[test])
    params, std = {}, {}
    # Jacobian in (beta, theta) on the training samples
    cols = [Phi[train]]
    for j in range(theta.size):
        th = theta.copy()
        h = 1e-3
        th[j] += h
        o2, P2 = _combined_basis(effects, ld, th)
        cols.append(((o2 + P2 @ beta - pred)[train] / h)[:, None])
    J = np.hstack(cols)
    n, p = int(train.sum()), J.shape[1]
    rho = _rho(r[train])
    s2 = rss_tr / max(n - p, 1) * (1 + rho) / (1 - rho)
    try:
        js = np.sqrt((J**2).sum(axis=0))
        js[js == 0] = 1.0
        cov = s2 * np.linalg.pinv((J / js).T @ (J / js)) / np.outer(js, js)
        sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    except np.linalg.LinAlgError:  # pragma: no cover
        sd = np.full(p, np.nan)
    kb, kt = 0, 0
    for e in effects:
        nb, nt = 1, len(e.theta0)  # every effect has one linear coefficient
        b_e, t_e = beta[kb : kb + nb], theta[kt : kt + nt]
        ps = report_params(e, ld, b_e, t_e)
        sds = list(sd[kb : kb + nb]) + [sd[beta.size + kt + i] * math.log(10) * 10 ** t_e[i] for i in range(nt)]
        for (k, v), s in zip(ps.items(), _order_sd(e, sds, len(ps))):
            params[f"{e.name}.{k}"] = v
            std[f"{e.name}.{k}"] = float(s)
        kb += nb
        kt += nt
    progress.candidate("+".join(e.name for e in effects) or "nominal")
    return Fit(
        effects=tuple(e.name for e in effects),
        labels=tuple(e.label for e in effects),
        params=params,
        std=std,
        beta=beta,
        theta=theta,
        rss_train=rss_tr,
        rss_test=rss_te,
        n_params=p,
        pred=pred,
    )


def _order_sd(e: Effect, sds: list[float], n: int) -> list[float]:
    """Standard deviations in report_params order (linear first, then nonlinear)."""
    if e.name == "play" and len(e.theta0) == 1:  # report order: play_gap, link_stiffness
        return [sds[1], sds[0]]
    if e.name == "play":  # play_gap, friction_force, elastic_deflection
        return [sds[1], sds[0], sds[2]]
    return sds[:n] + [float("nan")] * (n - len(sds))


def gap_closed(ms_before: float, ms_after: float, noise: float) -> float:
    g0 = max(ms_before - noise**2, 0.0)
    g1 = max(ms_after - noise**2, 0.0)
    return float("nan") if g0 <= 0 else 1.0 - g1 / g0


@dataclass
class Diagnosis:
    nominal_rss_test: float
    n_test: int
    n_eff: float
    noise: float
    structural: bool
    ranking: list  #: Fits, best first (singles, then pairs tried)
    chosen: Fit | None
    train: np.ndarray = field(repr=False)
    test: np.ndarray = field(repr=False)
    verdict: str = ""
    bic0: float = 0.0  #: held-out BIC of the nominal model
    excess: float = 0.0  #: nominal held-out rms / noise floor - 1


def diagnose_link(ld: LinkData, max_pairs_from: int = 7) -> Diagnosis:
    train, test = split_masks(ld)
    # the noise floor of the held-out samples, from each record's own noise
    ld.noise = float(np.sqrt(np.mean(ld.noise_rec[ld.rec[test]] ** 2)))
    r0 = ld.F - ld.F_nom
    nt = int(test.sum())
    rss0 = float(r0[test] @ r0[test])
    f_rms = float(np.sqrt(np.mean(ld.F[test] ** 2)))
    if not f_rms > 0:
        raise DataError(
            "the measured force is zero in every held-out record ("
            + ", ".join(sorted({ld.records[i].name for i in ld.rec[test]}))
            + "): a dead force channel, nothing to diagnose"
        )
    effects = effect_list(ld)
    fits = [fit_effects([e], ld, train, test) for e in effects]
    best = min(fits, key=lambda f: f.rss_test)
    n_eff = max(10.0, nt * (1 - _rho((ld.F - best.pred)[test])) / (1 + _rho((ld.F - best.pred)[test])))

    def score(f: Fit) -> None:
        f.bic = n_eff * _log(f.rss_test / nt) + f.n_params * math.log(n_eff)
        f.closed = gap_closed(rss0 / nt, f.rss_test / nt, ld.noise)
        f.nrmse_test = math.sqrt(f.rss_test / nt) / f_rms if f_rms > 0 else float("nan")

    for f in fits:
        score(f)
    bic0 = n_eff * _log(rss0 / nt)
    fits.sort(key=lambda f: f.bic)
    excess = math.sqrt(rss0 / nt) / max(ld.noise, 1e-300) - 1.0
    structural = excess > EXCESS_THRESHOLD and fits[0].bic < bic0 - BIC_THRESHOLD
    chosen = fits[0] if structural else None
    ranking = list(fits)
    if chosen is not None:  # structural
        by = {e.name: e for e in effects}
        top = [f.effects[0] for f in fits[:max_pairs_from]]
        pairs = [fit_effects([by[a], by[b]], ld, train, test) for a, b in itertools.combinations(top, 2)]
        for f in pairs:
            score(f)
        pairs.sort(key=lambda f: f.bic)
        ranking += pairs
        if (
            pairs
            and pairs[0].bic < chosen.bic - BIC_THRESHOLD
            and pairs[0].closed > chosen.closed + PAIR_SHARE * (1 - chosen.closed)
        ):
            chosen = pairs[0]
    ranking.sort(key=lambda f: f.bic)
    if chosen is None:
        verdict = (
            f"No structural effect: the held-out gap (rms {math.sqrt(rss0 / nt):.4g} N) is within "
            f"{100 * EXCESS_THRESHOLD:.0f} % of the noise floor ({ld.noise:.4g} N) or no candidate beats it."
        )
    else:
        verdict = (
            f"Gap attributed to {' + '.join(chosen.labels)} (closes {100 * chosen.closed:.0f} % of the held-out gap)."
        )
    d = Diagnosis(
        nominal_rss_test=rss0,
        n_test=nt,
        n_eff=n_eff,
        noise=ld.noise,
        structural=structural,
        ranking=ranking,
        chosen=chosen,
        train=train,
        test=test,
        verdict=verdict,
        bic0=bic0,
        excess=excess,
    )
    return d


def per_band(ld: LinkData, diag: Diagnosis, fit: Fit | None) -> list[Any]:
    """Held-out gap per frequency band (records grouped by drive frequency)."""
    rows = []
    oms = np.array([r.omega if r.omega is not None else -1.0 for r in ld.records])
    test_recs = sorted(set(ld.rec[diag.test].tolist()))
    for w in sorted(set(np.round(oms[test_recs], 6))):
        ids = [i for i in test_recs if abs(oms[i] - w) < 1e-6]
        m = ld.mask(ids) & diag.test
        r0 = (ld.F - ld.F_nom)[m]
        ms0 = float(np.mean(r0**2))
        fr = float(np.sqrt(np.mean(ld.F[m] ** 2)))
        row = {
            "omega": float(w) if w > 0 else None,  # None: records without a drive frequency
            "records": [ld.records[i].name for i in ids],
            "nrmse_before": math.sqrt(ms0) / fr if fr > 0 else float("nan"),
        }
        if fit is not None:
            ms1 = float(np.mean((ld.F - fit.pred)[m] ** 2))
            row.update(
                nrmse_after=math.sqrt(ms1) / fr if fr > 0 else float("nan"), gap_closed=gap_closed(ms0, ms1, ld.noise)
            )
        rows.append(row)
    return rows
