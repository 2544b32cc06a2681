"""Play in the inerter gear at system level: the rattle signature and its fit through the
project's play model.

Signature. A gear with play rattles: the chain force P has a non-periodic part (contact spikes)
that acts on the base and the TMD with opposite signs, so the parts of the accelerations that the
harmonic series of the steady state cannot explain are anti-correlated:
``M xdd_np = -(P_np + ...)``, ``m ydd_np = P_np + ...``. Measurement noise is independent per
channel, so the covariance of the two residuals is noise-free:

    S = -M m cov(xdd_np, ydd_np)   [N^2]    (the rattle power of the chain force)

is zero without rattle (its noise std is M m s_x s_y / sqrt(n)) and grows with the gap.

Fit. The same statistic is computed on records simulated by the project's solver
(``solvers.monolithic``, inerter = play, ki and ci of the nominal TMD, steady state from the
companion orbit) at the measured frequency, force amplitude, sampling rate and length, read through
the accelerometers' declared anti-alias filters when there are any, for a short geometric ladder of
gaps; the gap is where the measured S of the training records falls on the
simulated S(eps) curves (log-log interpolation). Held out: the S of each record predicted from the
gap fitted on the others.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from ...solvers.harmonic import fit_series

if TYPE_CHECKING:
    from typing import Any

    from numpy import float64

    from ...physics.params import BaseParams, TMDParams
    from ...solvers.harmonic import Series
    from .model import RecView, SystemModel

Z_GATE = 6.0  #: rattle statistic (in noise std) above which a record shows contact spikes
EPS_LADDER = (1e-5, 1e-4, 1e-3)  #: gaps [m] of the first simulations
SIGNATURE_PERIODS = 8  #: the play signature is taken over this many times the record's periods
RTOL = 1e-6  #: integrator tolerance of the fitting simulations (the rattle statistic needs no more)
SETTLE = 4  #: periods simulated from the companion orbit before the record starts
DENSE_HZ = 20000.0  #: rate [Hz] at which a record is simulated before a declared filter reads it


def rattle_stat(s: Series, M: float, m: float) -> tuple[float, float]:
    """(S [N^2], z) of a fitted Series with xdd and ydd residuals."""
    ex, ey = s.resid.get("xdd"), s.resid.get("ydd")
    if ex is None or ey is None:
        return 0.0, 0.0
    n = ex.size
    c = float(np.mean((ex - ex.mean()) * (ey - ey.mean())))
    sd = float(np.std(ex) * np.std(ey)) / math.sqrt(n)
    return -M * m * c, (-c / sd if sd > 0 else 0.0)


def filtered(chains: dict | None) -> bool:
    """Whether an accelerometer of the chain has a declared analog filter (which shapes the spikes)."""
    return any(getattr((chains or {}).get(ch), "type", None) is not None for ch in ("xdd", "ydd"))


def simulated_stat(
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    force: float,
    eps: float,
    dt: float,
    n_periods: int,
    chains: dict | None = None,
    H: int | None = None,
) -> tuple[float, Series]:
    """(S, Series) of a record simulated with the gap ``eps``, sampled every ``dt``. With ``chains``
    declaring a filter on an accelerometer, the record is read as the rig reads it: simulated at a
    dense rate (>= DENSE_HZ), passed through the declared chains (:func:`acquisition.rig_samples`) and
    decimated to ``dt``, one period more than asked, whose start (the filter's transient) is dropped:
    the rattle statistic of filtered contact spikes is far smaller than of the spikes sampled raw.
    ``H``: fit only the harmonics up to H (the signature needs no more; a long record's full basis
    takes hundreds of MB)."""
    from ...physics.params import InerterModel
    from ..acquisition import rig_samples
    from .bench import steady_record

    b = replace(base, force_amplitude=force)
    t = replace(tmd, inerter=InerterModel.PLAY, play_gap=float(eps))
    if not filtered(chains):
        tt, z, acc, _ = steady_record(b, t, omega, n_periods, fs=1.0 / dt, settle_periods=SETTLE, rtol=RTOL)
        sig = {"x": z[:, 0], "y": z[:, 2], "xdd": acc[:, 0], "ydd": acc[:, 1]}
    else:
        k = max(1, math.ceil(DENSE_HZ * dt))
        td, z, acc, _ = steady_record(b, t, omega, n_periods + 1, fs=k / dt, settle_periods=SETTLE, rtol=RTOL)
        dense = {"x": z[:, 0], "y": z[:, 2], "xdd": acc[:, 0], "ydd": acc[:, 1]}
        sig = rig_samples(chains or {}, td, dense, step=k)
        tt = td[::k]
        drop = math.ceil(2 * math.pi / omega / dt)
        tt, sig = tt[drop:], {ch: u[drop:] for ch, u in sig.items()}
    s = fit_series(tt, sig, omega, H)
    return max(rattle_stat(s, base.mass, tmd.mass)[0], 1e-30), s


class PlayFit:
    """Gap of the inerter gear from the rattle statistic of the records (module doc)."""

    def __init__(self, base: BaseParams, tmd: TMDParams, views: list[RecView]) -> None:
        self.base, self.tmd, self.views = base, tmd, views
        self.S, self.z = [], []
        for v in views:
            S, z = rattle_stat(v.series, base.mass, tmd.mass)
            self.S.append(S)
            self.z.append(z)
        self.curves: list[dict[float, float]] = [dict() for _ in views]
        self.sims: list[dict[float, Any]] = [dict() for _ in views]
        self.n_sim = 0

    @property
    def indicated(self) -> bool:
        """Contact spikes in the records: the rattle statistic beyond Z_GATE in at least half of them."""
        z = np.array(self.z)
        return bool(np.sum(z > Z_GATE) >= max(1, math.ceil(0.5 * z.size)))

    def _sim(self, i: int, eps: float) -> float:
        c = self.curves[i]
        if eps not in c:
            v = self.views[i]
            nper = max(2, int(round(v.series.n * v.dt * v.omega / (2 * math.pi))))
            c[eps], self.sims[i][eps] = simulated_stat(
                self.base, self.tmd, v.omega, v.amplitude, eps, v.dt, nper, chains=v.acq
            )
            self.n_sim += 1
        return c[eps]

    def _predict(self, i: int, eps: float | float64) -> float:
        c = self.curves[i]
        e = np.array(sorted(c))
        S = np.array([c[k] for k in e])
        return float(np.exp(np.interp(math.log(eps), np.log(e), np.log(S))))

    def _best(self, ids: list[int]) -> float:
        grid = np.exp(np.linspace(math.log(EPS_LADDER[0]), math.log(EPS_LADDER[-1]), 400))
        cost = [sum((math.log(max(self.S[i], 1e-30)) - math.log(self._predict(i, g))) ** 2 for i in ids) for g in grid]
        return float(grid[int(np.argmin(cost))])

    def fit(self, train_ids: list[int], folds: list[tuple[list[int], list[int]]]) -> PlayFit:
        """Gap fitted on train_ids (simulations on every record, for the held-out prediction)."""
        for i in range(len(self.views)):
            for e in EPS_LADDER:
                self._sim(i, e)
        eps = self._best(train_ids)
        for i in range(len(self.views)):  # refine the curves next to the estimate
            self._sim(i, eps)
        self.eps = self._best(train_ids)
        # held out: predicted S of each test record from the gap fitted on its training records
        before, after = 0.0, 0.0
        self.ho = []
        for tr, te in folds:
            e = self._best(tr)
            for i in te:
                pred = self._predict(i, e)
                before += self.S[i]
                after += abs(self.S[i] - pred)
                self.ho.append({"record": self.views[i].name, "S_measured": self.S[i], "S_predicted": pred, "gap": e})
        self.closed = 1.0 - after / before if before > 0 else float("nan")
        logs = [math.log(max(self.S[i], 1e-30)) - math.log(self._predict(i, self.eps)) for i in train_ids]
        # uncertainty: the log-scatter of the records mapped through the local slope of S(eps)
        c = self.curves[train_ids[0]]
        eg = np.array(sorted(c))
        S = np.log([c[k] for k in eg])
        k = int(np.clip(np.searchsorted(eg, self.eps), 1, eg.size - 1))
        slope = (S[k] - S[k - 1]) / math.log(eg[k] / eg[k - 1]) if eg[k] != eg[k - 1] else 1.0
        scat = float(np.std(logs)) / math.sqrt(max(len(logs) - 1, 1)) if len(logs) > 1 else 0.3
        self.std = self.eps * scat / max(abs(slope), 1e-3)
        return self

    def signature(self, model: SystemModel, eps: float | None = None) -> dict[str, Any]:
        """Per record, the equation error (A_h, B_h) the nominal model leaves on the record simulated
        with the fitted gap (the periodic part of the rattling chain force minus I a), in the phase
        of the measured force: the play candidate's prediction for the harmonic residuals."""
        from ...solvers.harmonic import fuse

        out = {}
        for v in self.views:
            # a longer run than the record: the periodic part of a chaotic rattle scatters less
            nper = SIGNATURE_PERIODS * max(2, int(round(v.series.n * v.dt * v.omega / (2 * math.pi))))
            H = v.X.size - 1
            _, s = simulated_stat(
                self.base, self.tmd, v.omega, v.amplitude, self.eps if eps is None else eps, v.dt, nper, H=H
            )
            self.n_sim += 1
            X, _ = fuse(s, "x", None, H)
            Y, _ = fuse(s, "y", None, H)
            F = np.zeros(H + 1, complex)
            F[1] = v.amplitude
            A, B = model.residuals(v, X, Y, F)
            rot = np.exp(1j * np.arange(H + 1) * np.angle(v.F[1]))
            out[v.name] = (A * rot, B * rot)
        return out
