"""Transient records: the screen that picks which candidates are fully fitted.

Every candidate's full fit costs tens of simulations of every record (a trust-region least squares
with a finite-difference Jacobian); a linear candidate's effect on the residual near the nominal is
its Jacobian column, one simulation per record and parameter. The screen takes one Gauss-Newton
step from the nominal per candidate (the drop of the training chi-square it predicts,
``g^T (J^T J)^-1 g`` with ``g = J^T r``) and fits fully the SCREEN_KEEP linear candidates with the
largest drop, and always the nonlinear ones (NONLINEAR), whose effect at zero is not their effect
at size. Candidates screened out are listed with their predicted drop (diagnosis.json).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .transient_effects import apply
from .transient_fit import pmap, residual

if TYPE_CHECKING:
    from numpy import ndarray

    from ..shapes import TransientDiagnosisShape


SCREEN_KEEP = 4  #: linear candidates fully fitted after the screen
NONLINEAR = ("friction", "play", "cubic")  #: always fitted


def screen(
    d: TransientDiagnosisShape,
    cands: list[str],
    train: list[ndarray],
    base: tuple[tuple[str, ...], ndarray] | None = None,
) -> tuple[list[str], dict[str, float]]:
    """The candidates to fit: the nonlinear ones (always) and the SCREEN_KEEP linear ones whose
    one Gauss-Newton step from the nominal lowers the training chi-square most (each parameter's
    column: one simulation per record); returns (kept, {screened out: its linearised drop}). With
    ``base`` (effects, fitted parameters) the step starts from that model instead: what a second
    effect would add to the first."""
    b_eff, b_th = base if base is not None else ((), np.zeros(0))
    nom = apply(d.p_nom, b_eff, b_th)
    assert not isinstance(nom, str)

    def stack(mdl: Any) -> ndarray | None:
        rs = pmap(lambda i: residual(d.views[i], mdl, train[i]), range(len(d.views)), [v.n_out for v in d.views])
        out = [r[:, v.has][m].ravel() for r, v, m in zip(rs, d.views, train) if r is not None]
        return np.concatenate(out) if len(out) == len(rs) else None

    r0 = stack(nom)
    drops: dict[str, float] = {}
    for e in cands:
        if e in NONLINEAR or e in b_eff or r0 is None:
            continue
        cols = []
        for j, s in enumerate(d.sc[e]):
            th = np.zeros(len(d.sc[e]))
            th[j] = 0.1 * s
            mdl = apply(d.p_nom, (*b_eff, e), np.concatenate([b_th, th]))
            r = None if isinstance(mdl, str) else stack(mdl)
            if r is not None:
                cols.append((r - r0) / th[j])
        if cols:
            J = np.column_stack(cols)
            g = J.T @ r0
            drops[e] = float(g @ np.linalg.lstsq(J.T @ J, g, rcond=None)[0])
    ranked = sorted(drops, key=lambda e: -drops[e])
    other = [e for e in cands if e not in b_eff and e not in drops]  # nonlinear, or no column
    keep = ranked[:SCREEN_KEEP] + other  # the linear ones by their drop, largest first
    d.log.append(f"screened: {', '.join(f'{e} {drops[e]:.4g}' for e in ranked)}")
    return keep, {e: drops[e] for e in ranked[SCREEN_KEEP:]}
