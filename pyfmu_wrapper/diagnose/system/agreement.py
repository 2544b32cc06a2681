"""Whether the records agree on the named effects' parameters: each record fitted alone.

A cause that explains the data has one value of its parameters for every record. A parameter that
drifts between records (the truth changed while the rig ran) or a pair of effects standing in for a
cause outside the vocabulary (an odd quadratic spring k2 |u| u fitted as a linear spring plus a cubic
one: the best pair changes with the amplitude) fits each record with its own values.

The one test (:func:`records_agree`, used by the steady records' :func:`record_agreement` and the
transient records' :meth:`.transient_heldout.HeldOut.agreement`): per parameter

    chi2 = sum_i (p_i - p_w)^2 / s_i^2,    p_w the inverse-variance weighted mean, n_records - 1 dof,

refused at the level ``LEVEL`` with Bonferroni over the parameters tested (the family's p-value is
``min(1, n_params x the smallest p``). Per parameter rather than pooled over the parameters: a cause
outside the vocabulary shows as one parameter that drifts, which a pooled chi-square dilutes with
the dof of those that agree, and the verdict can name the parameter. A caller may add a model-error
floor to the stds (the transient fits: the measured force is the simulation's input with its own
noise, errors in variables that the statistical std does not cover).

Steady records: the linear parameters of the named effects fitted on each record alone (the same
whitened equation error as the pooled fit, :func:`.eqfit.fit_eq`); their stds are those of the
pooled fit's method, scaled up by the record's own misfit (a record the effects do not fit does not
claim a tight value). The play gap (fitted through the solver) is not tested here.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.stats import chi2 as chi2_dist

from .eqfit import fit_eq

if TYPE_CHECKING:
    from collections.abc import Sequence

    from .model import SystemModel

LEVEL = 1e-3  #: false-alarm probability of the agreement test per dataset
MIN_RECORDS = 3  #: fewer records than this: the test is not made


def records_agree(
    values: Sequence[Any],
    stds: Sequence[Any],
    names: Sequence[str],
    floor: float = 0.0,
    scale: Sequence[float] | None = None,
    level: float | None = None,
    silent: Sequence[Sequence[bool]] | None = None,
) -> dict[str, Any] | None:
    """The agreement test (module doc) of per-record parameters ``values[i][j]`` (record i, parameter
    ``names[j]``) with stds ``stds[i][j]``; ``floor``: a model-error std added in quadrature, that share
    of max(|weighted mean|, ``scale[j]``); ``level``: the test's level (default :data:`LEVEL`, read at
    the call). A parameter that some record cannot determine (non-finite)
    does not vote. ``{"agree", "level", "p_value" (the family's), "chi2", "dof" (the worst parameter's),
    "worst": {"param", ...}, "params": {name: {"values", "stds", "weighted_mean", "chi2", "dof",
    "p_value"}}}``, or None when no parameter votes. ``silent[i][j]``: record i's value of parameter j
    is left out of that parameter's test (the others still test it when at least two are left)."""
    V = np.asarray(values, float)
    S = np.maximum(np.asarray(stds, float), 1e-300)
    keep = np.ones(V.shape, bool) if silent is None else ~np.asarray(silent, bool)
    out: dict[str, Any] = {}
    for j, k in enumerate(names):
        p, s = V[keep[:, j], j], S[keep[:, j], j]
        n = p.size
        if n < 2 or not (np.all(np.isfinite(p)) and np.all(np.isfinite(s))):
            continue
        if floor:
            mean = float((p / s**2).sum() / (1 / s**2).sum())
            s = np.sqrt(s**2 + (floor * max(abs(mean), float(scale[j]) if scale is not None else 0.0)) ** 2)
        w = 1 / s**2
        mean = float((w * p).sum() / w.sum())
        c = float((((p - mean) / s) ** 2).sum())
        out[k] = {
            "values": p.tolist(),
            "stds": s.tolist(),
            "weighted_mean": mean,
            "chi2": c,
            "dof": n - 1,
            "p_value": float(chi2_dist.sf(c, n - 1)),
        }
    if not out:
        return None
    level = LEVEL if level is None else level
    worst = min(out, key=lambda k: out[k]["p_value"])
    p_family = min(1.0, len(out) * out[worst]["p_value"])
    return {
        "agree": bool(p_family >= level),
        "level": level,
        "p_value": p_family,
        "chi2": out[worst]["chi2"],
        "dof": out[worst]["dof"],
        "worst": {"param": worst, **out[worst]},
        "params": out,
    }


def record_agreement(model: SystemModel, effects: tuple[str, ...], theta: dict[str, Any]) -> dict[str, Any] | None:
    """The agreement of the steady records on the linear parameters of ``effects`` (``theta``: the pooled
    fit's nonlinear settings, e.g. the friction slope): :func:`records_agree` with the records' names
    under ``records``, or None when fewer than MIN_RECORDS records or no linear parameter."""
    n = len(model.views)
    if n < MIN_RECORDS:
        return None
    fits = [fit_eq(model, effects, [([i], [i])], theta) for i in range(n)]
    names = [k for k in fits[0].params if k in fits[0].std and not k.endswith("friction_slope")]
    names = [k for k in names if not k.startswith("play.")]
    if not names:
        return None
    out = records_agree([[f.params[k] for k in names] for f in fits], [[f.std[k] for k in names] for f in fits], names)
    if out is None:
        return None
    return {**out, "records": [v.name for v in model.views]}
