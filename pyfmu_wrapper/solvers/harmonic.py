"""Fourier series over whole forcing periods: derivatives a rig can give, and the noise per channel.

(The diagnosis fits its steady records with it; the engines' steady states take their periodic
amplitude, :func:`periodic_max`, from the same series.)

A steady-state record at forcing frequency w is periodic: every channel is
``s(t) = Re(sum_h C_h exp(i h w t)) + noise``. Least squares on the samples of the largest whole
number of periods gives the coefficients C_h (h = 0..H) of every channel at once (one QR per
record), their noise (from the residual, per channel), and exact derivatives of the series
(multiply C_h by i h w). Displacement and acceleration of the same body are fused per harmonic
(inverse-variance weights: x gives X_h, xdd gives -Xdd_h / (h w)^2), so velocities come from the
better-measured of the two at every harmonic and their noise is known.

A record is **periodic** when the harmonic series explains at least ``PERIODIC_R2`` of the
variance of its force and displacement channels; non-periodic records (earthquakes, transients)
are flagged and never get harmonic panels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy import ndarray

PERIODIC_R2 = 0.9  #: share of the variance a harmonic series must explain for a record to count as periodic
H_MAX = 150  #: cap on the harmonics of the full (noise-estimating) fit
GRID = 4096  #: phases over one period a series' maximum is taken on (:func:`series_max`)


def estimate_omega(t: ndarray, s: ndarray) -> float | None:
    """Dominant angular frequency [rad/s] of a sampled signal, or None when there is none.

    FFT peak refined by a parabola through the neighbouring bins (shift clipped to half a bin) and
    then by a one-harmonic least-squares scan. None when the record holds fewer than two cycles of
    its peak or the peak holds less than a quarter of the signal's power (not periodic)."""
    t = np.asarray(t, float)
    s = np.asarray(s, float)
    n = len(t)
    if n < 8:
        return None
    dt = (t[-1] - t[0]) / (n - 1)
    x = s - s.mean()
    if not np.any(x):
        return None
    spec = np.abs(np.fft.rfft(x * np.hanning(n))) ** 2
    k = int(np.argmax(spec[1:]) + 1)
    if k < 2:
        return None
    share = spec[max(k - 2, 1) : k + 3].sum() / spec[1:].sum()
    if share < 0.25:
        return None
    off = 0.0
    if k < len(spec) - 1:
        a, b, c = np.sqrt(spec[k - 1 : k + 2])
        den = a - 2 * b + c
        off = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den != 0 else 0.0
    w0 = 2 * math.pi * (k + off) / (n * dt)
    # refine: the frequency whose single harmonic explains most of the signal
    span = 2 * math.pi / (n * dt)
    best = (-1.0, w0)
    for w in w0 + span * np.linspace(-0.5, 0.5, 41):
        B = np.column_stack([np.cos(w * t), np.sin(w * t)])
        c = np.linalg.lstsq(B, x, rcond=None)[0]
        e = float(np.sum((B @ c) ** 2))
        if e > best[0]:
            best = (e, w)
    w = best[1]
    return float(w) if w > 0 and math.isfinite(w) else None


@dataclass
class Series:
    """Harmonic coefficients of the channels of one record (complex, h = 0..H)."""

    omega: float
    H: int
    coef: dict  #: channel -> complex array C_h, h = 0..H
    var: dict  #: channel -> variance of Re C_h (= of Im C_h) per harmonic [unit^2]
    noise: dict  #: channel -> noise std per sample (residual of the full fit) [unit]
    noise_robust: dict  #: channel -> 1.4826 MAD of the residual [unit]
    r2: dict  #: channel -> share of the variance explained by the series
    resid: dict = field(repr=False, default_factory=dict)  #: channel -> residual samples of the full fit
    n: int = 0
    span: tuple = (0, 0)  #: sample range used (whole periods)
    periodic: bool = True

    def eval(self, ch: str, theta: ndarray, deriv: int = 0) -> ndarray:
        """Series of channel ``ch`` (or its deriv-th derivative) at phases theta = w t."""
        h = np.arange(self.H + 1)
        c = self.coef[ch] * (1j * h * self.omega) ** deriv
        return np.real(np.exp(1j * np.outer(theta, h)) @ c)


