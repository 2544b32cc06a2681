"""Where the residual of a transient diagnosis lives: by body, time segment, frequency band and
band of relative-displacement amplitude (:func:`where`)."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_sim import TView

SEGMENTS = 8  #: time segments per record (even: fitted, odd: held out; :mod:`.transient`)


def where(views: list[TView], resid: list[ndarray]) -> dict[str, Any]:
    """Where a residual's excess over the noise lives: by body (base x/xdd, TMD y/ydd), by time
    segment of each record, by frequency band and by band of relative-displacement amplitude."""
    from scipy.signal import welch

    body = {"base": 0.0, "tmd": 0.0}
    segs, psd_ex, amp_rows = [], None, []
    freqs = None
    for v, e in zip(views, resid):
        m = np.ones(v.n_out, bool)
        m[: v.skip] = False
        for k in range(4):
            if v.has[k]:
                body["base" if k in (0, 2) else "tmd"] += max(float(np.sum(e[m, k] ** 2)) - int(m.sum()), 0.0)
        seg = np.minimum((np.arange(v.n_out) * SEGMENTS) // v.n_out, SEGMENTS - 1)
        for s in range(SEGMENTS):
            sm = m & (seg == s)
            x = e[sm][:, v.has]
            segs.append(
                (
                    v.name,
                    float(v.t[sm][0]) if sm.any() else 0.0,
                    float(v.t[sm][-1]) if sm.any() else 0.0,
                    max(float(np.sum(x**2)) - x.size, 0.0),
                )
            )
        ee = np.nan_to_num(e[m][:, v.has])
        f, P = welch(ee, fs=v.fs, axis=0, nperseg=min(1024, ee.shape[0]))
        P = np.sum(P * v.fs / 2 - 1.0, axis=1)  # white noise of unit variance: P = 2 / fs per channel
        if psd_ex is None or (freqs is not None and f.size != freqs.size):
            psd_ex, freqs = np.maximum(P, 0), f
        else:
            psd_ex = psd_ex + np.maximum(P, 0)
        if v.has[0] and v.has[1]:
            from scipy.signal import hilbert

            rel = np.abs(hilbert(np.nan_to_num(v.meas[:, 0] - v.meas[:, 1]) - np.nanmean(v.meas[:, 0] - v.meas[:, 1])))
            amp_rows.append((rel[m], np.sum(ee**2, axis=1) - ee.shape[1]))
    tot = sum(body.values()) or 1.0
    out: dict[str, Any] = {"body": {k: b / tot for k, b in body.items()}}
    st = sum(s[3] for s in segs) or 1.0
    top = sorted(segs, key=lambda s: -s[3])[:3]
    out["segments"] = [{"record": s[0], "t0": s[1], "t1": s[2], "share": s[3] / st} for s in top]
    band = None
    if psd_ex is not None and freqs is not None and psd_ex.sum() > 0:
        c = np.cumsum(psd_ex) / psd_ex.sum()
        band = (float(freqs[np.searchsorted(c, 0.1)]), float(freqs[min(np.searchsorted(c, 0.9), freqs.size - 1)]))
        out["frequency_band_hz"] = band
    if amp_rows:
        a = np.concatenate([r[0] for r in amp_rows])
        x = np.concatenate([r[1] for r in amp_rows])
        qs = np.quantile(a, np.linspace(0, 1, 6))
        sh = [max(float(x[(a >= qs[i]) & (a <= qs[i + 1])].sum()), 0.0) for i in range(5)]
        tot_a = sum(sh) or 1.0
        i = int(np.argmax(sh))
        out["amplitude_band_m"] = {"from": float(qs[i]), "to": float(qs[i + 1]), "share": sh[i] / tot_a}
    parts = [
        f"the {'base' if out['body']['base'] >= out['body']['tmd'] else 'TMD'} channels ({100 * max(out['body'].values()):.0f} %)"
    ]
    if top:
        parts.append(f"most in {top[0][0]} {top[0][1]:.1f}-{top[0][2]:.1f} s ({100 * top[0][3] / st:.0f} %)")
    if band:
        parts.append(f"{band[0]:.2f}-{band[1]:.2f} Hz (80 % of the excess)")
    if "amplitude_band_m" in out:
        ab = out["amplitude_band_m"]
        parts.append(f"relative amplitude {1e3 * ab['from']:.2g}-{1e3 * ab['to']:.2g} mm ({100 * ab['share']:.0f} %)")
    out["text"] = ", ".join(parts)
    return out
