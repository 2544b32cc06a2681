"""System-level time records: the equation error of both equations of motion, per harmonic,
whitened by the noise propagated from every channel of every record.

For a periodic record at w with fused displacement series X_h, Y_h (see :mod:`harmonic`), the
measured force series F_h and the nominal link force L_h (the physics kernels'
``static_link_force`` plus the ideal inerter I (xdd - ydd), evaluated on one period and projected on
the harmonics), the two residuals

    A_h = F_h - (K + i C h w - M (h w)^2) X_h - L_h        base:  M xdd + C xd + K x + L = force
    B_h = -m (h w)^2 Y_h - L_h                             TMD:   m ydd = L

vanish for the nominal model up to noise. Their 2x2 noise covariance per harmonic follows from the
variances of X_h, Y_h, F_h (the linear part of the model); residuals and regressors are whitened
with it, so a chi-square is in units of the measured noise of that record and channel.

Every candidate effect adds ``offset + Phi beta`` to the residual model (Phi: one column per
linear parameter, for A and for B). The nominal's own parameters are candidates too (true =
nominal + delta): base mass ``(-(h w)^2 X, 0)``, base stiffness ``(X, 0)``, base damping
``(i h w X, 0)``, TMD spring stiffness ``(X - Y, X - Y)``. Parameters are fitted by weighted least squares; held-out
evidence is leave-one-record-out (or the dataset's roles): the chi-square of each record with the
parameters fitted on the others.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ..._jit import njit
from ...physics.kernels import friction_force, static_link_force
from ...physics.params import N_PARAMS, BaseParams, P_k3, TMDParams, pack
from ...solvers.harmonic import PERIODIC_R2, fit_series, fuse, grid_coef, grid_values
from .effects import EQ_EFFECTS, VOCAB

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray

    from ...physics.params import BaseParams, TMDParams
    from ..data import Dataset

H_EQ = 12  #: harmonics used in the equation error
N_GRID = 256  #: samples per period for nonlinear force laws
SLOPES = (1e2, 1e3, 1e4, 1e5, 1e6)  #: friction slopes [s/m] tried (kernels' regularisation)


@njit(cache=True)
def link_force_grid(x: np.ndarray, xd: np.ndarray, y: np.ndarray, yd: np.ndarray, p: np.ndarray) -> np.ndarray:
    out = np.empty(x.shape[0])
    for i in range(x.shape[0]):
        out[i] = static_link_force(x[i], xd[i], y[i], yd[i], p)
    return out


@njit(cache=True)
def friction_grid(v: np.ndarray, s: float) -> np.ndarray:
    out = np.empty(v.shape[0])
    for i in range(v.shape[0]):
        out[i] = friction_force(v[i], 1.0, s)
    return out


@dataclass
class RecView:
    name: str
    omega: float
    amplitude: float
    series: Any
    X: np.ndarray
    vX: np.ndarray
    Y: np.ndarray
    vY: np.ndarray
    F: np.ndarray
    vF: np.ndarray
    grid: dict = field(default_factory=dict)  #: x, xd, xdd, y, yd, ydd on one period
    W: np.ndarray = field(default_factory=lambda: np.empty((0, 2, 2)))  #: whitening matrices per harmonic (H+1, 2, 2)
    r: np.ndarray = field(
        default_factory=lambda: np.empty(0)
    )  #: whitened nominal residual, real vector (set by SystemModel)
    role: str | None = None
    dt: float = 1e-3  #: sampling interval [s]
    spike: dict = field(default_factory=dict)
    dc: bool = True  #: the mean displacements are measured (x and y); False: acceleration-only, h = 0 unobservable
    acq: dict = field(default_factory=dict)  #: the dataset's acquisition chain (channel -> acquisition.Chain)


def _nominal_objects(ds: Dataset) -> tuple[BaseParams, TMDParams]:
    return BaseParams(**ds.nominal["base"]), TMDParams(**ds.nominal["tmd"])


def record_views(ds: Dataset) -> tuple[list[RecView], list[tuple[str, str]]]:
    """Periodic system time records as :class:`RecView`; returns (views, flagged) where flagged lists
    (record name, reason) for records left out of the harmonic analysis.

    The dataset's acquisition chain (``ds.acquisition``, :mod:`acquisition`) is divided out of every
    harmonic of the declared channels. A record without the displacement pair x, y (acceleration-only)
    gets its displacements h >= 1 from xdd, ydd; its mean is unobservable (``dc = False``): the
    h = 0 equation errors are left out and the means are put at the nominal static equilibrium with
    no relative offset (X_0 = Y_0 = F_0 / K), about which the link force is evaluated."""
    from ..acquisition import correct_series

    chains = getattr(ds, "acquisition", None) or {}
    views, flagged = [], []
    for rec in ds.records:
        if rec.kind != "time":
            continue
        c = rec.columns
        if not ({"y", "ydd"} & set(c)):
            flagged.append((rec.name, "no 'y' or 'ydd' column: the TMD equation needs the TMD motion"))
            continue
        if not ({"x", "xdd"} & set(c)):
            flagged.append((rec.name, "no 'x' or 'xdd' column: the base equation needs the base motion"))
            continue
        if rec.omega is None or not rec.omega > 0:
            flagged.append((rec.name, "no forcing frequency (not periodic)"))
            continue
        chans = {k: c[k] for k in ("force", "x", "y", "xdd", "ydd", "xd", "yd") if k in c}
        s = fit_series(c["t"], chans, rec.omega)
        correct_series(s, chains)
        mo = "x" if "x" in c else "xdd"
        if not s.periodic or min(s.r2["force"], s.r2[mo]) < PERIODIC_R2:
            flagged.append(
                (
                    rec.name,
                    f"not periodic at w = {rec.omega:.4g} rad/s (harmonic series explains "
                    f"{100 * min(s.r2['force'], s.r2[mo]):.0f} % of force/{mo}): no harmonic analysis",
                )
            )
            continue
        H = min(H_EQ, s.H)
        X, vX = fuse(s, "x", "xdd" if "xdd" in c else None, H)
        Y, vY = fuse(s, "y", "ydd" if "ydd" in c else None, H)
        F, vF = s.coef["force"][: H + 1], s.var["force"][: H + 1]
        dc = "x" in c and "y" in c
        if not dc:  # nominal static equilibrium, no preload: the mean is not measured
            X[0] = Y[0] = F[0].real / BaseParams(**ds.nominal["base"]).stiffness
            vX[0] = vY[0] = 0.0
        amp = float(np.abs(F[1])) if rec.amplitude is None else rec.amplitude
        v = RecView(
            rec.name,
            rec.omega,
            amp,
            s,
            X,
            vX,
            Y,
            vY,
            F,
            vF,
            role=rec.role,
            dt=float((c["t"][-1] - c["t"][0]) / (len(c["t"]) - 1)),
            dc=dc,
            acq=chains,
        )
        for nm, C in (("x", X), ("y", Y)):
            for k, suf in ((0, ""), (1, "d"), (2, "dd")):
                v.grid[nm + suf] = grid_values(C, rec.omega, N_GRID, k)
        if "ydd" in s.resid:
            e = s.resid["ydd"]
            dof = max(s.n - (2 * s.H + 1), 1)
            ms = float(e @ e) / dof
            sr = s.noise_robust["ydd"]
            v.spike = {
                "ms": ms,
                "sigma": sr,
                "n": s.n,
                "ratio": ms / max(sr * sr, 1e-300),
                "excess": max(ms - sr * sr, 0.0),
            }
            if "xdd" in s.resid:
                ex = s.resid["xdd"]
                v.spike["xy_corr"] = float(np.corrcoef(ex, e)[0, 1]) if np.std(ex) > 0 and np.std(e) > 0 else 0.0
        views.append(v)
    return views, flagged


class SystemModel:
    """Nominal residuals, noise whitening and candidate regressors for a set of RecViews."""

    def __init__(self, ds: Dataset, views: list[RecView]) -> None:
        self.base, self.tmd = _nominal_objects(ds)
        self.views = views
        b, t = self.base, self.tmd
        self.p = pack(b, t, 0.0)
        self.play_signature: dict[str, Any] = {}
        self.friction_signature: dict[str, Any] = {}  #: record -> (A_h, B_h) per newton of friction, from the solver
        #: a nominal with dry friction (and no play): its law evaluated along a record's harmonic series
        #: (the stick phases truncated) leaves an equation error even on the nominal's own motion, so
        #: that error (:meth:`own_error`) is taken out of every record's nominal residual
        self.friction_nominal = t.friction_force > 0.0 and not (t.inerter.name == "PLAY" and t.play_gap > 0.0)
        for v in views:
            H = v.X.size - 1
            hw = np.arange(H + 1) * v.omega
            A, B = self.residuals(v, v.X, v.Y, v.F, v.grid)
            if self.friction_nominal:  # the nominal's equation error on its own orbit: the series' truncation
                A0, B0 = self.own_error(v)
                A, B = A - A0, B - B0
            zl = t.stiffness + 1j * t.damping * hw - t.inertance * hw**2  # linear link: dL/dX = -dL/dY
            zb = b.stiffness + 1j * b.damping * hw - b.mass * hw**2
            J = np.zeros((H + 1, 2, 3), complex)
            J[:, 0, 0], J[:, 0, 1], J[:, 0, 2] = -zb - zl, zl, 1.0
            J[:, 1, 0], J[:, 1, 1] = -zl, -t.mass * hw**2 + zl
            var = np.stack([v.vX, v.vY, v.vF], axis=1)
            S = np.einsum("hik,hk,hjk->hij", J, var, J.conj())
            W = np.empty_like(S)
            for h in range(H + 1):
                Sh = S[h] + np.eye(2) * 1e-30
                W[h] = np.linalg.inv(np.linalg.cholesky(Sh))
            v.W = W
            v.r = self.whiten(v, A, B)

    def residuals(
        self, v: RecView, X: ndarray, Y: ndarray, F: ndarray, grid: dict[str, ndarray] | None = None
    ) -> tuple[ndarray, ndarray]:
        """Equation errors (A_h, B_h) of the nominal model for displacement series X, Y and force F."""
        b, t = self.base, self.tmd
        H = X.size - 1
        hw = np.arange(H + 1) * v.omega
        if grid is None:
            grid = {
                nm + suf: grid_values(C, v.omega, N_GRID, k)
                for nm, C in (("x", X), ("y", Y))
                for k, suf in ((0, ""), (1, "d"), (2, "dd"))
            }
        Fs = link_force_grid(grid["x"], grid["xd"], grid["y"], grid["yd"], self.p)
        L = grid_coef(Fs, H) + t.inertance * grid_coef(grid["xdd"] - grid["ydd"], H)
        zb = b.stiffness + 1j * b.damping * hw - b.mass * hw**2
        return F - zb * X - L, -t.mass * hw**2 * Y - L

    def own_error(self, v: RecView) -> tuple[ndarray, ndarray]:
        """Equation errors (A_h, B_h) the nominal leaves on its own periodic steady state at the
        record's frequency and force (:func:`steady_signature` of the nominal): zero for a smooth law,
        the truncation of the stick-slip for dry friction. Zero when the solver finds no steady state."""
        from ...solvers.monolithic import SolverError

        try:
            return steady_signature(self, v, self.tmd)
        except (SolverError, ValueError, FloatingPointError):
            z = np.zeros(v.X.size, complex)
            return z, z

    def whiten(self, v: RecView, A: ndarray, B: ndarray) -> ndarray:
        """Real vector of whitened residual components (h = 0: real parts only)."""
        Z = np.einsum("hij,hj->hi", v.W, np.stack([A, B], axis=1))
        if not v.dc:  # acceleration-only record: the mean (h = 0) is not observed
            return np.concatenate([Z[1:].real.ravel(), Z[1:].imag.ravel()])
        return np.concatenate([Z[0].real, Z[1:].real.ravel(), Z[1:].imag.ravel()])

    # --- candidate regressors: list of (A_h, B_h) complex pairs, one per linear parameter ----------
    def columns(self, effect: str, v: RecView, theta: Sequence[float] = ()) -> list[tuple[ndarray, ndarray]]:
        t, b = self.tmd, self.base
        H = v.X.size - 1
        hw = np.arange(H + 1) * v.omega
        D = v.X - v.Y
        Vr = 1j * hw * D
        a = -(hw**2) * D
        z = np.zeros(H + 1, complex)
        if effect == "viscous":
            return [(Vr, Vr)]
        if effect == "friction":
            if v.name in self.friction_signature:  # simulated with the solver (stick-slip included)
                return [self.friction_signature[v.name]]
            f = grid_coef(friction_grid(v.grid["xd"] - v.grid["yd"], float(theta[0])), H)
            return [(f, f)]
        if effect == "cubic":  # the kernels' spring force with k = 0, k3 = 1
            c3 = grid_coef(self.unit_link_force(v, P_k3), H)
            return [(c3, c3)]
        if effect == "mass_split":
            return [(a, -(hw**2) * v.X)]
        if effect == "force_error":
            return [(v.F, z)]
        if effect == "sensor_offset":
            e0 = z.copy()
            e0[0] = 1.0
            return [(-(b.stiffness + t.stiffness) * e0, -t.stiffness * e0), (t.stiffness * e0, t.stiffness * e0)]
        if effect == "play":  # the inertance the gear loses on average while it rattles
            return [(a, a)]
        # the nominal's own parameters: true = nominal + delta; the nominal's residual is the
        # force the delta adds (base equation: (dK + i h w dC - dM (h w)^2) X; link: dk (x - y))
        if effect == "base_mass":
            return [(-(hw**2) * v.X, z)]
        if effect == "base_stiffness":
            return [(v.X.copy(), z)]
        if effect == "base_damping":
            return [(1j * hw * v.X, z)]
        if effect == "tmd_stiffness":
            return [(D, D)]
        raise KeyError(effect)

    def unit_link_force(self, v: RecView, index: int) -> ndarray:
        """The kernels' static link force over one period with only parameter ``index`` = 1."""
        p = np.zeros(N_PARAMS)
        p[index] = 1.0
        g = v.grid
        return link_force_grid(g["x"], g["xd"], g["y"], g["yd"], p)

    def offset(self, effect: str, v: RecView) -> tuple[ndarray, ndarray] | None:
        """Offset added to the residual model by a candidate that replaces part of the nominal."""
        if effect == "play" and v.name in self.play_signature:
            return self.play_signature[v.name]
        if effect == "friction" and self.tmd.friction_force > 0:
            vr = v.grid["xd"] - v.grid["yd"]
            f = grid_coef(friction_grid(vr, self.tmd.friction_slope), v.X.size - 1) * self.tmd.friction_force
            return -f, -f
        return None

    def design(self, effects: tuple[str, ...], thetas: dict[str, Any]) -> list[tuple[ndarray, ndarray]]:
        """Per record: (whitened offset vector, whitened design matrix)."""
        out = []
        for v in self.views:
            cols, off = [], np.zeros_like(v.r)
            for e in effects:
                for A, B in self.columns(e, v, thetas.get(e, ())):
                    cols.append(self.whiten(v, A, B))
                o = self.offset(e, v)
                if o is not None:
                    off = off + self.whiten(v, *o)
            out.append((off, np.column_stack(cols)))
        return out


