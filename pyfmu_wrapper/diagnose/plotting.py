"""The plots of the diagnosis: the one module of ``diagnose/`` that imports matplotlib (the compute
modules return data; the reports call these)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .link.localise import by_phase, by_record, by_state, harmonics

if TYPE_CHECKING:
    from pathlib import Path

    from numpy import ndarray

    from .link.fit import Fit
    from .link.models import LinkData
    from .shapes import FRCDiagnosisShape, SystemDiagnosisShape, TransientDiagnosisShape


def plot_where(ld: LinkData, r0: ndarray, r1: ndarray, path: Path, title: str = "") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 2, figsize=(11, 8))
    rows = by_record(ld, r0)
    om = [np.nan if x["omega"] is None else x["omega"] for x in rows]  # no drive frequency: not placed
    amp = np.array([x["amplitude"] or 0 for x in rows])
    sc = ax[0, 0].scatter(om, [x["nrmse"] for x in rows], c=amp, cmap="viridis")
    if r1 is not None:
        ax[0, 0].scatter(om, [x["nrmse"] for x in by_record(ld, r1)], c=amp, cmap="viridis", marker="x")
    unit = "displacement amplitude [m]" if ld.level == "link" else "force amplitude [N]"
    fig.colorbar(sc, ax=ax[0, 0], label=unit)
    ax[0, 0].set(
        xlabel="drive frequency w [rad/s]", ylabel="NRMSE of force", title="gap per record (o nominal, x fitted)"
    )
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
    ax[1, 0].set(
        xlabel="phase in cycle [deg] (0 = max displacement / force peak)",
        ylabel="residual [N]",
        title="gap by time within the cycle",
    )
    ax[1, 0].legend(fontsize=8)
    de, ve, S = by_state(ld, r0)
    lim = np.nanmax(np.abs(S)) if np.isfinite(S).any() else 1.0
    im = ax[1, 1].pcolormesh(de, ve, S.T, cmap="RdBu_r", vmin=-lim, vmax=lim)
    fig.colorbar(im, ax=ax[1, 1], label="mean residual force [N]")
    ax[1, 1].set(
        xlabel="relative displacement [m]", ylabel="relative velocity [m/s]", title="residual force surface (nominal)"
    )
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_loops(
    ld: LinkData, pred_nom: ndarray, pred_fit: ndarray, test: ndarray, path: Path, max_records: int = 4
) -> None:
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


def plot_candidates(ranking: list[Fit], path: Path) -> None:
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


def plot_system_harmonics(sd: SystemDiagnosisShape, path: Path) -> None:
    """Whitened residual per harmonic and record, nominal and fitted (periodic records only)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4))
    for v in sd.views:
        H = v.X.size - 1
        r = v.r
        o = 2 if v.dc else 0  # acceleration-only records have no h = 0 rows
        mag = np.concatenate(
            [[abs(r[0]) + abs(r[1])] if v.dc else [np.nan], np.hypot(r[o : o + 2 * H], r[o + 2 * H :])[0::2]]
        )
        ax.semilogy(np.arange(mag.size), np.maximum(mag, 1e-3), "o-", ms=3, label=f"{v.name}")
    ax.axhline(1.0, color="k", lw=0.8, label="noise (1 std)")
    ax.set(xlabel="harmonic k of w", ylabel="whitened residual |A_k| (nominal)", title="gap per harmonic (noise units)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_frc(self: FRCDiagnosisShape, path: Path) -> None:
    """The FRC diagnosis (:class:`~.frc.FRCDiagnosis`): measured and fitted curves, residual by frequency."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    o = np.argsort(self.w)
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(self.w[self.train], self.x[self.train], "o", label="measured (train)")
    ax[0].plot(self.w[self.test], self.x[self.test], "s", label="measured (held out)")
    ax[0].plot(self.w[o], self.pred0[o], "-", label="nominal")
    b = self.chosen or self.fits[0]
    ax[0].plot(self.w[o], b["pred"][o], "--", label=f"nominal + {b['effects'][0]}")
    ax[0].set(xlabel="w [rad/s]", ylabel="x_max [m]", title="frequency response")
    ax[0].legend(fontsize=8)
    ax[1].plot(self.w[o], (self.x - self.pred0)[o], "o-", label="nominal")
    ax[1].plot(self.w[o], (self.x - b["pred"])[o], "s-", label="fitted")
    ax[1].axhline(0, color="k", lw=0.5)
    ax[1].set(xlabel="w [rad/s]", ylabel="residual x_max [m]", title="gap by frequency")
    ax[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_transient(td: TransientDiagnosisShape, res: dict, path: Path) -> None:
    """Transient records: the nominal's whitened residual over time per record and channel (the
    noise band is +-1), and where its excess lives by frequency."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    views = td.views
    fig, axs = plt.subplots(len(views) + 1, 1, figsize=(11, 2.4 * (len(views) + 1)), squeeze=False)
    names = ("x", "y", "xdd", "ydd")
    for ax, v, e in zip(axs[:, 0], views, td.nominal_resid):
        for k in range(4):
            if v.has[k]:
                ax.plot(v.t, e[:, k], lw=0.5, label=names[k])
        ax.axhspan(-1, 1, color="k", alpha=0.15, lw=0)
        ax.set(
            xlabel="t [s]",
            ylabel="residual / noise std [1]",
            title=f"{v.name}: nominal model, simulated with the measured force",
        )
        ax.legend(fontsize=7, loc="upper right")
    ax = axs[-1, 0]
    rows = [c for c in res["candidates"] if c.get("ok") and c.get("gap_closed") is not None]
    rows.sort(key=lambda c: c["z"])
    # z spans decades and may be negative (explained below the noise): a symmetric log axis, linear
    # within +-1, shows every bar at its own sign and size (a log axis would clip z <= 0)
    z = [float(c["z"]) for c in rows[:12]]
    ax.barh([" + ".join(c["effects"]) for c in rows[:12]], z, color=["C2" if v <= 5.0 else "C0" for v in z])
    ax.set_xscale("symlog", linthresh=1.0)
    ax.axvline(0.0, color="0.5", lw=0.6)
    ax.axvline(5.0, color="k", lw=0.8)
    ax.set(xlabel="held-out z = (chi2 - dof) / sqrt(2 dof) [1] (line: explained to the noise)", title="candidates")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
