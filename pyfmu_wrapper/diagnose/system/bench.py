"""System-level withheld-effect datasets under fixed conditions (the tests of ``diagnose`` use
:func:`make_system_dataset`); the field-like suite of ``make-benchmark`` is
:mod:`sysbench_suite` (drawing), :mod:`sysbench_field` (simulation and acquisition chain) and
:mod:`sysbench_oov` (out-of-vocabulary truths), see docs/diagnose-evidence.md "Check 1".

The coupled base + TMD simulated with the project's solver (``solvers.monolithic``) and measured
as a test rig does. Per dataset of :func:`make_system_dataset`: paper Case 1 or Case 2 nominal
(ideal inerter, c = 15 N s/m, no friction, no play); four steady-state time records (t, force, x, y, xdd, ydd at 1 kHz over 10 forcing periods, no
velocity channel) at four distinct frequencies drawn from 16-24 rad/s and force amplitudes from
100-300 N; independent white noise of 0.5-2 % of each channel's rms, drawn per channel and per
record; one stepped-sine FRC (200 N, 15-25 rad/s in 0.5 rad/s steps, x_max = max x over the
steady window) with 0.5 % noise on x_max. Accelerations are the kernels' right-hand side at the
sample times (contact spikes of the play chain included, point-sampled like a real ADC).

Hidden effects and the parameter the diagnosis should recover (``truth`` in the manifest):

==============  =====================================================  ============================
effect          how it is simulated                                    severity range (log-uniform)
==============  =====================================================  ============================
friction        TMDParams.friction_force = df (slope 1e6 s/m)          df 1.5-20 N
play            inerter = play, play_gap = eps (ki 2e7, ci 0.01)       eps 3e-5-1e-3 m
viscous         damping 15 -> 15 + dc                                  dc 2-30 N s/m
mass_split      I -> I + dI, m -> m - dI (m + I = 10 kg)               |dI| 0.1-1 kg (Case 1: dI > -0.5)
cubic           TMDParams.cubic_stiffness = k3 (when the physics has)  k3 1e4-3e5 N/m^3
force_error     true force = (1 + a) x recorded force                  |a| 2-15 %
sensor_offset   x reads x + b (time records and x_max)                 |b| 3e-4-3e-3 m
==============  =====================================================  ============================
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from ..records import write_record
from .effects import VOCAB

if TYPE_CHECKING:
    from numpy import ndarray

    from ...physics.params import BaseParams, TMDParams
    from ...solvers.monolithic import SteadyState

RANGES = {
    "friction": (1.5, 20.0),
    "play": (3e-5, 1e-3),
    "viscous": (2.0, 30.0),
    "mass_split": (0.1, 1.0),
    "cubic": (1e4, 3e5),
    "force_error": (0.02, 0.15),
    "sensor_offset": (3e-4, 3e-3),
}
SIGNED = VOCAB.signed()  #: effects drawn with either sign (the vocabulary's signed ones)
TRUTH_KEY = VOCAB.truth_keys(RANGES)  #: effect -> the parameter key its truth is scored by
FS = 1000.0
N_PERIODS = 10
FRC_OMEGAS = np.linspace(15.0, 25.0, 21)
FRC_FORCE = 200.0
FRC_NOISE = 0.005


def has_cubic() -> bool:
    from ...physics.params import TMDParams

    return "cubic_stiffness" in {f.name for f in dataclasses.fields(TMDParams)}


def nominal(case: int, damping: float = 15.0) -> dict:
    """Paper Case 1, 2 or 3 (m, I) = (9, 1), (5, 5), (1, 9) kg with an ideal inerter and TMD damping c."""
    m, I = {1: (9.0, 1.0), 2: (5.0, 5.0), 3: (1.0, 9.0)}[case]
    return {
        "base": {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0},
        "tmd": {
            "mass": m,
            "stiffness": 4.0e3,
            "damping": float(damping),
            "friction_force": 0.0,
            "friction_slope": 1.0e6,
            "inertance": I,
            "inerter": "ideal",
        },
    }


def true_tmd(nom: dict, hidden: dict) -> TMDParams:
    from ...physics.params import TMDParams

    return TMDParams(**true_tmd_kwargs(nom, hidden))


def true_tmd_kwargs(nom: dict, hidden: dict) -> dict:
    """TMDParams keyword arguments of the nominal's TMD with the hidden TMD-link effects applied."""
    return true_values(nom, hidden)["tmd"]


def true_values(nom: dict, hidden: dict) -> dict[str, dict]:
    """The nominal's ``base`` and ``tmd`` blocks with the hidden model effects applied (``hidden``:
    effect -> the size the benchmark scores, :attr:`~pyfmu_wrapper.physics.effects.Effect.truth_key`),
    each by its targets in the unit's vocabulary; play also switches the inerter to the play chain.
    Measurement effects (force_error, sensor_offset) are the rig's: left to the caller."""
    vals = {f"{sub}.{k}": v for sub in ("base", "tmd") for k, v in nom[sub].items()}
    vals.setdefault("tmd.cubic_stiffness", 0.0)
    VOCAB.apply(vals, {VOCAB[e].truth_key: v for e, v in hidden.items() if e in VOCAB})
    out: dict[str, dict] = {"base": {}, "tmd": {}}
    for key, v in vals.items():
        sub, name = key.split(".", 1)
        out[sub][name] = v
    if not out["tmd"]["cubic_stiffness"] and "cubic_stiffness" not in nom["tmd"]:
        del out["tmd"]["cubic_stiffness"]
    if "play" in hidden:
        out["tmd"]["inerter"] = "play"
    return out


