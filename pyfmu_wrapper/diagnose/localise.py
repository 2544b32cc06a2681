"""Where the model misses: by frequency band, harmonic, phase in the cycle and region of state."""
from __future__ import annotations

import math

import numpy as np

N_HARM = 8


def by_record(ld, r):
    rows = []
    for k, rec in enumerate(ld.records):
        m = ld.rec == k
        fr = float(np.sqrt(np.mean(ld.F[m] ** 2)))
        rows.append({"record": rec.name, "omega": rec.omega, "amplitude": rec.amplitude,
                     "rms": float(np.sqrt(np.mean(r[m] ** 2))),
                     "nrmse": float(np.sqrt(np.mean(r[m] ** 2))) / fr if fr > 0 else float("nan")})
    return rows


def harmonics(ld, r):
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


def by_phase(ld, r, nbins=24):
    edges = np.linspace(0, 2 * math.pi, nbins + 1)
    idx = np.clip(np.digitize(ld.phase, edges) - 1, 0, nbins - 1)
    rms = np.array([np.sqrt(np.mean(r[idx == b] ** 2)) if np.any(idx == b) else np.nan for b in range(nbins)])
    mean = np.array([np.mean(r[idx == b]) if np.any(idx == b) else np.nan for b in range(nbins)])
    return 0.5 * (edges[1:] + edges[:-1]), rms, mean


def by_state(ld, r, nb=16):
    """Mean residual force on a grid of (displacement, velocity), restoring-force-surface style."""
    de = np.linspace(ld.d.min(), ld.d.max(), nb + 1)
    ve = np.linspace(ld.v.min(), ld.v.max(), nb + 1)
    s, _, _ = np.histogram2d(ld.d, ld.v, [de, ve], weights=r)
    c, _, _ = np.histogram2d(ld.d, ld.v, [de, ve])
    with np.errstate(invalid="ignore"):
        return de, ve, s / np.where(c > 0, c, np.nan)


def state_summary(ld, r):
    """Share of the residual energy near velocity reversals and near the displacement extremes."""
    e = r ** 2
    tot = float(e.sum()) or 1.0
    vn = np.zeros_like(ld.v)
    dn = np.zeros_like(ld.d)
    for k in range(len(ld.records)):
        m = ld.rec == k
        vn[m] = np.abs(ld.v[m]) / (np.abs(ld.v[m]).max() or 1.0)
        dn[m] = np.abs(ld.d[m]) / (np.abs(ld.d[m]).max() or 1.0)
    rev = vn < 0.3
    mid = dn < 0.3
    return {"energy_share_low_speed": float(e[rev].sum() / tot), "sample_share_low_speed": float(rev.mean()),
            "energy_share_near_zero_displacement": float(e[mid].sum() / tot),
            "sample_share_near_zero_displacement": float(mid.mean())}


def describe(ld, r, harm, phase_rms):
    """A sentence or two on where the gap lies."""
    out = []
    share = harm / max(harm.sum(), 1e-300)
    odd, even = share[3::2].sum(), share[2::2].sum()
    if share[0] >= 0.5:
        out.append(f"the residual is mostly a constant offset ({100 * share[0]:.0f} % of its harmonic content)")
    elif odd + even < 0.25:
        out.append(f"the residual is mostly at the drive frequency ({100 * share[1]:.0f} % of its harmonic content): "
                   "a linear-looking mismatch (damping, stiffness/inertia or gain)")
    else:
        kind = "odd (symmetric nonlinearity)" if odd >= even else "even (asymmetric nonlinearity)"
        out.append(f"the residual has strong higher harmonics: {100 * odd:.0f} % odd, {100 * even:.0f} % even, "
                   f"{100 * share[1]:.0f} % at the drive frequency -- mostly {kind}")
    if np.isfinite(phase_rms).any():
        c = np.degrees(np.linspace(0, 2 * np.pi, phase_rms.size + 1)[:-1] + np.pi / phase_rms.size)
        k = int(np.nanargmax(phase_rms))
        out.append(f"it is largest at {c[k]:.0f} deg of the cycle (0 = maximum displacement)")
    ss = state_summary(ld, r)
    if ss["energy_share_low_speed"] > 1.5 * ss["sample_share_low_speed"]:
        out.append(f"{100 * ss['energy_share_low_speed']:.0f} % of the residual energy lies at low relative speed "
                   f"(velocity reversals, {100 * ss['sample_share_low_speed']:.0f} % of the samples)")
    if ss["energy_share_near_zero_displacement"] > 1.5 * ss["sample_share_near_zero_displacement"]:
        out.append(f"{100 * ss['energy_share_near_zero_displacement']:.0f} % lies near zero displacement")
    return "; ".join(out) + "."


