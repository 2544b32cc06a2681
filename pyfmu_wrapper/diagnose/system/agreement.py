"""Whether the time records agree on the named effects' parameters: each record fitted alone.

A cause that explains the data has one value of its parameters for every record. A parameter that
drifts between records (the truth changed while the rig ran) or a pair of effects standing in for a
cause outside the vocabulary (an odd quadratic spring k2 |u| u fitted as a linear spring plus a cubic
one: the best pair changes with the amplitude) fits each record with its own values. The test: the
linear parameters of the named effects fitted on each record alone (the same whitened equation
error as the pooled fit, :func:`.eqfit.fit_eq`), then per parameter

    chi2 = sum_i (p_i - p_w)^2 / s_i^2,    p_w the inverse-variance weighted mean, n_records - 1 dof,

refused at the level ``LEVEL`` (Bonferroni over the parameters tested). The record-by-record stds are
those of the pooled fit's method, scaled up by the record's own misfit (a record the effects do not
fit does not claim a tight value). The play gap (fitted through the solver) is not tested here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from scipy.stats import chi2 as chi2_dist

from .eqfit import fit_eq

if TYPE_CHECKING:
    from typing import Any

    from .model import SystemModel

LEVEL = 1e-3  #: false-alarm probability of the agreement test per dataset
MIN_RECORDS = 3  #: fewer records than this: the test is not made


def record_agreement(model: SystemModel, effects: tuple[str, ...], theta: dict[str, Any]) -> dict[str, Any] | None:
    """The agreement of the records on the linear parameters of ``effects`` (``theta``: the pooled fit's
    nonlinear settings, e.g. the friction slope): ``{"agree": bool, "worst": {...}, "params": {...}}``,
    or None when fewer than MIN_RECORDS records or no linear parameter."""
    n = len(model.views)
    if n < MIN_RECORDS:
        return None
    fits = [fit_eq(model, effects, [([i], [i])], theta) for i in range(n)]
    names = [k for k in fits[0].params if k in fits[0].std and not k.endswith("friction_slope")]
    names = [k for k in names if not k.startswith("play.")]
    if not names:
        return None
    out: dict[str, Any] = {}
    for k in names:
        p = [f.params[k] for f in fits]
        s = [max(f.std[k], 1e-300) for f in fits]
        if not all(math.isfinite(v) for v in p + s):
            continue  # a record that cannot determine the parameter does not vote
        w = [1.0 / si**2 for si in s]
        mean = sum(wi * pi for wi, pi in zip(w, p)) / sum(w)
        c = sum(((pi - mean) / si) ** 2 for pi, si in zip(p, s))
        out[k] = {
            "values": p,
            "stds": s,
            "weighted_mean": mean,
            "chi2": c,
            "dof": n - 1,
            "p_value": float(chi2_dist.sf(c, n - 1)),
        }
    if not out:
        return None
    worst = min(out, key=lambda k: out[k]["p_value"])
    agree = out[worst]["p_value"] >= LEVEL / len(out)
    return {
        "agree": bool(agree),
        "level": LEVEL,
        "worst": {"param": worst, **out[worst]},
        "records": [v.name for v in model.views],
        "params": out,
    }