#: the linear parameters each candidate of the steady fits adds (the vocabulary's; the friction slope
#: is held on the grid SLOPES): play enters through its rattle signature (:func:`steady_signature`),
#: an effective inertance its gap is then refitted from (:mod:`.playfit`)
EFFECT_PARAMS = {**{e: VOCAB[e].linear_params for e in EQ_EFFECTS}, "play": ("delta_inertance_eff",)}
SIGN = {"force_error": -1.0}  # beta = -alpha


def steady_signature(model: SystemModel, v: RecView, tmd: TMDParams) -> tuple:
    """Equation errors (A_h, B_h) the nominal model leaves on the periodic steady state of ``tmd``
    simulated by the project's solver at the record's frequency and force amplitude, rotated into
    the phase of the measured force. For a link-force effect this is the effect's force along the
    simulated motion (e.g. dry friction with its stick phases)."""
    from dataclasses import replace

    from ...models.solve import periodic_time_series

    base = replace(model.base, force_amplitude=v.amplitude)
    t, z, _ = periodic_time_series(base, tmd, v.omega, 1, N_GRID)
    H = v.X.size - 1
    X, Y = grid_coef(z[:, 0], H), grid_coef(z[:, 2], H)
    F = np.zeros(H + 1, complex)
    F[1] = v.amplitude
    A, B = model.residuals(v, X, Y, F)
    rot = np.exp(1j * np.arange(H + 1) * np.angle(v.F[1]))
    return A * rot, B * rot