def whole_periods(t: ndarray, omega: float) -> tuple[slice, int]:
    """Index slice of the largest whole number of periods from the start of the record."""
    T = 2 * math.pi / omega
    nper = int(math.floor((t[-1] - t[0]) / T + 1e-9))
    if nper < 1:
        return slice(0, len(t)), 0
    dt = (t[-1] - t[0]) / (len(t) - 1)
    stop = int(np.searchsorted(t, t[0] + nper * T - 0.5 * dt))
    return slice(0, max(stop, 3)), nper


_BASIS: dict = {}
BASIS_CACHE_BYTES = 128 * 2**20  #: the cached bases' total size; older ones are dropped beyond it


def _basis(tt: ndarray, omega: float, H: int) -> tuple[ndarray, ndarray, ndarray]:
    """Harmonic basis at the sample times tt, (B^T B)^-1 and its diagonal; cached for uniform sampling."""
    n = tt.size
    uniform = bool(np.max(np.abs(tt - np.linspace(0.0, tt[-1], n))) <= 1e-6 * tt[-1] / max(n - 1, 1))
    key = (n, omega, H, float(tt[-1])) if uniform else None
    if key is None or key not in _BASIS:
        ang = np.outer(tt, omega * np.arange(1, H + 1))
        B = np.empty((n, 2 * H + 1))
        B[:, 0] = 1.0
        B[:, 1::2] = np.cos(ang)
        B[:, 2::2] = np.sin(ang)
        # normal equations: over whole periods the basis is nearly orthogonal (B^T B ~ n/2 I), so
        # this is well conditioned and much cheaper than a QR of the n x (2H+1) matrix
        Li = np.linalg.inv(np.linalg.cholesky(B.T @ B))
        Ginv = Li.T @ Li
        if key is None or B.nbytes > BASIS_CACHE_BYTES // 4:  # a long record's basis is not kept
            return B, Ginv, np.diag(Ginv).copy()
        while _BASIS and sum(b[0].nbytes for b in _BASIS.values()) + B.nbytes > BASIS_CACHE_BYTES:
            del _BASIS[next(iter(_BASIS))]  # the oldest first
        _BASIS[key] = (B, Ginv, np.diag(Ginv).copy())
    return _BASIS[key]