def steady_record(
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    n_periods: int = N_PERIODS,
    fs: float = FS,
    settle_periods: int | None = None,
    rtol: float = 1e-9,
) -> tuple[ndarray, ndarray, ndarray, SteadyState | None]:
    """(t, states, accelerations [n, 2]) of n_periods of the steady state sampled at fs."""
    from ...models.solve import steady_state
    from ...solvers.monolithic import SolverSettings

    T = 2 * math.pi / omega
    if settle_periods is None:
        ss = steady_state(base, tmd, omega, settings=SolverSettings(max_periods_window=80))
        z0, t0 = ss.state, 0.0
    else:  # the play model's companion orbit, then a fixed number of settling periods
        from ...models.solve import companion_start

        ss = None
        z0, t0 = companion_start(base, tmd, omega, SolverSettings()), settle_periods * T
    t = np.arange(0.0, n_periods * T, 1.0 / fs)
    atol = None
    if rtol > 1e-9:
        from ...models.solve import integrator_atol

        atol = integrator_atol(base, tmd, omega, SolverSettings())
    z, acc = solver_samples(base, tmd, omega, z0, t + t0, rtol, atol, t_end=t0 + n_periods * T)
    return t, z, acc, ss


def solver_samples(
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: ndarray,
    times: ndarray,
    rtol: float,
    atol: ndarray | None = None,
    t_end: float | None = None,
) -> tuple[ndarray, ndarray]:
    """(states, accelerations [n, 2]) at ``times`` of the motion from ``z0`` at t = 0 (the forcing's
    phase 0): the project's solver (``models.solve.simulate`` to ``t_end``, default times[-1]); the
    accelerations xdd, ydd are the kernels' right-hand side at the sample times (contact spikes of the
    play chain included, point-sampled like a real ADC). The steady benchmarks' one simulator."""
    from ...models.solve import simulate
    from ...physics.kernels import rhs
    from ...physics.params import pack

    t_end = float(times[-1]) if t_end is None else t_end
    _, z = simulate(base, tmd, omega, t_end, z0=z0, sample_times=times, rtol=rtol, atol=atol)
    p = pack(base, tmd, omega)
    dz = np.empty(6)
    acc = np.empty((times.size, 2))
    for i in range(times.size):
        rhs(times[i], z[i], p, dz)
        acc[i] = dz[1], dz[3]
    return z, acc


def make_system_dataset(
    folder: Path,
    hidden: dict,
    seed: int,
    case: int = 1,
    n_records: int = 4,
    frc: bool = True,
    n_periods: int = N_PERIODS,
    n_frc: int = 1,
) -> None:
    """Write one system-level dataset (time records + FRC) with the hidden effects ``hidden``;
    ``n_frc`` FRCs (with ``frc``): the first at FRC_FORCE, the others at FRC_FORCE / 2, / 3, ...
    (two force levels, as a lab takes them to see amplitude dependence)."""
    from ...physics.params import BaseParams

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    nom = nominal(case)
    tmd = true_tmd(nom, hidden)
    alpha = hidden.get("force_error", 0.0)
    b = hidden.get("sensor_offset", 0.0)
    omegas = np.sort(rng.choice(np.arange(16.0, 24.01, 0.5), n_records, replace=False))
    forces = np.round(rng.uniform(100.0, 300.0, n_records), 0)
    recs = []
    for w, F in zip(omegas, forces):
        base = BaseParams(**{**nom["base"], "force_amplitude": F * (1 + alpha)})
        t, z, acc, _ = steady_record(base, tmd, float(w), n_periods)
        cols = {"t": t, "force": F * np.cos(w * t), "x": z[:, 0] + b, "y": z[:, 2], "xdd": acc[:, 0], "ydd": acc[:, 1]}
        for k in ("force", "x", "y", "xdd", "ydd"):
            rms = float(np.sqrt(np.mean((cols[k] - (b if k == "x" else 0.0)) ** 2)))
            cols[k] = cols[k] + rng.normal(0.0, rng.uniform(0.005, 0.02) * rms, t.size)
        name = f"w{w:g}_F{F:g}N.csv"
        write_record(folder / name, cols, fmt="%.8g")
        recs.append({"file": name, "omega": float(w), "force_amplitude": float(F)})
    if frc:
        from ...models.solve import steady_state
        from ...solvers.monolithic import SolverSettings

        for j in range(n_frc):
            amp = FRC_FORCE / (j + 1)
            base = BaseParams(**{**nom["base"], "force_amplitude": amp * (1 + alpha)})
            xm = (
                np.array(
                    [
                        steady_state(base, tmd, float(w), settings=SolverSettings(max_periods_window=80)).amplitude
                        for w in FRC_OMEGAS
                    ]
                )
                + b
            )
            xm = xm * (1 + rng.normal(0.0, FRC_NOISE, xm.size))
            name = "frc.csv" if j == 0 else f"frc_{amp:g}N.csv"
            write_record(folder / name, {"omega": FRC_OMEGAS, "force_amplitude": np.full(xm.size, amp), "x_max": xm})
            recs.append({"file": name})
    meta = {
        "level": "system",
        "description": "withheld-effect benchmark dataset (system level, simulated rig)",
        "nominal": nom,
        "records": recs,
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
