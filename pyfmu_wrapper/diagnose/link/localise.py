"""Where the model misses: by frequency band, harmonic, phase in the cycle and region of state."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray

    from .models import LinkData

N_HARM = 8


def by_record(ld: LinkData, r: ndarray) -> list[Any]:
    rows = []
    for k, rec in enumerate(ld.records):
        m = ld.rec == k
        fr = float(np.sqrt(np.mean(ld.F[m] ** 2)))
        rows.append(
            {
                "record": rec.name,
                "omega": rec.omega,
                "amplitude": rec.amplitude,
                "rms": float(np.sqrt(np.mean(r[m] ** 2))),
                "nrmse": float(np.sqrt(np.mean(r[m] ** 2))) / fr if fr > 0 else float("nan"),
            }
        )
    return rows


def harmonics(ld: LinkData, r: ndarray) -> ndarray:
    """Residual amplitude at k w (k = 0..N_HARM), averaged over records, as a fraction of the total."""
    amps = np.zeros(N_HARM + 1)
    used = 0
    for k, rec in enumerate(ld.records):
        if rec.omega is None:  # non-periodic record: no harmonic panel
            continue
        used += 1
        m = ld.rec == k
        t, x = ld.t[m], r[m]
        cols = [np.ones_like(t)]
        for h in range(1, N_HARM + 1):
            cols += [np.cos(h * rec.omega * t), np.sin(h * rec.omega * t)]
        c = np.linalg.lstsq(np.column_stack(cols), x, rcond=None)[0]
        amps[0] += abs(c[0])
        amps[1:] += np.hypot(c[1::2], c[2::2])
    return amps / max(used, 1)


def by_phase(ld: LinkData, r: ndarray, nbins: int = 24) -> tuple[ndarray, ndarray, ndarray]:
    edges = np.linspace(0, 2 * math.pi, nbins + 1)
    idx = np.clip(np.digitize(ld.phase, edges) - 1, 0, nbins - 1)
    rms = np.array([np.sqrt(np.mean(r[idx == b] ** 2)) if np.any(idx == b) else np.nan for b in range(nbins)])
    mean = np.array([np.mean(r[idx == b]) if np.any(idx == b) else np.nan for b in range(nbins)])
    return 0.5 * (edges[1:] + edges[:-1]), rms, mean


def by_state(ld: LinkData, r: ndarray, nb: int = 16) -> tuple[ndarray, ndarray, ndarray]:
    """Mean residual force on a grid of (displacement, velocity), restoring-force-surface style."""
    de = np.linspace(ld.d.min(), ld.d.max(), nb + 1)
    ve = np.linspace(ld.v.min(), ld.v.max(), nb + 1)
    s, _, _ = np.histogram2d(ld.d, ld.v, [de, ve], weights=r)
    c, _, _ = np.histogram2d(ld.d, ld.v, [de, ve])
    with np.errstate(invalid="ignore"):
        return de, ve, s / np.where(c > 0, c, np.nan)


def state_summary(ld: LinkData, r: ndarray) -> dict[str, float]:
    """Share of the residual energy near velocity reversals and near the displacement extremes."""
    e = r**2
    tot = float(e.sum()) or 1.0
    vn = np.zeros_like(ld.v)
    dn = np.zeros_like(ld.d)
    for k in range(len(ld.records)):
        m = ld.rec == k
        vn[m] = np.abs(ld.v[m]) / (np.abs(ld.v[m]).max() or 1.0)
        dn[m] = np.abs(ld.d[m]) / (np.abs(ld.d[m]).max() or 1.0)
    rev = vn < 0.3
    mid = dn < 0.3
    return {
        "energy_share_low_speed": float(e[rev].sum() / tot),
        "sample_share_low_speed": float(rev.mean()),
        "energy_share_near_zero_displacement": float(e[mid].sum() / tot),
        "sample_share_near_zero_displacement": float(mid.mean()),
    }


def describe(ld: LinkData, r: ndarray, harm: ndarray, phase_rms: ndarray) -> str:
    """A sentence or two on where the gap lies."""
    out = []
    share = harm / max(harm.sum(), 1e-300)
    odd, even = share[3::2].sum(), share[2::2].sum()
    if share[0] >= 0.5:
        out.append(f"the residual is mostly a constant offset ({100 * share[0]:.0f} % of its harmonic content)")
    elif odd + even < 0.25:
        out.append(
            f"the residual is mostly at the drive frequency ({100 * share[1]:.0f} % of its harmonic content): "
            "a linear-looking mismatch (damping, stiffness/inertia or gain)"
        )
    else:
        kind = "odd (symmetric nonlinearity)" if odd >= even else "even (asymmetric nonlinearity)"
        out.append(
            f"the residual has strong higher harmonics: {100 * odd:.0f} % odd, {100 * even:.0f} % even, "
            f"{100 * share[1]:.0f} % at the drive frequency -- mostly {kind}"
        )
    if np.isfinite(phase_rms).any():
        c = np.degrees(np.linspace(0, 2 * np.pi, phase_rms.size + 1)[:-1] + np.pi / phase_rms.size)
        k = int(np.nanargmax(phase_rms))
        out.append(f"it is largest at {c[k]:.0f} deg of the cycle (0 = maximum displacement)")
    ss = state_summary(ld, r)
    if ss["energy_share_low_speed"] > 1.5 * ss["sample_share_low_speed"]:
        out.append(
            f"{100 * ss['energy_share_low_speed']:.0f} % of the residual energy lies at low relative speed "
            f"(velocity reversals, {100 * ss['sample_share_low_speed']:.0f} % of the samples)"
        )
    if ss["energy_share_near_zero_displacement"] > 1.5 * ss["sample_share_near_zero_displacement"]:
        out.append(f"{100 * ss['energy_share_near_zero_displacement']:.0f} % lies near zero displacement")
    return "; ".join(out) + "."
