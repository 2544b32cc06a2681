"""The linear frame + TMD(I) of a frame nominal and its exact simulation on a record's samples.

Degrees of freedom: the storeys' displacements x_1..x_n (1 = lowest, absolute) and the TMD's y. With
the matrices of :mod:`pyfmu_wrapper.physics.frame` (mass M plus the inerter's inertance matrix B,
stiffness K, damping C; the TMD's spring and damper between its storey s and y, the ideal inerter I
between y and its terminal j, the ground when j = 0) the motion under the force F(t) on storey L is

    (M + B) a = -K x - C v + e_L F,

linear in the state; the accelerations have the direct term (M + B)^-1 e_L F. Friction, play and a
cubic spring are not part of this model (the TMD's play chain is taken as an ideal inerter).

Each record is simulated exactly for a force linear between its samples (first-order hold): the plant
and the declared analog anti-alias filters of its channels (:meth:`pyfmu_wrapper.diagnose.acquisition.
Chain.state_space`) form one linear system, diagonalised, each mode stepped as
z+ = e^(lambda h) z + b0 u_k + b1 u_k+1; a declared delay shifts the sampled channel. A filter of
the force channel equal to a response channel's commutes with the linear plant: the measured force
then drives the model and that channel needs no filter of its own.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..._jit import njit

if TYPE_CHECKING:
    from numpy import ndarray

    from ..acquisition import Chain


@dataclass(frozen=True)
class FrameModel:
    """The linear frame + TMD(I): per-storey masses, stiffnesses, dampings (storey 1 first), the loaded
    storey, the TMD (m, k, c, I) on storey ``storey`` with its inerter to ``inerter_to`` (0: ground)."""

    masses: tuple[float, ...]
    stiffnesses: tuple[float, ...]
    dampings: tuple[float, ...]
    force_storey: int
    mass: float
    stiffness: float
    damping: float
    inertance: float
    storey: int
    inerter_to: int

    @classmethod
    def from_nominal(cls, nominal: dict[str, Any]) -> FrameModel:
        """From a normalised frame nominal (:func:`pyfmu_wrapper.diagnose.data.normalise_frame_nominal`)."""
        from ...physics.params import InerterModel, TMDParams

        fr, td = nominal["frame"], dict(nominal["tmd"])
        s, j = int(td.pop("storey")), int(td.pop("inerter_to"))
        t = TMDParams(**td)
        inert = t.inertance if t.inerter != InerterModel.NONE else 0.0
        return cls(
            tuple(map(float, fr["mass"])),
            tuple(map(float, fr["stiffness"])),
            tuple(map(float, fr["damping"])),
            int(fr["force_storey"]),
            float(t.mass),
            float(t.stiffness),
            float(t.damping),
            float(inert),
            s,
            j,
        )

    @property
    def n(self) -> int:
        return len(self.masses)

    def value(self, effect: str, where: Any = None) -> float:
        """The nominal value an effect's parameter changes (a storey's row, or the TMD's)."""
        if effect.startswith("storey_"):
            vals = {"storey_mass": self.masses, "storey_stiffness": self.stiffnesses, "storey_damping": self.dampings}
            return float(vals[effect][int(where) - 1])
        return float(getattr(self, TMD_FIELD[effect]))

    def changed(self, deltas: dict[tuple[str, Any], float]) -> FrameModel:
        """This model with the structural effects ``deltas`` ((effect, storey or None) -> change) added;
        measurement effects (gains) are ignored here."""
        per = {
            "storey_mass": list(self.masses),
            "storey_stiffness": list(self.stiffnesses),
            "storey_damping": list(self.dampings),
        }
        kw: dict[str, Any] = {}
        for (e, where), d in deltas.items():
            if e in per:
                per[e][int(where) - 1] += float(d)
            elif e in TMD_FIELD:
                kw[TMD_FIELD[e]] = kw.get(TMD_FIELD[e], getattr(self, TMD_FIELD[e])) + float(d)
        return dataclasses.replace(
            self,
            masses=tuple(per["storey_mass"]),
            stiffnesses=tuple(per["storey_stiffness"]),
            dampings=tuple(per["storey_damping"]),
            **kw,
        )

    def physical(self) -> str:
        """'' when every parameter is physical, else what is not."""
        for name, vals in (("mass", self.masses), ("stiffness", self.stiffnesses)):
            for i, v in enumerate(vals):
                if not v > 0:
                    return f"storey {i + 1} {name} {v:.4g} <= 0"
        for i, v in enumerate(self.dampings):
            if v < 0:
                return f"storey {i + 1} damping {v:.4g} < 0"
        if not self.mass + self.inertance > 0 or self.mass < 0:
            return f"TMD mass {self.mass:.4g} kg"
        for name in ("stiffness", "damping", "inertance"):
            if getattr(self, name) < 0:
                return f"TMD {name} {getattr(self, name):.4g} < 0"
        return ""

    def matrices(self) -> tuple[ndarray, ndarray, ndarray, ndarray]:
        """(M + B, C, K, e): mass with the inerter's inertance, damping, stiffness ((n+1) x (n+1), the
        TMD last) and the force's influence vector."""
        n = self.n
        N = n + 1
        M, C, K, e = np.zeros((N, N)), np.zeros((N, N)), np.zeros((N, N)), np.zeros(N)
        M[np.arange(n), np.arange(n)] = self.masses
        M[n, n] = self.mass
        for i in range(n):  # storey i+1 to the storey below (the ground for i = 0)
            for mat, v in ((K, self.stiffnesses[i]), (C, self.dampings[i])):
                mat[i, i] += v
                if i > 0:
                    mat[i - 1, i - 1] += v
                    mat[i, i - 1] -= v
                    mat[i - 1, i] -= v
        s = self.storey - 1
        for mat, v in ((K, self.stiffness), (C, self.damping)):
            mat[s, s] += v
            mat[n, n] += v
            mat[s, n] -= v
            mat[n, s] -= v
        M[n, n] += self.inertance
        if self.inerter_to > 0:
            j = self.inerter_to - 1
            M[j, j] += self.inertance
            M[j, n] -= self.inertance
            M[n, j] -= self.inertance
        e[self.force_storey - 1] = 1.0
        return M, C, K, e

    def modes_hz(self) -> list[float]:
        """The undamped natural frequencies [Hz], ascending."""
        M, _, K, _ = self.matrices()
        w2 = np.linalg.eigvals(np.linalg.solve(M, K)).real
        return sorted(math.sqrt(max(float(v), 0.0)) / (2 * math.pi) for v in w2)

    def friction_input(self) -> tuple[ndarray, ndarray]:
        """(Bq, cv): the state's rate per unit friction force q in the TMD link (q pushes the TMD's storey
        in -x and the TMD in +y, as the kernels' link force), and the row giving the link's relative
        velocity xd_s - yd from the state."""
        M, _, _, _ = self.matrices()
        N = self.n + 1
        g = np.zeros(N)
        g[self.storey - 1], g[self.n] = -1.0, 1.0
        Bq = np.concatenate([np.zeros(N), np.linalg.solve(M, g)])
        cv = np.zeros(2 * N)
        cv[N + self.storey - 1], cv[N + self.n] = 1.0, -1.0
        return Bq, cv

    def state_space(self, channels: list[str]) -> tuple[ndarray, ndarray, ndarray, ndarray]:
        """(A, B, Cy, Dy) of state [x; v] (storeys 1..n, TMD), input F, outputs ``channels``
        (``x<i>``, ``x<i>dd``, ``y``, ``ydd``)."""
        M, C, K, e = self.matrices()
        N = self.n + 1
        Mi = np.linalg.inv(M)
        A = np.zeros((2 * N, 2 * N))
        A[:N, N:] = np.eye(N)
        A[N:, :N] = -Mi @ K
        A[N:, N:] = -Mi @ C
        B = np.concatenate([np.zeros(N), Mi @ e])
        Cy = np.zeros((len(channels), 2 * N))
        Dy = np.zeros(len(channels))
        for r, ch in enumerate(channels):
            dof, acc = channel_dof(ch, self.n)
            if acc:
                Cy[r] = A[N + dof]
                Dy[r] = B[N + dof]
            else:
                Cy[r, dof] = 1.0
        return A, B, Cy, Dy


