"""The field-like system suite of ``make-benchmark`` (docs/diagnose-evidence.md, "Check 1").

Per dataset, drawn with the seed: paper Case 1, 2 or 3 nominal with c = 10 or 15 N s/m (ideal
inerter); sampling rate 256 Hz-5 kHz; an acquisition chain (none, anti-alias filters on the
accelerometers only, or on every channel: Butterworth or Bessel, order 2-8, cut-off 0.25-0.45 fs;
sometimes a load-cell delay) declared in ``dataset.yaml`` under ``acquisition``; 3-6 time records
at distinct frequencies (15-25 rad/s, on a 0.01 Hz grid) and forces (100-300 N), each a non-whole
number (8.1-15.9) of periods long, starting at an arbitrary phase; noise 0.3-2 % on the force
channel and 0.5-3 % on the others (per channel and record, added after the filter); about one in
five datasets acceleration-only (t, force, xdd, ydd); one or two stepped-sine FRC records
(15-25 rad/s in 0.5 rad/s steps, 100-250 N, swept up or down, 0.3-1 % noise on x_max).

Classes: clean, single in-vocabulary effects (cycling over the 11 names of ``IN_VOCAB``), pairs
and out-of-vocabulary effects (:mod:`sysbench_oov`). Labels, severities, the drawn conditions and
the visibility of the truth (chi-square of the noise-free difference from the nominal, all records)
go to ``manifest.json`` only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..suites import counts, write_manifest
from .bench import RANGES as BASE_RANGES
from .bench import has_cubic, nominal, true_values
from .effects import VOCAB

RANGES = dict(
    BASE_RANGES,
    base_mass=(2.0, 8.0),
    base_stiffness=(800.0, 3200.0),
    base_damping=(10.0, 50.0),
    tmd_stiffness=(80.0, 320.0),
)
SIGNED = VOCAB.signed()
TRUTH_KEY = VOCAB.truth_keys(RANGES)
OOV_RANGES = {
    "quadratic_damping": (1.0, 20.0),
    "base_friction": (1.0, 10.0),
    "base_hardening": (5e4, 5e5),
    "x_gain": (0.03, 0.10),
    "accel_gain": (0.03, 0.10),
    # held out (oov.HELD_OUT): k2 |u| is 2.5-25 % of k = 4e3 N/m at a 1 cm deflection; C2 |xd| is
    # 3-30 % of C = 100 N s/m at a base velocity of 0.1 m/s
    "asymmetric_spring": (1e4, 1e5),
    "base_drag": (30.0, 300.0),
}
OOV_SIGNED = {"x_gain", "accel_gain"}
FS_CHOICES = (256.0, 500.0, 512.0, 1000.0, 1024.0, 2000.0, 2048.0, 2500.0, 2560.0, 5000.0)
VISIBLE_CHI2 = 100.0  #: a truth is "visible" when the noise-free difference has chi-square above this


def in_vocab() -> list:
    return [e for e in RANGES if e != "cubic" or has_cubic()]


def draw_value(rng: np.random.Generator, lo_hi: Sequence[float], signed: bool, strength: float | None = None) -> float:
    lo, hi = lo_hi
    u = rng.uniform() if strength is None else strength
    v = float(lo * (hi / lo) ** u)
    return -v if signed and rng.uniform() < 0.5 else v


def true_parts(nom: dict, hidden: dict, oov: dict) -> dict:
    true = true_values(nom, hidden)
    return {
        "base": true["base"],
        "tmd": true["tmd"],
        "force_error": hidden.get("force_error", 0.0),
        "sensor_offset": hidden.get("sensor_offset", 0.0),
        "oov": dict(oov),
    }


def draw_acquisition(rng: np.random.Generator, fs: float, accel_only: bool) -> dict[str, Any] | None:
    mode = rng.choice(["none", "accel", "all"], p=[0.3, 0.3, 0.4])
    acq: dict[str, dict] = {}
    if mode != "none":
        typ = str(rng.choice(["butterworth", "bessel"]))
        filt = {
            "type": typ,
            "order": int(rng.integers(2, 9)),
            "cutoff_hz": round(float(rng.uniform(0.25, 0.45)) * fs, 1),
        }
        chans = (
            ["xdd", "ydd"]
            if mode == "accel"
            else (["force", "xdd", "ydd"] if accel_only else ["force", "x", "y", "xdd", "ydd"])
        )
        for c in chans:
            acq[c] = {"filter": dict(filt)}
    if rng.uniform() < 0.25:  # a load-cell conditioner delay
        acq.setdefault("force", {})["delay_s"] = round(float(rng.uniform(1e-4, 1e-3)), 6)
    if mode == "all" and "delay_s" not in acq.get("force", {}) and not accel_only:
        acq = {"all": {"filter": acq["x"]["filter"]}}
    return acq or None


def draw_dataset(
    rng: np.random.Generator, hidden: dict[str, Any], oov: dict[str, Any], accel_only: bool | None = None
) -> dict[str, Any]:
    case = int(rng.integers(1, 4))
    c = float(rng.choice([10.0, 15.0]))
    nom = nominal(case, c)
    if "mass_split" in hidden:  # keep m and I positive: -I/2 < dI < m/2
        I0, m0 = nom["tmd"]["inertance"], nom["tmd"]["mass"]
        hidden["mass_split"] = float(np.clip(hidden["mass_split"], -0.5 * I0, 0.5 * m0))
    if accel_only is None:
        accel_only = rng.uniform() < 0.2 and "sensor_offset" not in hidden and "x_gain" not in oov
    fs = float(rng.choice(FS_CHOICES))
    n_rec = int(rng.integers(3, 7))
    fhz = (
        np.sort(
            rng.choice(np.arange(math.ceil(1500 / (2 * math.pi)), int(2500 / (2 * math.pi)) + 1), n_rec, replace=False)
        )
        / 100.0
    )
    recs = []
    for f in fhz:
        periods = int(rng.integers(8, 16)) + float(rng.uniform(0.1, 0.9))
        noise = {"force": float(rng.uniform(0.003, 0.02))}
        noise.update({ch: float(rng.uniform(0.005, 0.03)) for ch in ("x", "y", "xdd", "ydd")})
        recs.append(
            {
                "frequency_hz": float(f),
                "omega": 2 * math.pi * float(f),
                "force": float(5 * round(rng.uniform(100, 300) / 5)),
                "periods": periods,
                "phase": float(rng.uniform(0, 2 * math.pi)),
                "noise": noise,
            }
        )
    frcs = []
    for _ in range(int(rng.integers(1, 3))):
        d = str(rng.choice(["up", "down"]))
        om = np.arange(15.0, 25.001, 0.5)
        frcs.append(
            {
                "force": float(10 * round(rng.uniform(100, 250) / 10)),
                "direction": d,
                "omegas": (om if d == "up" else om[::-1]).tolist(),
                "noise": float(rng.uniform(0.003, 0.01)),
            }
        )
    return {
        "case": case,
        "nominal": nom,
        "fs": fs,
        "accel_only": bool(accel_only),
        "acquisition": draw_acquisition(rng, fs, accel_only),
        "records": recs,
        "frc": frcs,
        "truth": true_parts(nom, hidden, oov),
    }


def plan(
    rng: np.random.Generator,
    n: int | None = None,
    n_clean: int | None = None,
    n_pair: int | None = None,
    n_oov: int | None = None,
    held_out_oov: bool = False,
) -> list[Any]:
    """[(class, hidden, oov)] in a shuffled order; the OOV kinds are the tuned ones (``oov.OOV_EFFECTS``)
    or, with ``held_out_oov``, the held-out ones (``oov.HELD_OUT``)."""
    from .oov import HELD_OUT, OOV_EFFECTS

    kinds = HELD_OUT if held_out_oov else OOV_EFFECTS

    nc, ns, npair, no = counts("system", n, n_clean, n_pair, n_oov)
    eff = in_vocab()
    items: list[tuple[str, dict, dict]] = [("clean", {}, {})] * nc
    start = int(rng.integers(len(eff)))
    for j in range(ns):
        e = eff[(start + j) % len(eff)]
        items.append(("single", {e: draw_value(rng, RANGES[e], e in SIGNED)}, {}))
    for _ in range(npair):
        e1, e2 = (str(e) for e in rng.choice(eff, 2, replace=False))
        items.append(
            ("pair", {e: draw_value(rng, RANGES[e], e in SIGNED, rng.uniform(0.3, 1.0)) for e in (e1, e2)}, {})
        )
    start = int(rng.integers(len(kinds)))
    for j in range(no):
        e = kinds[(start + j) % len(kinds)]
        o: dict[str, float | str] = {e: draw_value(rng, OOV_RANGES[e], e in OOV_SIGNED)}
        if e == "accel_gain":
            o["accel_gain_channel"] = str(rng.choice(["xdd", "ydd"]))
        items.append(("oov", {}, o))
    return [items[i] for i in rng.permutation(len(items))]


def make_field_benchmark(
    out: Path,
    n: int | None = None,
    seed: int = 1,
    n_clean: int | None = None,
    n_pair: int | None = None,
    n_oov: int | None = None,
    progress: Callable[..., Any] | None = None,
    held_out_oov: bool = False,
) -> list[Any]:
    """Write the suite to ``out`` (one folder per dataset + manifest.json); ``progress(row)`` is
    called with the public part of each row (name, seconds) -- never the labels. ``held_out_oov``:
    the out-of-vocabulary datasets take the held-out kinds (``oov.HELD_OUT``)."""
    import time

    from .field import write_dataset

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    man = []
    for i, (cls, hidden, oov) in enumerate(plan(rng, n, n_clean, n_pair, n_oov, held_out_oov)):
        t0 = time.perf_counter()
        name = f"sys{i:03d}"
        sub = np.random.default_rng(int(rng.integers(1 << 31)))
        spec = draw_dataset(sub, dict(hidden), dict(oov))
        if "mass_split" in hidden:
            hidden["mass_split"] = spec["truth"]["tmd"]["inertance"] - spec["nominal"]["tmd"]["inertance"]
        vis = write_dataset(out / name, spec, sub)
        vis["visible"] = bool(vis["chi2"] > VISIBLE_CHI2)
        oov_names = [k for k in oov if k != "accel_gain_channel"]
        row = {
            "dataset": name,
            "class": cls,
            "case": spec["case"],
            "nominal_damping": spec["nominal"]["tmd"]["damping"],
            "fs": spec["fs"],
            "accel_only": spec["accel_only"],
            "acquisition": spec["acquisition"],
            "n_records": len(spec["records"]),
            "records": [
                {k: r[k] for k in ("frequency_hz", "force", "periods", "phase", "noise")} for r in spec["records"]
            ],
            "frc": [{"force": f["force"], "direction": f["direction"], "noise": f["noise"]} for f in spec["frc"]],
            "hidden": sorted(hidden) + sorted(oov_names),
            "severity": {**hidden, **oov},
            "truth": {TRUTH_KEY[e]: v for e, v in hidden.items()},
            "oov": oov,
            "visibility": vis,
            "seconds": round(time.perf_counter() - t0, 2),
        }
        man.append(row)
        if progress:
            progress({"dataset": name, "seconds": row["seconds"]})
    write_manifest(
        out,
        {
            "suite": "system",
            "generator": "field",
            "seed": seed,
            "held_out_oov": held_out_oov,
            "visible_chi2": VISIBLE_CHI2,
            "datasets": man,
        },
    )
    return man


#: the field-like system suite (:func:`make_field_benchmark`); labels in manifest.json only
make_system_benchmark = make_field_benchmark
