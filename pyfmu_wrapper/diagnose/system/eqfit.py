"""Fits of effect sets to the records' equation errors: whitened linear least squares (with optional
priors), nonlinear parameters by a scan, held out record by record (the folds), as the system
diagnosis (:mod:`.diagnosis`) and the play refit (:mod:`.playfit`) use them. The design columns
come from the system model (:mod:`.model`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..data import DataError
from .model import EFFECT_PARAMS, SIGN, SLOPES, RecView, SystemModel

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray


def _lstsq(Phi: ndarray, y: ndarray) -> tuple[ndarray, ndarray]:
    sc = np.sqrt((Phi**2).sum(axis=0))
    sc[sc == 0] = 1.0
    A = Phi / sc
    beta, *_ = np.linalg.lstsq(A, y, rcond=None)
    cov = np.linalg.pinv(A.T @ A) / np.outer(sc, sc)
    return beta / sc, cov


@dataclass
class EqFit:
    effects: tuple
    theta: dict
    beta: np.ndarray
    cov: np.ndarray
    chi2_ho: float  #: held-out chi-square (leave-one-record-out or roles)
    chi2_ho_rec: list
    chi2_fit: float
    n_params: int
    params: dict = field(default_factory=dict)
    std: dict = field(default_factory=dict)
    resid_ho: list = field(default_factory=list)  #: per record, the whitened held-out residual (None: never held out)


def _with_prior(Phi: ndarray, y: ndarray, prior: dict[int, Any] | None) -> tuple[ndarray, ndarray]:
    """Append one row per prior (column k: value b with std sd) to a whitened least-squares problem."""
    if not prior:
        return Phi, y
    R = np.zeros((len(prior), Phi.shape[1]))
    v = np.empty(len(prior))
    for j, (k, (b, sd)) in enumerate(prior.items()):
        R[j, k], v[j] = 1.0 / sd, b / sd
    return np.vstack([Phi, R]), np.concatenate([y, v])


def fit_eq(
    model: SystemModel,
    effects: tuple[str, ...],
    folds: list[tuple[list[int], list[int]]],
    theta: dict[str, Any] | None = None,
    prior: dict[int, Any] | None = None,
) -> EqFit:
    """Fit the linear parameters of ``effects`` on all training records; held-out chi-square by folds.

    folds: list of (train record ids, test record ids). prior: {column: (value, std)} -- evidence
    on a parameter from outside the time records (the FRC fit), added to every fold's training
    data, so a record held out is predicted from all the other evidence."""
    theta = dict(theta or {})
    if "friction" in effects and "friction" not in theta:
        best = None
        for s in SLOPES:
            f = fit_eq(model, effects, folds, {**theta, "friction": (s,)}, prior)
            if best is None or f.chi2_fit < best.chi2_fit:
                best = f
        assert best is not None  # SLOPES is not empty
        return best
    des = model.design(effects, theta)
    ys = [v.r for v in model.views]
    train_all = sorted({i for tr, _ in folds for i in tr})
    chi_rec = [0.0] * len(ys)
    res_rec = [None] * len(ys)
    for tr, te in folds:
        Phi = np.vstack([des[i][1] for i in tr])
        y = np.concatenate([ys[i] - des[i][0] for i in tr])
        beta, _ = _lstsq(*_with_prior(Phi, y, prior))
        for i in te:
            r = ys[i] - des[i][0] - des[i][1] @ beta
            chi_rec[i] += float(r @ r)
            res_rec[i] = r
    Phi, y = _with_prior(
        np.vstack([des[i][1] for i in train_all]), np.concatenate([ys[i] - des[i][0] for i in train_all]), prior
    )
    beta, cov = _lstsq(Phi, y)
    r = y - Phi @ beta
    chi_fit = float(r @ r)
    dof = max(y.size - beta.size, 1)
    cov = cov * max(1.0, chi_fit / dof)
    test_ids = sorted({i for _, te in folds for i in te})
    f = EqFit(
        tuple(effects),
        theta,
        beta,
        cov,
        sum(chi_rec[i] for i in test_ids),
        chi_rec,
        chi_fit,
        beta.size,
        resid_ho=res_rec,
    )
    k = 0
    sd = np.sqrt(np.clip(np.diag(cov), 0, None))
    for e in effects:
        sgn = SIGN.get(e, 1.0)
        for pn in EFFECT_PARAMS[e]:
            f.params[f"{e}.{pn}"] = float(sgn * beta[k])
            f.std[f"{e}.{pn}"] = float(sd[k])
            k += 1
        if e == "friction":
            f.params["friction.friction_slope"] = float(theta["friction"][0])
    return f


def folds_for(views: list[RecView]) -> list[tuple[list[int], list[int]]]:
    """Leave-one-record-out folds, or the dataset's roles (train/test)."""
    n = len(views)
    roles = [v.role for v in views]
    if any(roles):
        te = [i for i, r in enumerate(roles) if r == "test"]
        tr = [i for i, r in enumerate(roles) if r != "test"]
        if not te:
            raise DataError(
                "every time record has role 'train': mark at least one record 'role: test' "
                "(or give no roles: each record is then held out in turn)"
            )
        if not tr:
            raise DataError("every time record has role 'test': at least one record must be for training")
        return [(tr, te)]
    if n < 2:
        raise DataError(
            "the system-level diagnosis needs at least two periodic time records "
            "(one is held out while the others are fitted)"
        )
    return [([j for j in range(n) if j != i], [i]) for i in range(n)]
