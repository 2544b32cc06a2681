"""Where a held-out gap lives, and the one-sentence verdict of a system-level diagnosis.

Localisation splits the held-out chi-square excess the named effects leave (or the nominal's, when
none is named) by source: time records vs FRC points; per time record; per harmonic of the forcing
frequency; per equation (base or TMD: the whitened residual mapped back to (A_h, B_h), each divided
by its own noise std); and the frequency band of the FRC points whose residual exceeds 3 noise std.
Shares are of the positive excess (chi-square minus its dof), so noise alone gives shares of about 0.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from typing import Any

    from .shapes import SystemDiagnosisShape


Z_POINT = 3.0  #: an FRC point is in the band when its held-out residual exceeds this many noise std


def _share(d: dict) -> dict:
    tot = sum(max(v, 0.0) for v in d.values())
    return {k: (max(v, 0.0) / tot if tot > 0 else 0.0) for k, v in d.items()}


def localise(sd: SystemDiagnosisShape) -> dict:
    """Where the held-out gap left by the named effects lives (module doc)."""
    cur: Any = sd.cur if sd.chosen else None
    fit = cur.fit if cur is not None else None
    rec: dict[str, float] = {}
    harm: dict[int, float] = {}
    eq = {"base": 0.0, "tmd": 0.0}
    for i in sd.test_ids:
        v = sd.views[i]
        r = fit.resid_ho[i] if fit is not None and fit.resid_ho and fit.resid_ho[i] is not None else v.r
        H = v.X.size - 1
        rec[v.name] = float(r @ r) - r.size
        Z = np.zeros((H + 1, 2), complex)
        k0 = 2 if v.dc else 0  # an acceleration-only record has no h = 0 rows (SystemModel.whiten)
        Z[0] = r[:k0] if k0 else 0.0
        Z[1:] = (r[k0 : k0 + 2 * H] + 1j * r[k0 + 2 * H :]).reshape(H, 2)
        for h in range(0 if v.dc else 1, H + 1):
            nc = 2 if h == 0 else 4
            harm[h] = harm.get(h, 0.0) + float(np.sum(np.abs(Z[h]) ** 2)) - nc
            L = np.linalg.inv(v.W[h])
            AB = L @ Z[h]
            S = L @ L.conj().T
            for k, name in ((0, "base"), (1, "tmd")):
                eq[name] += float(abs(AB[k]) ** 2 / max(S[k, k].real, 1e-300)) - nc / 2
    out: dict[str, Any] = {
        "time_records_share": None,
        "frc_share": None,
        "equation": _share(eq),
        "records": sorted(
            (
                {"record": k, "omega": sd.views[[w.name for w in sd.views].index(k)].omega, "share": s}
                for k, s in _share(rec).items()
            ),
            key=lambda d: -d["share"],
        ),
        "harmonics": {str(h): s for h, s in sorted(_share(harm).items()) if s >= 0.01},
        "frc_band": None,
    }
    g_t = sum(max(x, 0.0) for x in rec.values())
    g_f = 0.0
    fr = sd.frc
    if fr is not None:
        pred = None
        try:
            pred = fr.predict(cur.params) if cur is not None else fr.pred0
        except Exception:  # noqa: BLE001 -- a model the solver cannot reach: no FRC localisation
            pred = None
        if pred is not None and np.all(np.isfinite(pred)):
            z = (fr.x - pred) / fr.sigma
            g_f = max(float(z @ z) - z.size, 0.0)
            hot = np.abs(z) > Z_POINT
            if hot.any():
                out["frc_band"] = {
                    "omega_min": float(fr.w[hot].min()),
                    "omega_max": float(fr.w[hot].max()),
                    "points": int(hot.sum()),
                    "max_residual_noise_units": float(np.abs(z).max()),
                    "max_relative_residual": float(np.max(np.abs((fr.x - pred) / fr.x)[hot])),
                }
    if g_t + g_f > 0:
        out["time_records_share"], out["frc_share"] = g_t / (g_t + g_f), (g_f / (g_t + g_f) if fr is not None else None)
    out["text"] = _where_text(out)
    return out


def _where_text(loc: dict[str, Any]) -> str:
    parts = []
    ts = loc["time_records_share"]
    if ts is None or ts > 0.05:
        eqs = loc["equation"]
        e = max(eqs, key=eqs.get)
        parts.append(f"the {'base' if e == 'base' else 'TMD'} equation ({100 * eqs[e]:.0f} %)")
        top = [r for r in loc["records"] if r["share"] >= 0.15][:3]
        if top:
            parts.append(
                "records "
                + ", ".join(f"{r['record']} (w = {r['omega']:.4g} rad/s, {100 * r['share']:.0f} %)" for r in top)
            )
        hs = sorted(loc["harmonics"].items(), key=lambda kv: -kv[1])[:3]
        if hs:
            parts.append("harmonics " + ", ".join(f"{h} ({100 * s:.0f} %)" for h, s in hs))
    b = loc["frc_band"]
    if b is not None and (loc["frc_share"] or 0) > 0.05:
        parts.append(
            f"the FRC between {b['omega_min']:.4g} and {b['omega_max']:.4g} rad/s "
            f"(up to {100 * b['max_relative_residual']:.2g} % of x_max, {100 * loc['frc_share']:.0f} % of the gap)"
        )
    return "; ".join(parts) if parts else "no one place (spread over records, harmonics and equations)"


def _param_text(sd: SystemDiagnosisShape, e: str, p: dict[str, float], s: dict[str, Any], units: dict[str, str]) -> str:
    return ", ".join(
        f"{k.split('.', 1)[1]} = {v:.4g} +- {s.get(k, float('nan')):.2g} {units.get(k.split('.', 1)[1], '')}"
        for k, v in p.items()
        if k.startswith(e + ".")
        and not k.endswith("friction_slope")
        and not k.endswith("delta_inertance_eff")
        and not k.endswith("signature_scale")
        and not (k.endswith("y_offset") and abs(v) < 2 * s.get(k, 0))
    )


def _disagreement(a: dict[str, Any], labels: dict[str, str], units: dict[str, str]) -> str:
    """The verdict's sentence on records that disagree on a parameter (:mod:`.system.agreement`)."""
    w = a["worst"]
    e, pn = w["param"].split(".", 1)
    vals = ", ".join(f"{v:.4g}" for v in w["values"])
    return (
        f" The records disagree on {labels.get(e, e)} ({pn} = {vals} {units.get(pn, '')} record by record; "
        f"chi2 {w['chi2']:.1f} for {w['dof']} dof, p = {w['p_value']:.1g}): a parameter that drifts between "
        "records, or a pair of effects standing in for a cause outside the vocabulary; no cause is named "
        "with confidence and the gap is left unexplained."
    )