def harmonics_for(samples_per_period: float, n: int | None = None) -> int:
    """The harmonics a series fitted to uniform samples holds: at most :data:`H_MAX`, below 0.45 of
    the samples per period (short of Nyquist) and, of ``n`` samples in all, (n - 2) // 3."""
    cap = max(1, (n - 2) // 3) if n is not None else H_MAX
    return int(min(H_MAX, max(1, math.floor(0.45 * samples_per_period)), cap))


def series_max(C: ndarray) -> float:
    """max |x - mean| over one period of the series with coefficients C (h = 0..H; C_0, the mean,
    dropped), on a grid of :data:`GRID` phases: a steady record's amplitude as the diagnosis takes it."""
    c = np.array(C, complex)
    c[0] = 0.0
    return float(np.max(np.abs(grid_values(c, 1.0, GRID))))


def periodic_max(period: ndarray) -> float:
    """:func:`series_max` of the harmonic series of x sampled uniformly over one period (``period``:
    n samples at phases 2 pi j / n, j = 0..n-1, e.g. the mean of several periods' samples at the same
    phases, which is the least-squares series of all of them), with :func:`harmonics_for` n
    harmonics; NaN without three finite samples."""
    vals = np.asarray(period, float)
    if vals.size < 3 or not np.all(np.isfinite(vals)):
        return math.nan
    return series_max(grid_coef(vals, harmonics_for(vals.size)))


def fit_series(t: ndarray, channels: dict, omega: float, H: int | None = None) -> Series:
    """Least-squares Fourier series of every channel over the whole periods of the record."""
    sl, nper = whole_periods(t, omega)
    tt = t[sl] - t[0]
    n = tt.size
    dt = (tt[-1] - tt[0]) / max(n - 1, 1)
    spp = 2 * math.pi / omega / dt
    Hf = harmonics_for(spp, n)
    if H is not None:
        Hf = min(Hf, H) if H > 0 else Hf
    B, Ginv, cdiag = _basis(tt, float(omega), int(Hf))
    names = list(channels)
    Y = np.column_stack([np.asarray(channels[c], float)[sl] for c in names])
    C = Ginv @ (B.T @ Y)
    E = Y - B @ C
    dof = max(n - B.shape[1], 1)
    out = Series(
        omega=omega,
        H=Hf,
        coef={},
        var={},
        noise={},
        noise_robust={},
        r2={},
        n=n,
        span=(sl.start or 0, sl.stop),
        periodic=nper >= 2,
    )
    for j, c in enumerate(names):
        s2 = float(E[:, j] @ E[:, j]) / dof
        cc = np.empty(Hf + 1, complex)
        cc[0] = C[0, j]
        cc[1:] = C[1::2, j] - 1j * C[2::2, j]
        v = np.empty(Hf + 1)
        v[0] = s2 * cdiag[0]
        v[1:] = s2 * 0.5 * (cdiag[1::2] + cdiag[2::2])
        y = Y[:, j] - Y[:, j].mean()
        out.coef[c], out.var[c] = cc, v
        out.noise[c] = math.sqrt(s2)
        med = np.median(E[:, j])
        out.noise_robust[c] = 1.4826 * float(np.median(np.abs(E[:, j] - med))) * math.sqrt(n / dof)
        out.r2[c] = 1.0 - float(E[:, j] @ E[:, j]) / max(float(y @ y), 1e-300)
        out.resid[c] = E[:, j]
    return out


def fuse(s: Series, pos: str, acc: str | None, H: int) -> tuple[ndarray, ndarray]:
    """Displacement coefficients X_h (h = 0..H) fused from a displacement and an acceleration
    channel, and their variance per real component. Returns (X, var).

    Without the displacement channel (an acceleration-only record) X_h = -Xdd_h / (h w)^2 for
    h >= 1; the mean X_0 is unobservable and returned as 0 with variance 0 (the caller decides)."""
    h = np.arange(H + 1)
    if pos not in s.coef:
        w2 = (h[1:] * s.omega) ** 2
        X = np.zeros(H + 1, complex)
        vx = np.zeros(H + 1)
        X[1:] = -s.coef[acc][1 : H + 1] / w2
        vx[1:] = s.var[acc][1 : H + 1] / w2**2
        return X, vx
    X = s.coef[pos][: H + 1].copy()
    vx = s.var[pos][: H + 1].copy()
    if acc is None or acc not in s.coef:
        return X, vx
    w2 = (h[1:] * s.omega) ** 2
    Xa = -s.coef[acc][1 : H + 1] / w2
    va = s.var[acc][1 : H + 1] / w2**2
    wx, wa = 1.0 / np.maximum(vx[1:], 1e-300), 1.0 / np.maximum(va, 1e-300)
    X[1:] = (wx * X[1:] + wa * Xa) / (wx + wa)
    vx[1:] = 1.0 / (wx + wa)
    return X, vx


def grid_values(C: ndarray, omega: float, n_grid: int, deriv: int = 0) -> ndarray:
    """Samples over one period (theta_j = 2 pi j / n_grid) of the series with coefficients C."""
    h = np.arange(C.size)
    c = C * (1j * h * omega) ** deriv
    full = np.zeros(n_grid // 2 + 1, complex)
    m = min(C.size, full.size)
    full[:m] = c[:m]
    # Re(sum c_h e^{i h theta}) = irfft of (n/2) c_h for h >= 1, n c_0 for h = 0
    full[0] *= n_grid
    full[1:] *= n_grid / 2.0
    return np.fft.irfft(full, n_grid)


def grid_coef(vals: ndarray, H: int) -> ndarray:
    """Harmonic coefficients C_h (h = 0..H) of samples over one period."""
    n = vals.size
    f = np.fft.rfft(vals) / n
    c = np.zeros(H + 1, complex)
    m = min(H + 1, f.size)
    c[:m] = f[:m]
    c[1:m] *= 2.0
    return c