#: the TMD's field each TMD effect changes
TMD_FIELD = {"tmd_mass": "mass", "tmd_stiffness": "stiffness", "viscous": "damping", "inertance": "inertance"}


def channel_dof(ch: str, n: int) -> tuple[int, bool]:
    """(degree of freedom, is an acceleration) of a record column (``x3dd`` -> (2, True), ``y`` -> (n, False))."""
    if ch in ("y", "ydd"):
        return n, ch == "ydd"
    acc = ch.endswith("dd")
    return int(ch[1:].removesuffix("dd")) - 1, acc


def _same_filter(a: Chain | None, b: Chain | None) -> bool:
    if a is None or b is None or a.type is None or b.type is None:
        return False
    return (a.type, a.order, a.cutoff_hz) == (b.type, b.order, b.cutoff_hz)


@dataclass
class Simulator:
    """The exact sampled simulation of one record's channels under a model (module doc)."""

    channels: list[str]
    chains: dict
    h: float
    #: steps per sample: the force between samples a cubic spline through them, linear between the
    #: sub-steps (1: linear between the samples)
    sub: int = 1

    def filters(self) -> tuple[list[Any], ndarray]:
        """Per channel the filter to apply in the model (None: none) and the net delay [s] (made once)."""
        if getattr(self, "_filters", None) is None:
            self._filters = self._make_filters()
        return self._filters

    def _make_filters(self) -> tuple[list[Any], ndarray]:
        cf = self.chains.get("force")
        fd = cf.delay_s if cf is not None else 0.0
        out: list[Any] = []
        delays = np.zeros(len(self.channels))
        for r, ch in enumerate(self.channels):
            c = self.chains.get(ch)
            delays[r] = (c.delay_s if c is not None else 0.0) - fd
            if c is None or c.type is None or _same_filter(c, cf):
                out.append(None)
            else:
                out.append(c.state_space())
        return out, delays

    def system(self, model: FrameModel) -> tuple[ndarray, ndarray, ndarray, ndarray]:
        """(A, B, C, D) of the plant with each channel's filter in series (outputs: the channels as the
        acquisition delivers them, before their delays)."""
        A, B, C, D, _ = self.system2(model)
        return A, B[:, 0], C, D[:, 0]

    def system2(self, model: FrameModel) -> tuple[ndarray, ndarray, ndarray, ndarray, ndarray]:
        """(A, B, C, D, cv) of :meth:`system` with two inputs, the force and the friction force in the
        TMD link (:meth:`FrameModel.friction_input`), and the row of the link's relative velocity."""
        A0, B0, Cy, Dy = model.state_space(self.channels)
        Bq0, cv0 = model.friction_input()
        N = model.n + 1
        Dq = np.array(
            [Bq0[N + channel_dof(ch, model.n)[0]] if channel_dof(ch, model.n)[1] else 0.0 for ch in self.channels]
        )
        filt, _ = self.filters()
        nx = A0.shape[0] + sum(f[0].shape[0] for f in filt if f is not None)
        A, B = np.zeros((nx, nx)), np.zeros((nx, 2))
        C, D = np.zeros((len(self.channels), nx)), np.zeros((len(self.channels), 2))
        n0 = A0.shape[0]
        A[:n0, :n0], B[:n0, 0], B[:n0, 1] = A0, B0, Bq0
        i = n0
        for r, f in enumerate(filt):
            if f is None:
                C[r, :n0], D[r] = Cy[r], (Dy[r], Dq[r])
                continue
            Af, Bf, Cf = f
            m = Af.shape[0]
            A[i : i + m, i : i + m] = Af
            A[i : i + m, :n0] = np.outer(Bf, Cy[r])
            B[i : i + m, 0] = Bf * Dy[r]
            B[i : i + m, 1] = Bf * Dq[r]
            C[r, i : i + m] = Cf
            i += m
        cv = np.zeros(nx)
        cv[:n0] = cv0
        return A, B, C, D, cv

    def decompose(self, model: FrameModel) -> tuple[ndarray, ndarray, ndarray, ndarray, ndarray, ndarray]:
        """The plant with the channels' filters in series in modal form, from the plant's own
        eigen-decomposition and each filter's (made once): the system is block triangular, so its modes
        are the plant's (z, rate lambda z + beta u) and each filtered channel's filter modes eta (rate
        mu eta + (gamma Dy - kappa beta) u), with filter state zeta = eta + kappa z, kappa_ji = gamma_j
        c_i / (lambda_i - mu_j) (c = the channel's row on the plant modes). Returns (lam, Bm (modes x 2:
        force, friction), W (channels x modes), D (channels x 2), X0 (modes x plant states: the modal
        start of a plant start state, the filters at rest), wv (the link's relative velocity on the
        modes)); outputs y = Re(W z) + D u."""
        A0, B0, Cy, Dy = model.state_space(self.channels)
        Bq0, cv0 = model.friction_input()
        N = model.n + 1
        Dq = np.array(
            [Bq0[N + channel_dof(ch, model.n)[0]] if channel_dof(ch, model.n)[1] else 0.0 for ch in self.channels]
        )
        lam0, V0 = np.linalg.eig(A0)
        V0i = np.linalg.inv(V0)
        beta = np.einsum("ij,jk->ik", V0i, np.column_stack([B0, Bq0]))  # (plant modes, 2)
        cy = np.einsum("rj,ji->ri", Cy, V0)  # the channels' rows on the plant modes
        filt = self.modal_filters()
        nf = sum(f[0].size for f in filt if f is not None)
        n0, nc = lam0.size, len(self.channels)
        lam = np.concatenate([lam0, *[f[0] for f in filt if f is not None]]) if nf else lam0
        Bm = np.zeros((n0 + nf, 2), complex)
        W = np.zeros((nc, n0 + nf), complex)
        D = np.zeros((nc, 2))
        X0 = np.zeros((n0 + nf, n0), complex)
        Bm[:n0], X0[:n0] = beta, V0i
        i = n0
        for r, f in enumerate(filt):
            if f is None:
                W[r, :n0], D[r] = cy[r], (Dy[r], Dq[r])
                continue
            mu, gam, w = f
            m = mu.size
            kappa = gam[:, None] * cy[r][None, :] / (lam0[None, :] - mu[:, None])  # (filter modes, plant modes)
            Bm[i : i + m, 0] = gam * Dy[r] - kappa @ beta[:, 0]
            Bm[i : i + m, 1] = gam * Dq[r] - kappa @ beta[:, 1]
            W[r, :n0] = w @ kappa
            W[r, i : i + m] = w
            X0[i : i + m] = -kappa @ V0i
            i += m
        wv = np.zeros(n0 + nf, complex)
        wv[:n0] = cv0 @ V0
        return lam, Bm, W, D, X0, wv

    def modal_filters(self) -> list[Any]:
        """Per channel its filter in modal form (mu, gamma, w): rates, input and output weights (None: no
        filter in the model), made once."""
        if getattr(self, "_modal_filters", None) is None:
            out: list[Any] = []
            for f in self.filters()[0]:
                if f is None:
                    out.append(None)
                    continue
                Af, Bf, Cf = f
                mu, Vf = np.linalg.eig(Af)
                out.append((mu, np.linalg.solve(Vf, Bf.astype(complex)), Cf @ Vf))
            self._modal_filters = out
        return self._modal_filters

    @staticmethod
    def _steps(lam: ndarray, h: float) -> tuple[ndarray, ndarray, ndarray]:
        """(phi, g0, g1): e^(lambda h) and the integrals of e^(lambda s) over a step (constant, ramp)."""
        lh = lam * h
        phi = np.exp(lh)
        small = np.abs(lh) < 1e-4
        with np.errstate(divide="ignore", invalid="ignore"):
            g0 = np.where(small, h * (1 + lh / 2 + lh**2 / 6), (phi - 1) / lam)
            g1 = np.where(small, h * (0.5 + lh / 6 + lh**2 / 24), (phi - 1 - lh) / (lam**2 * h))
        return phi, g0, g1

    def modal(self, model: FrameModel, h: float) -> tuple[ndarray, ndarray, ndarray, ndarray, ndarray, ndarray]:
        """(phi, b0, b1, W, D, X0): the system in modal form (:meth:`decompose`) discretised for a force
        linear between instants h apart; outputs y = Re(W z) + D u."""
        lam, Bm, W, D, X0, _ = self.decompose(model)
        phi, g0, g1 = self._steps(lam, h)
        b = Bm[:, 0]
        return phi, b * (g0 - g1), b * g1, W, D[:, 0], X0

    def run(self, model: FrameModel, u: ndarray, friction: tuple[float, float] | None = None) -> ndarray:
        """(samples, channels): the channels of the record under force samples ``u``, from rest;
        ``friction``: (df, s), dry friction df (2/pi) atan(s (xd_s - yd)) in the TMD link, each sub-step
        implicit in the friction force (:func:`_friction_run`)."""
        u = np.asarray(u, float)
        if friction is not None and friction[0] > 0:
            return self._run_friction(model, u, *friction)
        phi, b0, b1, W, D, _ = self.modal(model, self.h / self.sub)
        if self.sub > 1:
            u = self.fine(u)
        y = _modal_run(phi, b0, b1, np.ascontiguousarray(W), D, u, self.sub)
        return self.delayed(y)

    def _run_friction(self, model: FrameModel, u: ndarray, df: float, slope: float) -> ndarray:
        h = self.h / self.sub
        lam, Bm, W, D, _, wv = self.decompose(model)
        phi, g0, g1 = self._steps(lam, h)
        b, bq = Bm[:, 0], Bm[:, 1]
        uf = self.fine(u) if self.sub > 1 else u
        y = _friction_run(
            phi,
            b * (g0 - g1),
            b * g1,
            bq * g0,
            np.ascontiguousarray(W),
            np.ascontiguousarray(D),
            wv,
            uf,
            self.sub,
            df,
            slope,
        )
        return self.delayed(y)

    def fine(self, u: ndarray) -> ndarray:
        """The force on the sub-step grid: a cubic spline through the samples."""
        key = (id(u), u.size)
        if getattr(self, "_fine_key", None) != key:
            from scipy.interpolate import CubicSpline

            k = np.arange(u.size, dtype=float)
            kf = np.arange((u.size - 1) * self.sub + 1) / self.sub
            self._fine = CubicSpline(k, u)(kf)
            self._fine_key = key
        return self._fine

    def free(self, model: FrameModel, n_samples: int) -> ndarray:
        """(samples, channels, 2 (n + 1)): the channels' free responses to a unit start state of each
        displacement and velocity of the plant (no force)."""
        phi, _, _, W, _, X0 = self.modal(model, self.h)
        Mx = np.ascontiguousarray(W[:, :, None] * X0[None, :, :])  # (channels, modes, plant states)
        out = _free_run(phi, Mx, n_samples)
        for j in range(X0.shape[1]):
            out[:, :, j] = self.delayed(out[:, :, j])
        return out

    def response(self, model: FrameModel, omega: ndarray) -> ndarray:
        """(frequencies, channels): the channels' frequency response to the force at ``omega`` [rad/s]
        (filters and delays included)."""
        lam, Bm, W, D, _, _ = self.decompose(model)
        b = Bm[:, 0]
        H = (W[None, :, :] * (b[None, None, :] / (1j * omega[:, None, None] - lam[None, None, :]))).sum(axis=2) + D[
            :, 0
        ]
        _, delays = self.filters()
        return H * np.exp(-1j * omega[:, None] * delays[None, :])

    def delayed(self, y: ndarray) -> ndarray:
        _, delays = self.filters()
        if not np.any(delays):
            return y
        t = np.arange(y.shape[0]) * self.h
        out = y.copy()
        for r, d in enumerate(delays):
            if d:
                out[:, r] = np.interp(t - d, t, y[:, r], left=0.0)
        return out