def verdict_text(sd: SystemDiagnosisShape, labels: dict[str, str], units: dict[str, str]) -> str:
    """The printed verdict: the named causes and what they close, then -- when a structural gap
    remains -- one sentence on it and where it lives, with the best candidate as a hint."""
    p, s = sd.params()
    loc = sd.localisation
    hint = ""
    if sd.hint is not None:
        eff, sh = sd.hint
        hint = (
            " The closest candidate, "
            + " + ".join(labels.get(e, e) for e in eff)
            + (f" (closes {100 * max(sh, 0):.0f} %)" if sh is not None and math.isfinite(sh) else "")
            + ", is a hint, not a cause."
        )
    if not sd.chosen:
        if not sd.noise_ok:
            return (
                f"No structural effect: the held-out gap is within the measured noise "
                f"(chi2 {sd.chi0:.0f} for {sd.dof} dof)."
            )
        return f"A structural gap remains that none of the candidates explains; it lives in {loc['text']}.{hint}"
    parts = [f"{labels[e]} ({_param_text(sd, e, p, s, units)})" for e in sd.chosen]
    gc = sd.held_out()["gap_closed"]
    txt = (
        "Gap attributed to "
        + " + ".join(parts)
        + (f"; closes {100 * gc:.0f} % of the held-out gap." if gc is not None else ".")
    )
    a = sd.agreement
    if sd.gap_left:
        txt += (
            f" A structural gap remains that these effects do not explain ({100 * sd.unexplained_share:.0f} % "
            f"of the held-out gap); it lives in {loc['text']}."
        )
    if a is not None and not a["agree"]:
        txt += _disagreement(a, labels, units)
    return txt