def plot_where(ld, r0, r1, path, title=""):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    rows = by_record(ld, r0)
    om = [x["omega"] for x in rows]
    amp = np.array([x["amplitude"] or 0 for x in rows])
    sc = ax[0, 0].scatter(om, [x["nrmse"] for x in rows], c=amp, cmap="viridis")
    if r1 is not None:
        ax[0, 0].scatter(om, [x["nrmse"] for x in by_record(ld, r1)], c=amp, cmap="viridis", marker="x")
    fig.colorbar(sc, ax=ax[0, 0], label="amplitude")
    ax[0, 0].set(xlabel="drive frequency w [rad/s]", ylabel="NRMSE of force", title="gap per record (o nominal, x fitted)")
    h0 = harmonics(ld, r0)
    ax[0, 1].bar(np.arange(h0.size) - 0.2, h0, 0.4, label="nominal")
    if r1 is not None:
        ax[0, 1].bar(np.arange(h0.size) + 0.2, harmonics(ld, r1), 0.4, label="fitted")
    ax[0, 1].set(xlabel="harmonic k of w", ylabel="residual amplitude [N]", title="harmonic content of the residual")
    ax[0, 1].legend()
    c, rms0, mean0 = by_phase(ld, r0)
    ax[1, 0].plot(np.degrees(c), rms0, "o-", label="rms nominal")
    ax[1, 0].plot(np.degrees(c), mean0, "--", label="mean nominal")
    if r1 is not None:
        ax[1, 0].plot(np.degrees(c), by_phase(ld, r1)[1], "s-", label="rms fitted")
    ax[1, 0].axhline(ld.noise, color="k", lw=0.8, label="noise floor")
    ax[1, 0].set(xlabel="phase in cycle [deg] (0 = max displacement / force peak)", ylabel="residual [N]",
                 title="gap by time within the cycle")
    ax[1, 0].legend(fontsize=8)
    de, ve, S = by_state(ld, r0)
    lim = np.nanmax(np.abs(S)) if np.isfinite(S).any() else 1.0
    im = ax[1, 1].pcolormesh(de, ve, S.T, cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=ax[1, 1], label="mean residual force [N]")
    ax[1, 1].set(xlabel="relative displacement [m]", ylabel="relative velocity [m/s]",
                 title="residual force surface (nominal)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_loops(ld, pred_nom, pred_fit, test, path, max_records=4):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ids = sorted(set(ld.rec[test].tolist()))[:max_records]
    fig, axs = plt.subplots(1, len(ids), figsize=(4.2 * len(ids), 3.8), squeeze=False)
    for ax, k in zip(axs[0], ids):
        m = (ld.rec == k) & test
        ax.plot(ld.d[m], ld.F[m], ".", ms=2, color="0.5", label="measured")
        ax.plot(ld.d[m], pred_nom[m], "-", lw=1, label="nominal")
        if pred_fit is not None:
            ax.plot(ld.d[m], pred_fit[m], "-", lw=1, label="nominal + effect")
        ax.set(title=f"{ld.records[k].name} (held out)", xlabel="displacement [m]", ylabel="force [N]")
    axs[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_candidates(ranking, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = [f.name for f in ranking]
    fig, ax = plt.subplots(figsize=(8, 0.35 * len(names) + 1.2))
    ax.barh(names[::-1], [100 * (f.closed if f.closed == f.closed else 0) for f in ranking][::-1])
    ax.set(xlabel="held-out gap closed [%]", title="candidates (best first, by held-out BIC)")
    ax.set_xlim(min(0, min(100 * (f.closed if f.closed == f.closed else 0) for f in ranking)), 100)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
