"""The rig's data-acquisition chain, per channel, and what acceleration-only records cannot see.

``dataset.yaml`` may declare what the acquisition did to each channel before it was sampled::

    acquisition:            # optional; channels: force, x, y, xdd, ydd (or `all`)
      xdd: {filter: {type: butterworth, order: 4, cutoff_hz: 102.4}, delay_s: 0.0}
      ydd: {filter: {type: butterworth, order: 4, cutoff_hz: 102.4}}
      force: {delay_s: 0.0005}

* ``filter``: an analog low-pass (the anti-alias filter in front of the ADC), ``type`` butterworth
  or bessel, ``order`` >= 1, ``cutoff_hz`` the -3 dB frequency in Hz for **both** types
  (``scipy.signal.butter(order, 2 pi cutoff_hz, analog=True)``, ``scipy.signal.bessel(...,
  analog=True, norm='mag')``); ``filter: none`` declares no filter (e.g. to exempt one channel
  from ``all``).
* ``delay_s``: a pure delay [s] >= 0 (e.g. the group delay of a delta-sigma ADC).
* ``all`` applies to every channel; a channel's own entry overrides it key by key (``filter``,
  ``delay_s``).

The chain of a channel is the frequency response ``G(i w) = H(i w) exp(-i w delay_s)`` (unit gain
at DC). In steady state at forcing frequency w the measured harmonic h of a channel is
``G(i h w)`` times the true one, so the diagnosis divides every harmonic of the channel (and its
noise std) by ``G(i h w)`` (:func:`correct_series`): the whitened equation error is then exactly
the one obtained by filtering the model's prediction instead, since
``|M - G P|^2 / (|G|^2 s^2) = |M / G - P|^2 / s^2`` (checked in the tests).

FRC records hold amplitudes: the measured ``x_max`` is ``|G_x(i w)|`` times the true one and the
force amplitude ``|G_force(i w)|`` times the true one (exact for the fundamental; the harmonics of
x are far smaller), so both are divided by the gain of their channel at load time
(:func:`correct_frc`; the measured values are kept in ``Record.meta``). A delay does not change an
amplitude.

Acceleration-only records (``t, force, xdd, ydd``): the harmonics h >= 1 of the displacements follow
from the accelerations, ``X_h = -Xdd_h / (h w)^2``; the mean (h = 0) does not. Whatever needs it
is unobservable (:func:`unobservable`): a constant displacement-sensor offset (``sensor_offset``)
and the displacement DC (a static preload, the static deflection). The diagnosis drops the h = 0
rows of such records from the equation error and evaluates nonlinear link forces about the nominal
static equilibrium (no relative offset between base and TMD).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .._jit import njit

if TYPE_CHECKING:
    from collections.abc import Sequence
    from pathlib import Path
    from typing import Any

    from numpy import complex128, ndarray

    from ..inputs.yamlio import MarkedDict
    from ..solvers.harmonic import Series
    from .errors import DataError
    from .records import Record

CHANNELS = ("force", "x", "y", "xdd", "ydd")
FILTER_TYPES = ("butterworth", "bessel")
CHANNEL_KEYS = ("filter", "delay_s")
FILTER_KEYS = ("type", "order", "cutoff_hz")
MAX_ORDER = 12


def analog_lowpass(kind: str, order: int, cutoff_hz: float, output: str = "ba") -> Any:
    """The analog anti-alias low-pass declared as ``filter: {type, order, cutoff_hz}``, in s [rad/s]:
    ``(b, a)`` (``output="ba"``) or ``(z, p, k)`` (``"zpk"``); ``cutoff_hz`` is the -3 dB frequency for
    both types (Bessel normalised by magnitude). The one builder of the declared filters: the
    diagnosis's chains, the benchmarks' acquisition and their truths all take it from here."""
    from scipy import signal

    wc = 2 * math.pi * float(cutoff_hz)
    if kind == "butterworth":
        return signal.butter(int(order), wc, btype="low", analog=True, output=output)
    if kind == "bessel":
        return signal.bessel(int(order), wc, btype="low", analog=True, norm="mag", output=output)
    raise ValueError(f"unknown filter type {kind!r}; known: {', '.join(FILTER_TYPES)}")


@dataclass(frozen=True)
class Chain:
    """Acquisition chain of one channel: an analog low-pass (optional) and a pure delay."""

    channel: str
    type: str | None = None  #: butterworth | bessel | None (no filter)
    order: int = 0
    cutoff_hz: float = 0.0  #: -3 dB frequency [Hz]
    delay_s: float = 0.0  #: pure delay [s]
    filter_key: str = ""  #: the dataset.yaml key that declared the filter (for messages)

    def ba(self) -> tuple[ndarray, ndarray] | None:
        """Numerator and denominator of the analog low-pass in s [rad/s] (None without filter)."""
        if self.type is None:
            return None
        return analog_lowpass(self.type, self.order, self.cutoff_hz)

    def state_space(self) -> tuple[ndarray, ndarray, ndarray] | None:
        """(A, B, C) of the analog low-pass as a cascade of its second-order (and one first-order)
        sections, each with unit gain at DC (None without filter). Well conditioned at any order,
        unlike the companion form of the whole polynomial (order 12 overflows there)."""
        if self.type is None:
            return None
        _, p, _ = analog_lowpass(self.type, self.order, self.cutoff_hz, "zpk")
        secs = [np.array([[0.0, 1.0], [-(abs(q) ** 2), 2 * q.real]]) for q in p if q.imag > 1e-9 * abs(q)]
        secs += [np.array([[q.real]]) for q in p if abs(q.imag) <= 1e-9 * abs(q)]
        n = sum(a.shape[0] for a in secs)
        A, B, C = np.zeros((n, n)), np.zeros(n), np.zeros(n)
        i, prev = 0, None  # section k is driven by the output of section k - 1 (gain: its DC gain 1)
        for a in secs:
            m = a.shape[0]
            A[i : i + m, i : i + m] = a
            gain = -a[-1, 0] if m == 2 else -a[0, 0]  # b so that the section's DC gain is one
            if prev is None:
                B[i + m - 1] = gain
            else:
                A[i + m - 1, prev] = gain
            prev = i
            i += m
        C[prev] = 1.0
        return A, B, C

    def foh_step(self, h: float) -> tuple[ndarray, ndarray, ndarray, ndarray, ndarray] | None:
        """The filter discretised exactly for an input linear between samples h apart (first-order
        hold) on :meth:`state_space`: (phi, g1, g2, C, ee) with s+ = phi s + g1 u_k + g2 u_k+1,
        output C s (no direct term: all-pole low-passes), ee = -A^-1 B the state at rest per unit
        input (None without filter). The one discretisation of the declared filters."""
        from scipy.linalg import expm

        ss = self.state_space()
        if ss is None:
            return None
        A, B, C = ss
        n = A.shape[0]
        M = np.zeros((n + 2, n + 2))
        M[:n, :n], M[:n, n], M[n, n + 1] = A * h, B * h, 1.0
        E = expm(M)
        gam0, gam1 = E[:n, n], E[:n, n + 1]  # int_0^h e^{A s} B ds, its ramp part
        return E[:n, :n], gam0 - gam1, gam1, C, -np.linalg.solve(A, B)

    def response(self, omega: float | ndarray) -> complex128 | ndarray:
        """G(i omega) = H(i omega) exp(-i omega delay_s) at angular frequencies omega [rad/s]."""
        w = np.asarray(omega, dtype=float)
        g = np.exp(-1j * w * self.delay_s)
        ba = self.ba()
        if ba is not None:
            b, a = ba
            s = 1j * w
            g = g * np.polyval(b, s) / np.polyval(a, s)
        return g

    def describe(self) -> str:
        parts = []
        if self.type is not None:
            parts.append(f"{self.type} low-pass, order {self.order}, -3 dB at {self.cutoff_hz:g} Hz")
        if self.delay_s:
            parts.append(f"delay {self.delay_s:g} s")
        return ", ".join(parts) or "none"


def rig_samples(chains: dict, t: ndarray, channels: dict, step: int = 1) -> dict:
    """What the rig's acquisition makes of densely sampled true signals: each channel of ``channels``
    (uniformly sampled at times ``t``) run through its analog filter in the time domain (exact for
    an input linear between samples, :func:`filter_foh`; started at the filter's DC equilibrium for
    the first value) and delayed (linear interpolation), then every ``step``-th sample kept (the
    ADC). Channels without a chain are only decimated. The filter's transient lasts ~ order / (2 pi
    cutoff_hz) s: simulate a settling stretch and discard it. For simulated records that must look
    like the measured ones (the play candidate's rattle statistic is taken on the measured, filtered
    samples)."""
    t = np.asarray(t, float)
    out = {}
    for ch, u in channels.items():
        u = np.asarray(u, float)
        c = chains.get(ch)
        if c is not None and c.type is not None:
            u = filter_foh(c, u, float(t[1] - t[0]))
        if c is not None and c.delay_s:
            u = np.interp(t - c.delay_s, t, u)
        out[ch] = u[::step]
    return out


def filter_foh(chain: Chain, u: ndarray, dt: float) -> ndarray:
    """The chain's analog low-pass applied to ``u`` sampled every ``dt``, exact when ``u`` is linear
    between samples (:meth:`Chain.foh_step`), from the DC equilibrium of ``u[0]``; compiled recursion."""
    step = chain.foh_step(dt)
    if step is None:
        return np.asarray(u, float).copy()
    phi, g1, g2, C, ee = step
    return _foh_run(phi, g1, g2, C, np.asarray(u, float), ee * float(u[0]))


@njit(cache=True)
def _foh_run(Phi: ndarray, P: ndarray, Q: ndarray, C: ndarray, u: ndarray, x0: ndarray) -> ndarray:
    """y_k = C s_k, s_k+1 = Phi s_k + P u_k + Q u_k+1 from s_0 = x0."""
    n = x0.size
    x = x0.copy()
    xn = np.empty(n)
    y = np.empty(u.size)
    for k in range(u.size):
        y[k] = C @ x
        if k + 1 < u.size:
            for i in range(n):
                acc = P[i] * u[k] + Q[i] * u[k + 1]
                for j in range(n):
                    acc += Phi[i, j] * x[j]
                xn[i] = acc
            x[:] = xn
    return y


def _err(file: Path, msg: str) -> DataError:
    from .errors import DataError

    return DataError(f"{file}: {msg}")


def _finite(v: Any, file: Path, key: str) -> float:
    if isinstance(v, bool):
        raise _err(file, f"{key} must be a number, got {v!r}")
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise _err(file, f"{key} must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise _err(file, f"{key} must be finite, got {v!r}")
    return x


def _parse_filter(f: str | MarkedDict, file: Path, key: str) -> dict[str, Any]:
    if f is None or (isinstance(f, str) and f.strip().lower() == "none"):
        return {"type": None}
    if not isinstance(f, dict):
        raise _err(file, f"{key} must be a mapping {{type, order, cutoff_hz}} or 'none', got {f!r}")
    unknown = sorted(set(map(str, f)) - set(FILTER_KEYS))
    if unknown:
        raise _err(file, f"{key}: unknown key(s) {unknown}; known: {list(FILTER_KEYS)}")
    missing = [k for k in FILTER_KEYS if k not in f]
    if missing:
        raise _err(file, f"{key}.{missing[0]} is missing (a filter needs {list(FILTER_KEYS)})")
    typ = str(f["type"]).strip().lower()
    if typ not in FILTER_TYPES:
        raise _err(file, f"{key}.type must be one of {list(FILTER_TYPES)}, got {f['type']!r}")
    order = f["order"]
    if (
        isinstance(order, bool)
        or not isinstance(order, (int, float))
        or order != int(order)
        or not 1 <= int(order) <= MAX_ORDER
    ):
        raise _err(file, f"{key}.order must be an integer from 1 to {MAX_ORDER}, got {order!r}")
    fc = _finite(f["cutoff_hz"], file, f"{key}.cutoff_hz")
    if not fc > 0:
        raise _err(file, f"{key}.cutoff_hz must be > 0 Hz, got {f['cutoff_hz']!r}")
    return {"type": typ, "order": int(order), "cutoff_hz": fc}


def parse_acquisition(
    block: MarkedDict | None, file: Path, level: str = "system", extra_channels: tuple[str, ...] = ()
) -> dict:
    """Validate the ``acquisition`` block of dataset.yaml; returns {channel: Chain} (empty when the
    block is absent). Every problem is a DataError naming ``file`` and the key. ``extra_channels``:
    channels beside :data:`CHANNELS` the records hold (a frame's ``x1``, ``x2dd``, ...)."""
    channels = (*CHANNELS, *extra_channels)
    if block is None:
        return {}
    if level != "system":
        raise _err(
            file,
            "'acquisition' is for system-level datasets (channels force, x, y, xdd, ydd); "
            f"this dataset has level {level!r}",
        )
    if not isinstance(block, dict):
        raise _err(file, f"'acquisition' must be a mapping of channel -> {{filter, delay_s}}, got {block!r}")
    unknown = sorted(set(map(str, block)) - set(channels) - {"all"})
    if unknown:
        raise _err(file, f"acquisition: unknown channel(s) {unknown}; known: {list(channels) + ['all']}")
    parsed = {}
    for ch, spec in block.items():
        key = f"acquisition.{ch}"
        if spec is None:
            spec = {}
        if not isinstance(spec, dict):
            raise _err(file, f"{key} must be a mapping with keys {list(CHANNEL_KEYS)}, got {spec!r}")
        bad = sorted(set(map(str, spec)) - set(CHANNEL_KEYS))
        if bad:
            raise _err(file, f"{key}: unknown key(s) {bad}; known: {list(CHANNEL_KEYS)}")
        p: dict[str, Any] = {}
        if "filter" in spec:
            p["filter"] = _parse_filter(spec["filter"], file, f"{key}.filter")
        if "delay_s" in spec:
            d = _finite(spec["delay_s"], file, f"{key}.delay_s")
            if d < 0:
                raise _err(file, f"{key}.delay_s must be >= 0 s (a delay), got {spec['delay_s']!r}")
            p["delay_s"] = d
        parsed[str(ch)] = p
    out = {}
    for ch in channels:
        p = {**parsed.get("all", {}), **parsed.get(ch, {})}
        if not p:
            continue
        f = p.get("filter", {"type": None})
        src = ch if "filter" in parsed.get(ch, {}) else "all"
        c = Chain(
            ch,
            f["type"],
            f.get("order", 0),
            f.get("cutoff_hz", 0.0),
            p.get("delay_s", 0.0),
            f"acquisition.{src}.filter",
        )
        if c.type is not None or c.delay_s:
            out[ch] = c
    return out


def check_records(chains: dict, records: list[Record], file: Path) -> None:
    """A filter's cut-off must lie below the Nyquist frequency of every time record it applies to
    (an anti-alias filter above fs/2 is a typing error or a rig that aliases)."""
    for ch, c in chains.items():
        if c.type is None:
            continue
        for r in records:
            if r.kind not in ("time", "transient") or ch not in r.columns:
                continue
            t = r.columns["t"]
            # the rate the rig sampled at: a long record averaged on reading (blocks of q rows) keeps
            # its anti-alias filter, which acted before the ADC at q times the averaged rate
            fs = (t.size - 1) / (t[-1] - t[0]) * int((r.meta.get("reduced") or {}).get("block", 1))
            if c.cutoff_hz > 0.5 * fs * (1 + 1e-9):
                raise _err(
                    file,
                    f"{c.filter_key}.cutoff_hz = {c.cutoff_hz:g} Hz is above the Nyquist frequency fs/2 = {0.5 * fs:g} Hz "
                    f"of record {r.name} (an anti-alias cut-off lies below fs/2)",
                )


def correct_series(s: Series, chains: dict) -> Series:
    """Divide every harmonic of every declared channel of a fitted :class:`harmonic.Series` by the
    chain's G(i h w) (coefficients) and |G|^2 (their variance): the series then describe the true
    channels. The per-sample residuals (noise, rattle statistic) stay as measured."""
    for ch, c in (chains or {}).items():
        if ch not in s.coef:
            continue
        g = c.response(np.arange(s.coef[ch].size) * s.omega)
        s.coef[ch] = s.coef[ch] / g
        s.var[ch] = s.var[ch] / np.abs(g) ** 2
    return s


def correct_frc(records: list[Record], chains: dict) -> list[Record]:
    """True x_max and force amplitude of FRC records: divided by |G_x(i w)| and |G_force(i w)|
    (measured values kept in ``Record.meta['measured']``)."""
    for r in records:
        if r.kind != "frc":
            continue
        w = r.columns["omega"]
        for col, ch in (("x_max", "x"), ("force_amplitude", "force")):
            c = chains.get(ch)
            if c is None or c.type is None:
                continue
            r.meta.setdefault("measured", {})[col] = r.columns[col]
            r.columns[col] = r.columns[col] / np.abs(c.response(w))
    return records


def unobservable(views: Sequence[object]) -> list:
    """What the time records cannot see: ``displacement DC`` when some record has no displacement
    channel pair (x, y) -- its mean displacement, a static preload -- and ``sensor_offset`` when no
    record has one."""
    if not views:
        return []
    dc = [getattr(v, "dc", True) for v in views]
    out = []
    if not any(dc):
        out.append("sensor_offset")
    if not all(dc):
        out.append("displacement DC")
    return out