@njit(cache=True)
def _free_run(phi: ndarray, Mx: ndarray, n: int) -> ndarray:
    """y[k, c, j] = Re sum_m Mx[c, m, j] phi_m^k."""
    nc, m, n0 = Mx.shape
    y = np.zeros((n, nc, n0))
    p = np.ones(m, dtype=np.complex128)
    for k in range(n):
        for c in range(nc):
            for j in range(n0):
                acc = 0.0
                for i in range(m):
                    acc += (Mx[c, i, j] * p[i]).real
                y[k, c, j] = acc
        for i in range(m):
            p[i] *= phi[i]
    return y


@njit(cache=True)
def _modal_run(phi: ndarray, b0: ndarray, b1: ndarray, W: ndarray, D: ndarray, u: ndarray, sub: int) -> ndarray:
    """y_k = Re(W z_k) + D u_k at every ``sub``-th step, z_k+1 = phi z_k + b0 u_k + b1 u_k+1, z_0 = 0."""
    n, m = u.size, phi.size
    nc = D.size
    y = np.empty(((n - 1) // sub + 1, nc))
    z = np.zeros(m, dtype=np.complex128)
    for k in range(n):
        if k % sub == 0:
            for c in range(nc):
                acc = D[c] * u[k]
                for j in range(m):
                    acc += (W[c, j] * z[j]).real
                y[k // sub, c] = acc
        if k + 1 < n:
            for j in range(m):
                z[j] = phi[j] * z[j] + b0[j] * u[k] + b1[j] * u[k + 1]
    return y


@njit(cache=True)
def _friction_run(
    phi: ndarray,
    b0: ndarray,
    b1: ndarray,
    bq: ndarray,
    W: ndarray,
    D: ndarray,
    wv: ndarray,
    u: ndarray,
    sub: int,
    df: float,
    slope: float,
) -> ndarray:
    """:func:`_modal_run` with the friction force q = df (2/pi) atan(slope v) of the link's relative
    velocity v = Re(wv z) held over each step and implicit in it: q = f(v_free + gamma q) solved by a
    safeguarded Newton iteration in [-df, df] (gamma = Re(wv bq) < 0: stable at any slope)."""
    n, m = u.size, phi.size
    nc = D.shape[0]
    y = np.empty(((n - 1) // sub + 1, nc))
    z = np.zeros(m, dtype=np.complex128)
    zf = np.zeros(m, dtype=np.complex128)
    gam = 0.0
    for j in range(m):
        gam += (wv[j] * bq[j]).real
    c = 2.0 / np.pi * df
    q = 0.0
    for k in range(n):
        if k + 1 < n:
            vf = 0.0
            for j in range(m):
                zf[j] = phi[j] * z[j] + b0[j] * u[k] + b1[j] * u[k + 1]
                vf += (wv[j] * zf[j]).real
            lo, hi = -df, df
            for _ in range(40):
                x = vf + gam * q
                g = q - c * np.arctan(slope * x)
                if g > 0.0:
                    hi = q
                else:
                    lo = q
                dg = 1.0 - c * slope / (1.0 + (slope * x) ** 2) * gam
                qn = q - g / dg
                if not lo < qn < hi:
                    qn = 0.5 * (lo + hi)
                if abs(qn - q) <= 1e-12 * df:
                    q = qn
                    break
                q = qn
        if k % sub == 0:
            for r in range(nc):
                acc = D[r, 0] * u[k] + D[r, 1] * q
                for j in range(m):
                    acc += (W[r, j] * z[j]).real
                y[k // sub, r] = acc
        if k + 1 < n:
            for j in range(m):
                z[j] = zf[j] + bq[j] * q
    return y
