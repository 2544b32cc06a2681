"""One field-like system dataset: the truth simulated, then measured through a rig's acquisition chain.

Per record (see docs/diagnose-evidence.md, "Check 1"): the truth is evaluated on a dense time grid (rate
k fs >= 20 kHz, the ADC samples on it) that starts two forcing periods before the record (the
filter's transient dies there: its slowest time constant is < 5 ms); each channel is then

1. the sensor's reading of the truth (offset, gain errors),
2. the declared analog anti-alias filter (Butterworth or Bessel prototype, discretised by the
   bilinear transform at the dense rate: at the forcing frequency the phase and gain are exact to
   ~1e-7) and a declared delay (force channel only: the load-cell conditioner),
   (FRC records: x_max and the force amplitude carry the gain |H(i w)| of the x and force chains),
3. sampled at fs (every k-th dense point), t = 0 at an arbitrary phase phi of the cycle
   (force channel F cos(w (t - delay) + phi) before its filter), over a non-whole number of periods,
4. plus white Gaussian noise added **after** the filter (electrical noise at the ADC), std a
   fraction of the channel's rms drawn per channel and record.

The truth: exact linear frequency response (project ``exact_response``) when it is linear; the
project's solver (``monolithic``) for friction, play and the cubic spring; the independent OOV
integrator (:mod:`sysbench_oov`) for OOV dynamics.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from scipy import signal

from ..acquisition import analog_lowpass
from ..records import write_record

DENSE_HZ = 20000.0
PREROLL_PERIODS = 2
CHANNELS = ("force", "x", "y", "xdd", "ydd")
PLAY_PERIODS = 40  #: play (rattling): settle at most 40 periods; x_max = max over the last 20-period window


# -- acquisition ------------------------------------------------------------------------------------
def analog_zpk(spec: dict[str, Any]) -> tuple[np.ndarray, np.ndarray, float]:
    """Analog prototype (z, p, k) of a declared filter {type, order, cutoff_hz}
    (:func:`..acquisition.analog_lowpass`, the one builder)."""
    return analog_lowpass(spec["type"], spec["order"], spec["cutoff_hz"], "zpk")


def filter_response(spec: dict[str, Any], omega: Any) -> np.ndarray:
    """H(i w) of the declared analog filter at omega [rad/s] (scipy freqs_zpk)."""
    z, p, k = analog_zpk(spec)
    return signal.freqs_zpk(z, p, k, np.atleast_1d(np.asarray(omega, dtype=float)))[1]


def apply_filter(x: np.ndarray, spec: dict, fd: float) -> np.ndarray:
    """The analog filter simulated on a signal sampled at the dense rate fd (bilinear transform),
    from rest; the caller discards the pre-roll."""
    z, p, k = analog_zpk(spec)
    zd, pd, kd = signal.bilinear_zpk(z, p, k, fd)
    return signal.sosfilt(signal.zpk2sos(zd, pd, kd), x)


def channel_spec(acq: dict | None, ch: str) -> dict:
    """The acquisition of channel ``ch``: the ``all`` block, overridden by the channel's own key by key
    (``filter``, ``delay_s``; ``filter: none`` exempts the channel), as ``diagnose`` reads
    ``dataset.yaml`` (:func:`..acquisition.parse_acquisition`)."""
    if not acq:
        return {}
    spec = {**(acq.get("all") or {}), **(acq.get(ch) or {})}
    f = spec.get("filter")
    if f is None or (isinstance(f, str) and f.strip().lower() == "none"):  # `filter: none` exempts a channel
        spec.pop("filter", None)
    return spec


# -- truth on a dense grid ------------------------------------------------------------------------
def truth_dense(truth: dict, omega: float, F_rec: float, tau: np.ndarray) -> dict:
    """x, y, xdd, ydd of the true system at solver times tau (true force (1 + a) F_rec cos(w tau))."""
    from ...physics.params import BaseParams, TMDParams
    from .oov import has_dynamics, oov_model

    Ft = F_rec * (1.0 + truth.get("force_error", 0.0))
    oov = truth.get("oov", {})
    if has_dynamics(oov):
        nom = {"base": truth["base"], "tmd": truth["tmd"]}
        d, _ = oov_model(nom, oov, Ft).dense(omega, tau)
        return {k: d[k] for k in ("x", "y", "xdd", "ydd")}
    base = BaseParams(**{**truth["base"], "force_amplitude": Ft})
    tmd = TMDParams(**truth["tmd"])
    if tmd.is_linear:
        from ...models.solve import exact_response

        Z = exact_response(base, tmd, [omega])[0]
        e = np.exp(1j * omega * tau)
        X, Y = Z[0], Z[2]
        return {
            "x": np.real(X * e),
            "y": np.real(Y * e),
            "xdd": np.real(-(omega**2) * X * e),
            "ydd": np.real(-(omega**2) * Y * e),
        }
    from ...models.solve import steady_state
    from ...solvers.monolithic import SolverSettings
    from .bench import solver_samples

    ss = steady_state(base, tmd, omega, settings=SolverSettings(max_periods_window=PLAY_PERIODS))
    z, acc = solver_samples(base, tmd, omega, ss.state, tau, 1e-9)
    return {"x": z[:, 0], "y": z[:, 2], "xdd": acc[:, 0], "ydd": acc[:, 1]}


def measure(
    tr: dict[str, Any],
    truth: dict[str, Any],
    omega: float,
    F_rec: float,
    phi: float,
    t_dense: np.ndarray,
    acq: dict[str, Any] | None,
    fd: float,
    channels: Iterable[str],
) -> dict[str, np.ndarray]:
    """Noise-free measured channels on the dense grid (readings, delay, filter)."""
    gains = truth.get("oov", {})
    out = {}
    for ch in channels:
        spec = channel_spec(acq, ch)
        if ch == "force":
            sig = F_rec * np.cos(omega * (t_dense - float(spec.get("delay_s", 0.0))) + phi)
        else:
            sig = tr[ch].copy()
            if ch == "x":
                sig = sig * (1.0 + gains.get("x_gain", 0.0)) + truth.get("sensor_offset", 0.0)
            if ch in ("xdd", "ydd") and gains.get("accel_gain_channel") == ch:
                sig = sig * (1.0 + gains.get("accel_gain", 0.0))
        if spec.get("filter"):
            sig = apply_filter(sig, spec["filter"], fd)
        out[ch] = sig
    return out


def record_grid(omega: float, fs: float, n_periods: int, phi: float) -> tuple[Any, ...]:
    """(dense solver times tau, dense record times t_dense, k, j0, n): the record's t = 0 is at
    tau = phi / w + 3 T; the ADC takes dense points j0 + k i, i < n."""
    T = 2 * math.pi / omega
    k = int(math.ceil(DENSE_HZ / fs))
    fd = k * fs
    n = int(n_periods * T * fs)
    j0 = int(math.ceil(PREROLL_PERIODS * T * fd))
    jd = np.arange(j0 + k * (n - 1) + 1)
    t_dense = (jd - j0) / fd
    tau = phi / omega + (PREROLL_PERIODS + 1) * T + t_dense
    return tau, t_dense, k, j0, n, fd


def time_record(
    truth: dict[str, Any],
    nom: dict[str, Any],
    omega: float,
    F_rec: float,
    fs: float,
    n_periods: int,
    phi: float,
    acq: dict[str, Any] | None,
    accel_only: bool,
    rng: np.random.Generator,
    levels: dict[str, Any],
) -> tuple[Any, ...]:
    """(columns, noise-free difference chi-square against the nominal, noise stds)."""
    tau, t_dense, k, j0, n, fd = record_grid(omega, fs, n_periods, phi)
    chans = ("force", "xdd", "ydd") if accel_only else CHANNELS
    meas = measure(truth_dense(truth, omega, F_rec, tau), truth, omega, F_rec, phi, t_dense, acq, fd, chans)
    nom_truth = {"base": nom["base"], "tmd": nom["tmd"]}
    ref = measure(truth_dense(nom_truth, omega, F_rec, tau), nom_truth, omega, F_rec, phi, t_dense, acq, fd, chans)
    idx = j0 + k * np.arange(n)
    cols = {"t": np.arange(n) / fs}
    chi2, sig = 0.0, {}
    for ch in chans:
        s = meas[ch][idx]
        std = levels[ch] * float(np.std(s))
        sig[ch] = std
        if ch != "force":
            chi2 += float(np.sum((s - ref[ch][idx]) ** 2)) / std**2
        cols[ch] = s + rng.normal(0.0, std, n)
    order = ["t", "force", "xdd", "ydd"] if accel_only else ["t", "force", "x", "y", "xdd", "ydd"]
    return {c: cols[c] for c in order}, chi2, sig


def frc_amplitudes(truth: dict[str, Any], omegas: Any, F_rec: Any) -> np.ndarray:
    """Noise-free steady-state max |x| of the truth along a sweep (in the order given)."""
    from ...physics.params import BaseParams, TMDParams
    from .oov import has_dynamics, oov_model

    Ft = F_rec * (1.0 + truth.get("force_error", 0.0))
    oov = truth.get("oov", {})
    if has_dynamics(oov):
        mod = oov_model({"base": truth["base"], "tmd": truth["tmd"]}, oov, Ft)
        hint: dict = {}
        z, out = None, []
        for w in omegas:
            a, z = mod.amplitude(float(w), z0=z, hint=hint)
            out.append(a)
        return np.array(out)
    base = BaseParams(**{**truth["base"], "force_amplitude": Ft})
    tmd = TMDParams(**truth["tmd"])
    if tmd.is_linear:
        from ...models.solve import exact_amplitude

        return exact_amplitude(base, tmd, np.asarray(omegas, dtype=float))
    from ...models.solve import steady_state
    from ...physics.params import has_gap
    from ...solvers.monolithic import SolverSettings

    out, z, hint = [], None, {}
    rattle = has_gap(tmd)
    for w in omegas:  # a sweep: each point starts from the previous one's state (play: from the
        # continued companion orbit, which settles in about two windows)
        ss = steady_state(
            base,
            tmd,
            float(w),
            z0=None if rattle else z,
            settings=SolverSettings(max_periods_window=PLAY_PERIODS),
            hint=hint if rattle else None,
        )
        z = ss.state
        out.append(ss.amplitude)
    return np.array(out)


def frc_record(
    truth: dict[str, Any],
    nom: dict[str, Any],
    frc: dict[str, Any],
    acq: dict[str, Any] | None,
    rng: np.random.Generator,
) -> tuple[Any, ...]:
    """(columns, chi-square of the noise-free difference against the nominal)."""
    om = np.asarray(frc["omegas"], dtype=float)
    xm = frc_amplitudes(truth, om, frc["force"])
    xn = frc_amplitudes({"base": nom["base"], "tmd": nom["tmd"]}, om, frc["force"])
    spec = channel_spec(acq, "x").get("filter")
    hx = np.abs(filter_response(spec, om)) if spec else np.ones(om.size)
    g = 1.0 + truth.get("oov", {}).get("x_gain", 0.0)
    xm = xm * hx * g + truth.get("sensor_offset", 0.0)
    xn = xn * hx
    std = frc["noise"] * np.abs(xm)
    chi2 = float(np.sum(((xm - xn) / std) ** 2))
    fspec = channel_spec(acq, "force").get("filter")  # the amplitude the load cell reports
    hf = np.abs(filter_response(fspec, om)) if fspec else np.ones(om.size)
    cols = {"omega": om, "force_amplitude": float(frc["force"]) * hf, "x_max": xm + rng.normal(0.0, 1.0, om.size) * std}
    return cols, chi2


def write_dataset(folder: Path, spec: dict[str, Any], rng: np.random.Generator) -> dict[str, Any]:
    """Write dataset.yaml and the records of one drawn dataset ``spec`` (see sysbench_suite.draw_dataset);
    returns the visibility measure."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    truth, nom, acq = spec["truth"], spec["nominal"], spec.get("acquisition")
    recs: list = []
    chi2_t, chi2_f = 0.0, 0.0
    for r in spec["records"]:
        cols, c2, _ = time_record(
            truth,
            nom,
            r["omega"],
            r["force"],
            spec["fs"],
            r["periods"],
            r["phase"],
            acq,
            spec["accel_only"],
            rng,
            r["noise"],
        )
        chi2_t += c2
        name = f"rec{len(recs) + 1}_{r['frequency_hz']:.2f}Hz_F{r['force']:g}N.csv"
        write_record(folder / name, cols, fmt="%.9g")
        recs.append({"file": name, "frequency_hz": r["frequency_hz"], "force_amplitude": r["force"]})
    for i, f in enumerate(spec["frc"]):
        cols, c2 = frc_record(truth, nom, f, acq, rng)
        chi2_f += c2
        name = f"frc{i + 1}_{f['direction']}_F{f['force']:g}N.csv"
        _write_frc(folder / name, cols["omega"], cols["force_amplitude"], cols["x_max"], f["direction"])
        recs.append({"file": name})
    meta = {
        "level": "system",
        "description": "field-like benchmark dataset (system level, simulated rig)",
        "nominal": nom,
        "records": recs,
    }
    if acq:
        meta["acquisition"] = acq
    (folder / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    return {"chi2_time": chi2_t, "chi2_frc": chi2_f, "chi2": chi2_t + chi2_f}


def _write_frc(file: Path, om: np.ndarray, F: np.ndarray, xm: np.ndarray, direction: Any) -> None:
    with open(file, "w") as f:
        f.write("omega,force_amplitude,x_max,direction\n")
        for a, b, c in zip(om, F, xm):
            f.write(f"{a:.9g},{b:.9g},{c:.9g},{direction}\n")
