"""Transient records: the named effects' held-out stage, each record fitted alone (the agreement of
their parameters) and each record predicted from the others (held out by record).

The named set's fit on all records (``final``) is the start; the per-record and leave-one-out fits
start from it (:func:`.transient_fit.warm_start`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from .transient_effects import TEFFECTS, apply
from .transient_fit import TFit, chi2_of, fit, residual, start_update
from .transient_sim import param_variance_factor

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_sim import TView

AGREE_P = 1e-3  #: per-record parameters disagree when the agreement chi-square's p-value is below this
#: model-error floor of a per-record parameter in the agreement test, as a share of max(|mean|, its
#: scale): the measured force is the simulation's input with its own noise (errors in variables), which
#: the statistical std does not cover (measured: viscous dc = 10 N s/m on four records scatters by 0.3 %)
AGREE_FLOOR = 0.01


def params_of(effects: tuple[str, ...], theta: ndarray, std: ndarray) -> dict[str, dict[str, Any]]:
    """The parameters of a fit of ``effects`` by name: value, std, unit."""
    out, i = {}, 0
    for e in effects:
        names, units = TEFFECTS[e]
        for n, u in zip(names, units):
            out[f"{e}.{n}"] = {"value": float(theta[i]), "std": float(std[i]), "unit": u}
            i += 1
    return out


def closed(c0: float, c1: float, n: int) -> float | None:
    """The share of the excess chi-square over its dof n that c1 closes from c0 (None: no excess)."""
    return 1 - (c1 - n) / (c0 - n) if c0 > n else None


class HeldOut:
    """The held-out stage of a named set of effects on the records ``views`` (``masks``: their fit
    samples; ``final``: the set's fit on all of them; ``warm``: its :func:`.transient_fit.warm_start`;
    ``noise_parts``: record -> (white share of each channel's whitened noise, whitened input-noise
    response), as :class:`.transient.TransientDiagnosis` measures them)."""

    def __init__(
        self,
        views: list[TView],
        p_nom: ndarray,
        sc: dict[str, tuple[float, ...]],
        effects: tuple[str, ...],
        masks: list[ndarray],
        final: TFit,
        warm: dict[str, Any],
        noise_parts: dict[str, tuple[ndarray, ndarray | None]],
    ) -> None:
        self.views, self.p_nom, self.sc, self.effects = views, p_nom, sc, effects
        self.masks, self.final, self.warm, self.noise_parts = masks, final, warm, noise_parts

    def agreement(self) -> dict[str, Any]:
        """Each record alone: its parameters, and the chi-square of their agreement."""
        if len(self.views) < 2:
            return {"records": [], "p_value": None, "agree": True}
        from scipy.stats import chi2 as chi2dist

        effects = self.effects
        rows, vals, stds = [], [], []
        for v, m in zip(self.views, self.masks):
            f = fit([v], self.p_nom, effects, [m], None, self.sc, **self.warm)
            if not f.ok:
                continue
            std = f.std * np.sqrt(self._std_widening(v, m, f.theta))
            rows.append({"record": v.name, "params": params_of(effects, f.theta, std)})
            vals.append(f.theta)
            stds.append(std)
        if len(vals) < 2:
            return {"records": rows, "p_value": None, "agree": True}
        V, S = np.array(vals), np.maximum(np.array(stds), 1e-300)
        scale = np.array([s for e in effects for s in self.sc[e]], float)
        mean = (V / S**2).sum(0) / (1 / S**2).sum(0)
        S = np.sqrt(S**2 + (AGREE_FLOOR * np.maximum(np.abs(mean), scale)) ** 2)
        w = 1 / S**2
        mean = (V * w).sum(0) / w.sum(0)
        c2 = float(((V - mean) ** 2 * w).sum())
        dof = V.size - V.shape[1]
        p = float(chi2dist.sf(c2, dof))
        return {"records": rows, "chi2": c2, "dof": dof, "p_value": p, "agree": p >= AGREE_P}

    def _std_widening(self, v: TView, m: ndarray, theta: ndarray) -> ndarray:
        """Per parameter of a fit of record v alone: how much its variance exceeds the one
        ``(J^T J)^-1`` states, which assumes white noise; the force's noise drives the simulation and
        reaches the residual correlated in time and across channels (the sandwich covariance with the
        Welch spectra of the chi-square's spread, :func:`param_variance_factor`; its Jacobian by
        forward differences, one simulation per parameter). At least 1; 1 for a free decay."""
        white, y_w = self.noise_parts.get(v.name, (None, None))
        if white is None or y_w is None:
            return np.ones(theta.size)
        effects = self.effects
        mdl0 = apply(self.p_nom, effects, theta)
        e0 = None if isinstance(mdl0, str) else residual(v, mdl0, m)
        if e0 is None:
            return np.ones(theta.size)
        scale = np.array([s for e in effects for s in self.sc[e]], float)
        J = np.zeros((int(m.sum()), int(v.has.sum()), theta.size))
        for j in range(theta.size):
            for sgn in (1.0, -1.0):
                h = sgn * 1e-3 * max(abs(float(theta[j])), float(scale[j]))
                th = theta.copy()
                th[j] += h
                mdl = apply(self.p_nom, effects, th)
                e1 = None if isinstance(mdl, str) else residual(v, mdl, m)
                if e1 is not None:
                    J[:, :, j] = ((e1 - e0) / h)[m][:, v.has]
                    break
        return np.maximum(param_variance_factor(J, white, y_w), 1.0)

    def by_record(self) -> list[dict[str, Any]]:
        """Each record predicted from the others (its start state fitted on itself)."""
        if len(self.views) < 2:
            return []
        effects, allm = self.effects, self.masks
        nom = fit(self.views, self.p_nom, (), allm, None, self.sc)
        out = []
        for i, v in enumerate(self.views):
            others = [u for j, u in enumerate(self.views) if j != i]
            om = [m for j, m in enumerate(allm) if j != i]
            f = fit(others, self.p_nom, effects, om, None, self.sc, **self.warm)
            if not f.ok:
                continue
            mdl = apply(self.p_nom, effects, f.theta)
            if isinstance(mdl, str):
                continue

            z_saved = v.z0.copy()
            for _ in range(2):  # the held-out record's start state under the fitted model (not a parameter)
                start_update(v, mdl, allm[i])
            e = residual(v, mdl, allm[i])
            v.z0 = z_saved
            if e is None:
                continue
            c1, n1 = chi2_of([v], [e], [allm[i]])
            c0, _ = chi2_of([v], [nom.resid[i]], [allm[i]])
            out.append(
                {"record": v.name, "chi2_before": c0, "chi2_after": c1, "dof": n1, "gap_closed": closed(c0, c1, n1)}
            )
        return out
