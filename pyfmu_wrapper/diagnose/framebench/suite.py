"""``make-benchmark --suite frame`` (issue 41): shear frames with a TMD or TMDI, measured by accelerometers
under transient forces, in the dataset format of ``/work/notes/frame_contract.md`` (docs/diagnose.md).

Per dataset, drawn with the seed (every number below is the generator's, nothing is tuned to a result):

* **Nominal**: 3 or 5 storeys (half each); a storey mass m0 log-uniform in 50-500 kg, each storey
  m0 x U(0.9, 1.1) (within 50-500 kg); stiffnesses k0 x U(0.9, 1.1) per storey, k0 scaled so that the
  bare frame's first mode lies at f1 ~ U(1, 5) Hz; storey dampers stiffness-proportional for a first-mode
  damping ratio U(1, 3) %, each x U(0.9, 1.1); the force on the top storey (half) or another storey;
  a TMD on the top storey of mass U(2, 5) % of the frame's mass, inertance U(0, 20) % of its mass
  (ideal inerter), its inerter to its own storey or, one dataset in three (a TMDI), to the ground or a
  lower storey (a lower storey when the truth changes the TMD mass or the inertance: with the inerter to
  the ground the two are one parameter, m + I); tuned to the first mode (frequency ratio 1 / (1 + mu), damping ratio
  sqrt(3 mu / (8 (1 + mu)^3)), mu the absorber's inertia over the frame's first modal mass). Values
  rounded to 4 significant digits (the truth uses the rounded values).
* **Records**: 2-3 of distinct kinds from linear sweep, log sweep (0.6 f1 to U(1.1, 1.5) f2 or down),
  band-limited random force (0.5 f1 to 1.3 f2, 80 sines) and hammer impulses (3-8 hits at least 1.5 s
  apart, half-sines of U(3, 8) ms but at least ``HAMMER_SAMPLES`` samples of the record, only at rates of
  400 Hz and more), each U(20, 60) s; sampling 200, 256, 400, 500, 512 or 1000 Hz (one rate per dataset),
  simulated on a fine grid of at least 2 kHz. Forces: sweeps of amplitude
  U(0.3, 1) % of the frame's weight, random forces of that rms x 0.6, hammer peaks U(5, 15) %.
* **Channels**: ``t, force`` and accelerations ``x<i>dd`` on every storey (half) or on a random subset of
  at least two storeys with the top one, ``ydd`` one dataset in three; white noise of U(0.5, 2) % of the
  channel's rms (U(0.3, 1) % on the force) per channel and record, added after the acquisition.
* **Acquisition**: one dataset in three declares ``all: {filter: ...}`` (Butterworth or Bessel, order
  2-8, cut-off U(0.25, 0.45) fs), which the generator applies on the fine grid (the one filter builder,
  :func:`..acquisition.analog_lowpass`, through ``scipy.signal.lsim``).

Classes (default 40: 8 clean, 16 singles, 8 pairs, 8 out-of-vocabulary): the singles cycle over the
vocabulary of the frame unit (``IN_VOCAB``: element at random: a storey, the TMD, its link, the force,
a measured acceleration channel) with sizes ``SIZES``; pairs are two distinct effects (their sizes
drawn the same way); the out-of-vocabulary kinds (``OOV``) are none of the vocabulary's. Labels,
sizes, conditions and ``visible_chi2`` (chi-square of the noise-free difference between the truth and
the nominal over every record and channel, in units of each channel's noise) go to manifest.json only.
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from ...models.frame_model.effects import LINEAR, VOCABULARY
from ..suites import counts, write_manifest
from .truth import FineForce, FrameTruth, acquire, channels, hammer_force, random_force, sweep_force

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

#: the frame unit's vocabulary this suite draws (effect -> the parameter it is scored by): the effects the
#: linear frame diagnosis fits (:data:`pyfmu_wrapper.models.frame_model.effects.LINEAR`); friction and play
#: are not drawn for frames
IN_VOCAB: dict[str, str] = {e: VOCABULARY[e].params[0].name for e in LINEAR}
#: sizes: (low, high) share of the element's nominal value, log-uniform, and the sign: +1, -1 or 0 (either);
#: inertance as a share of the TMD mass (the nominal inertance may be near 0); gains are the gain itself
SIZES: dict[str, tuple[float, float, int]] = {
    "storey_mass": (0.05, 0.20, 0),
    "storey_stiffness": (0.05, 0.30, -1),  # a storey's stiffness loss
    "storey_damping": (0.50, 2.00, +1),
    "tmd_mass": (0.05, 0.20, 0),
    "tmd_stiffness": (0.05, 0.15, 0),
    "viscous": (0.30, 0.80, 0),
    "inertance": (0.03, 0.10, 0),  # of the TMD mass; a loss only where it leaves >= 20 % of the inertance
    "force_error": (0.03, 0.10, 0),
    "channel_gain": (0.03, 0.10, 0),
}
#: out-of-vocabulary kinds and their sizes (see :func:`_oov`)
OOV: dict[str, str] = {
    "cubic_storey": "a hardening storey spring k3 d^3: tangent stiffness +30-90 % at the storey's peak drift",
    "storey_friction": "dry friction in a storey (a slipping brace): 5-15 % of the storey's peak elastic force",
    "secondary_absorber": "an unlisted mass (1-3 % of the frame) on a storey, tuned to 0.9-1.1 f2, 2-5 % damping",
    # soft enough that its sway mode lies in the records' band: a foundation 5-20 times stiffer than storey 1
    # (seed 17's fr016 with the sizes of the first version) only acts as a spring in series with storey 1 there,
    # which storey_stiffness at storey 1 explains to the noise -- in the vocabulary in all but name
    "flexible_foundation": "a foundation mass (1-3 m1) on a spring (1.5-4 k1) and damper (5-10 %) under storey 1",
    "channel_clipping": "one acceleration channel clipped at 50-80 % of its peak (ADC range)",
    "channel_delay": "one channel (acceleration or force) delayed by 3-10 samples, undeclared",
    "stiffness_drift": "a storey's stiffness falling linearly by 10-25 % through the test",
}
RATES = (200.0, 256.0, 400.0, 500.0, 512.0, 1000.0)
KINDS = ("sweep_lin", "sweep_log", "random", "hammer")
#: a hammer pulse spans at least this many samples of its record, and hammer records are drawn only at
#: rates >= HAMMER_MIN_FS: what the force did between its samples is unknown to the diagnosis, and a
#: half-sine over N samples read as linear between them misstates its impulse by ~(pi / N)^2 / 12
#: (3 % at N = 5: seed 17's clean fr030, 10 ms at 500 Hz, was diagnosed with storey effects; 0.8 % at 10)
HAMMER_SAMPLES, HAMMER_MIN_FS = 10, 400.0
FINE_HZ = 2000.0  #: the truth's grid is at least this fine
RECORD_SECONDS = (20, 60)  #: each record's length [s], a whole number drawn uniformly in this range
G = 9.81


def _sig(x: float) -> float:
    return float(f"{x:.4g}")


def _log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def modal_frequencies(masses: list[float], stiffnesses: list[float]) -> np.ndarray:
    """Undamped natural frequencies [Hz] of the bare shear frame (ascending)."""
    from scipy.linalg import eigh

    n = len(masses)
    K = np.zeros((n, n))
    for i, k in enumerate(stiffnesses):
        K[i, i] += k
        if i > 0:
            K[i - 1, i - 1] += k
            K[i, i - 1] -= k
            K[i - 1, i] -= k
    w2 = eigh(K, np.diag(masses), eigvals_only=True)
    return np.sqrt(np.abs(w2)) / (2 * math.pi)


def draw_nominal(rng: np.random.Generator, n: int) -> dict[str, Any]:
    """The nominal frame and TMD (module docstring), as dataset.yaml writes them."""
    from scipy.linalg import eigh

    m0 = _log_uniform(rng, 50.0, 500.0)
    masses = [_sig(float(np.clip(m0 * rng.uniform(0.9, 1.1), 50.0, 500.0))) for _ in range(n)]
    kshape = [float(rng.uniform(0.9, 1.1)) for _ in range(n)]
    f1 = float(rng.uniform(1.0, 5.0))
    scale = (f1 / modal_frequencies(masses, kshape)[0]) ** 2
    stiff = [_sig(scale * k) for k in kshape]
    zeta = float(rng.uniform(0.01, 0.03))
    beta = 2 * zeta / (2 * math.pi * modal_frequencies(masses, stiff)[0])
    damp = [_sig(beta * k * rng.uniform(0.9, 1.1)) for k in stiff]
    force_storey = n if rng.uniform() < 0.5 else int(rng.integers(1, n))
    # the TMD: tuned to the first mode by its modal mass at the top storey
    K = np.diag([0.0] * n)
    for i, k in enumerate(stiff):
        K[i, i] += k
        if i > 0:
            K[i - 1, i - 1] += k
            K[i, i - 1] -= k
            K[i - 1, i] -= k
    _, V = eigh(K, np.diag(masses))
    phi = V[:, 0] / V[-1, 0]
    modal_mass = float(phi @ np.diag(masses) @ phi)
    mu_m = float(rng.uniform(0.02, 0.05))
    m = _sig(mu_m * sum(masses))
    inertance = _sig(float(rng.uniform(0.0, 0.2)) * m)
    tmdi = rng.uniform() < 1.0 / 3.0
    to = int(rng.integers(0, n)) if tmdi else n  # 0: the ground; 1..n-1: a lower storey
    mu = (m + inertance) / modal_mass
    wt = 2 * math.pi * modal_frequencies(masses, stiff)[0] / (1 + mu)
    zt = math.sqrt(3 * mu / (8 * (1 + mu) ** 3))
    tmd = {
        "storey": n,
        "inerter_to": to,
        "mass": m,
        "stiffness": _sig((m + inertance) * wt**2),
        "damping": _sig(2 * zt * (m + inertance) * wt),
        "inerter": "ideal",
        "inertance": inertance,
    }
    frame = {"storeys": n, "mass": masses, "stiffness": stiff, "damping": damp, "force_storey": force_storey}
    return {"frame": frame, "tmd": tmd, "f1_target": f1, "zeta": zeta}


def draw_effect(rng: np.random.Generator, effect: str, nom: dict, accel: list[str]) -> dict[str, Any]:
    """One in-vocabulary truth {effect, element, param, value} of a size drawn from ``SIZES``."""
    lo, hi, sign = SIZES[effect]
    share = _log_uniform(rng, lo, hi)
    s = sign if sign else (1 if rng.uniform() < 0.5 else -1)
    fr, tmd = nom["frame"], nom["tmd"]
    eff = VOCABULARY[effect]
    if effect.startswith("storey_"):
        j = int(rng.integers(1, fr["storeys"] + 1))
        key = {"storey_mass": "mass", "storey_stiffness": "stiffness", "storey_damping": "damping"}[effect]
        element, value = eff.at(j), s * share * fr[key][j - 1]
    elif effect in ("tmd_mass", "tmd_stiffness"):
        element, value = eff.element, s * share * tmd[effect[4:]]
    elif effect == "viscous":
        element, value = eff.element, s * share * tmd["damping"]
    elif effect == "inertance":
        value = share * tmd["mass"]
        if s < 0 and value <= 0.8 * tmd["inertance"]:
            value = -value
        element = eff.element
    elif effect == "force_error":
        element, value = eff.element, s * share
    elif effect == "channel_gain":
        element, value = eff.at(str(rng.choice(accel))), s * share
    else:
        raise ValueError(f"unknown effect {effect!r}")
    return {"effect": effect, "element": element, "param": IN_VOCAB[effect], "value": _sig(value)}


def plan(rng: np.random.Generator, n: int, n_clean: int, n_pair: int, n_oov: int) -> list[tuple[str, list, str | None]]:
    """[(class, effect names, oov kind)] shuffled; singles cycle over the vocabulary from a random start,
    OOV kinds likewise."""
    eff, kinds = list(IN_VOCAB), list(OOV)
    items: list[tuple[str, list, str | None]] = [("clean", [], None)] * n_clean
    start = int(rng.integers(len(eff)))
    for j in range(n - n_clean - n_pair - n_oov):
        items.append(("single", [eff[(start + j) % len(eff)]], None))
    for _ in range(n_pair):
        items.append(("pair", [str(e) for e in rng.choice(eff, 2, replace=False)], None))
    start = int(rng.integers(len(kinds)))
    for j in range(n_oov):
        items.append(("oov", [], kinds[(start + j) % len(kinds)]))
    return [items[i] for i in rng.permutation(len(items))]


def _truth(nom: dict, effects: list[dict]) -> tuple[FrameTruth, float, dict[str, float]]:
    """(true structure, force gain g, channel gains) of the nominal with the in-vocabulary effects."""
    fr, tmd = nom["frame"], dict(nom["tmd"])
    masses, stiff, damp = list(fr["mass"]), list(fr["stiffness"]), list(fr["damping"])
    g, gains = 0.0, {}
    for e in effects:
        name, el, v = e["effect"], e["element"], e["value"]
        if name.startswith("storey_"):
            j = int(el.split()[1]) - 1
            {"storey_mass": masses, "storey_stiffness": stiff, "storey_damping": damp}[name][j] += v
        elif name in ("tmd_mass", "tmd_stiffness"):
            tmd[name[4:]] += v
        elif name == "viscous":
            tmd["damping"] += v
        elif name == "inertance":
            tmd["inertance"] += v
        elif name == "force_error":
            g = v
        else:
            gains[el.split()[1]] = v
    return FrameTruth(masses, stiff, damp, int(fr["force_storey"]), tmd), g, gains


def _nominal_truth(nom: dict) -> FrameTruth:
    return _truth(nom, [])[0]


def _records_plan(rng: np.random.Generator, nom: dict, fs: float) -> list[dict[str, Any]]:
    fr = nom["frame"]
    f = modal_frequencies(fr["mass"], fr["stiffness"])
    weight = G * (sum(fr["mass"]) + nom["tmd"]["mass"])
    n_rec = int(rng.integers(2, 4))
    out = []
    kinds = KINDS if fs >= HAMMER_MIN_FS else tuple(k for k in KINDS if k != "hammer")
    for kind in (str(k) for k in rng.choice(kinds, n_rec, replace=False)):
        T = float(rng.integers(RECORD_SECONDS[0], RECORD_SECONDS[1] + 1))
        r: dict[str, Any] = {"kind": kind, "seconds": T}
        if kind.startswith("sweep"):
            lo, hi = 0.6 * f[0], min(float(rng.uniform(1.1, 1.5)) * f[1], fs / 8)
            up = rng.uniform() < 0.5
            r.update(f0=round(lo if up else hi, 3), f1=round(hi if up else lo, 3))
            r["amplitude"] = _sig(float(rng.uniform(0.003, 0.01)) * weight)
        elif kind == "random":
            r.update(f_lo=round(0.5 * f[0], 3), f_hi=round(min(1.3 * f[1], fs / 8), 3))
            r["rms"] = _sig(0.6 * float(rng.uniform(0.003, 0.01)) * weight)
        else:
            r.update(
                n_hits=int(rng.integers(3, 9)),
                width=round(max(float(rng.uniform(0.003, 0.008)), HAMMER_SAMPLES / fs), 4),
                peak=_sig(float(rng.uniform(0.05, 0.15)) * weight),
            )
        out.append(r)
    return out


def _force(rng: np.random.Generator, r: dict, t: np.ndarray) -> np.ndarray:
    T = r["seconds"]
    if r["kind"] == "sweep_lin":
        return sweep_force(t, T, r["f0"], r["f1"], r["amplitude"], log=False)
    if r["kind"] == "sweep_log":
        return sweep_force(t, T, r["f0"], r["f1"], r["amplitude"], log=True)
    if r["kind"] == "random":
        return random_force(rng, t, T, r["f_lo"], r["f_hi"], r["rms"])
    F, hits = hammer_force(rng, t, r["n_hits"], r["peak"], r["width"], T)
    r["hits"] = [round(h, 4) for h in hits]
    return F


def _oov(rng: np.random.Generator, kind: str, nom: dict, truth: FrameTruth, nominal_sims: list, names: list) -> dict:
    """Add the out-of-vocabulary kind to ``truth`` (structure) or return its measurement part
    ({"clips": ..} / {"delays": ..}); sizes relative to the nominal response where they depend on it."""
    fr = nom["frame"]
    n = fr["storeys"]
    j = int(rng.integers(1, n + 1))
    spec: dict[str, Any] = {"kind": kind}
    if kind in ("cubic_storey", "storey_friction"):
        d_max = max(float(np.max(np.abs(s["q"][j - 1] - (s["q"][j - 2] if j > 1 else 0.0)))) for s in nominal_sims)
        k = fr["stiffness"][j - 1]
        if kind == "cubic_storey":
            r = float(rng.uniform(0.1, 0.3))  # 3 k3 d^2 = 3 r k at the peak drift
            truth.cubic = {"storey": j, "k3": _sig(r * k / d_max**2)}
            spec.update(storey=j, k3=truth.cubic["k3"], tangent_increase_at_peak=round(3 * r, 3))
        else:
            r = float(rng.uniform(0.05, 0.15))
            truth.friction = {"storey": j, "force": _sig(r * k * d_max)}
            spec.update(storey=j, friction_force=truth.friction["force"], share_of_peak_force=round(r, 3))
    elif kind == "secondary_absorber":
        f = modal_frequencies(fr["mass"], fr["stiffness"])
        ms = float(rng.uniform(0.01, 0.03)) * sum(fr["mass"])
        ws = 2 * math.pi * f[1] * float(rng.uniform(0.9, 1.1))
        z = float(rng.uniform(0.02, 0.05))
        truth.secondary = {
            "storey": j,
            "mass": _sig(ms),
            "stiffness": _sig(ms * ws**2),
            "damping": _sig(2 * z * ms * ws),
        }
        spec.update(truth.secondary)
    elif kind == "flexible_foundation":
        mf = float(rng.uniform(1.0, 3.0)) * fr["mass"][0]
        kf = float(rng.uniform(1.5, 4.0)) * fr["stiffness"][0]
        z = float(rng.uniform(0.05, 0.10))
        total = mf + sum(fr["mass"])
        truth.foundation = {"mass": _sig(mf), "stiffness": _sig(kf), "damping": _sig(2 * z * math.sqrt(kf * total))}
        spec.update(truth.foundation)
    elif kind == "channel_clipping":
        ch = str(rng.choice([c for c in names if c.endswith("dd")]))
        spec.update(channel=ch, level_share=round(float(rng.uniform(0.5, 0.8)), 3))
    elif kind == "channel_delay":
        ch = str(rng.choice(names))
        spec.update(channel=ch, samples=int(rng.integers(3, 11)))
    elif kind == "stiffness_drift":
        spec.update(storey=j, total_share=round(-float(rng.uniform(0.10, 0.25)), 4))
    else:
        raise ValueError(f"unknown out-of-vocabulary kind {kind!r}")
    return spec


def write_dataset(path: Path, rng: np.random.Generator, effects: list[str], oov_kind: str | None) -> dict[str, Any]:
    """Draw and write one dataset (dataset.yaml and its record CSVs) to ``path``; returns its manifest row
    (without name and class)."""
    from ..records import write_record

    n = 3 if rng.uniform() < 0.5 else 5
    nom = draw_nominal(rng, n)
    if nom["tmd"]["inerter_to"] == 0 and {"tmd_mass", "inertance"} & set(effects):
        # an ideal inerter to the fixed ground adds its inertance to the TMD mass's: m + I, the same
        # equations whichever changed; a truth no data can tell from the other is not drawn
        nom["tmd"]["inerter_to"] = int(rng.integers(1, n))
    fs = float(rng.choice(RATES))
    step = int(math.ceil(FINE_HZ / fs))
    if rng.uniform() < 0.5:
        accel = [f"x{i}dd" for i in range(1, n + 1)]
    else:
        k = int(rng.integers(2, n))  # 2..n-1 storeys, the top one among them
        accel = [f"x{i}dd" for i in sorted(rng.choice(np.arange(1, n), k - 1, replace=False).tolist() + [n])]
    if rng.uniform() < 1.0 / 3.0:
        accel.append("ydd")
    acq = None
    if rng.uniform() < 1.0 / 3.0:
        acq = {
            "all": {
                "filter": {
                    "type": str(rng.choice(["butterworth", "bessel"])),
                    "order": int(rng.integers(2, 9)),
                    "cutoff_hz": round(float(rng.uniform(0.25, 0.45)) * fs, 1),
                }
            }
        }
    filt = acq["all"]["filter"] if acq else None
    truths = [draw_effect(rng, e, nom, accel) for e in effects]
    if len(truths) == 2 and truths[0]["element"] == truths[1]["element"] and truths[0]["effect"] == truths[1]["effect"]:
        raise AssertionError("a pair of one effect")  # plan() draws two distinct effects
    rec_plan = _records_plan(rng, nom, fs)
    truth, g, gains = _truth(nom, truths)
    nominal = _nominal_truth(nom)
    forces, grids, nominal_sims = [], [], []
    for r in rec_plan:
        t = np.arange(0.0, r["seconds"], 1.0 / (fs * step))
        F = _force(rng, r, t)
        forces.append(F)
        grids.append(t)
        hmax = r["width"] / 4 if r["kind"] == "hammer" else 0.0
        nominal_sims.append(nominal.simulate(FineForce(t[1], F), t, hmax=hmax))
    spec = _oov(rng, oov_kind, nom, truth, nominal_sims, accel + ["force"]) if oov_kind else None
    dynamic = bool(effects and set(effects) - {"channel_gain"}) or (
        spec is not None and spec["kind"] not in ("channel_clipping", "channel_delay")
    )
    path.mkdir(parents=True, exist_ok=True)
    recs, meta, chi2 = [], [], 0.0
    for i, (r, t, F, nsim) in enumerate(zip(rec_plan, grids, forces, nominal_sims)):
        hmax = r["width"] / 4 if r["kind"] == "hammer" else 0.0
        if spec is not None and spec["kind"] == "stiffness_drift":
            R = len(rec_plan)
            truth.drift = {"storey": spec["storey"], "share": spec["total_share"] / R, "T": r["seconds"]}
            truth.drift["start"] = spec["total_share"] * i / R
        tsim = truth.simulate(FineForce(t[1], F / (1.0 + g)), t, hmax=hmax) if dynamic else nsim
        true_sig = channels(truth, tsim, accel)
        true_sig["force"] = F
        nom_sig = channels(nominal, nsim, accel)
        nom_sig["force"] = F
        clips, delays = {}, {}
        if spec is not None and spec["kind"] == "channel_clipping":
            c = spec["channel"]
            peak = max(float(np.max(np.abs(channels(truth, s, [c])[c]))) for s in nominal_sims)
            clips[c] = spec["level_share"] * peak  # the channel's range: a share of its peak over the test
        if spec is not None and spec["kind"] == "channel_delay":
            delays[spec["channel"]] = spec["samples"] / fs
        m = acquire(true_sig, t, step, filt, gains, delays, clips)
        m_nom = acquire(nom_sig, t, step, filt)
        noise = {c: float(rng.uniform(0.005, 0.02)) for c in accel}
        noise["force"] = float(rng.uniform(0.003, 0.01))
        cols = {"t": m["t"], "force": m["force"]}
        cols.update({c: m[c] for c in accel})
        for c in ["force"] + accel:
            sd = noise[c] * float(np.std(m[c]) or 1.0)
            chi2 += float(np.sum(((m[c] - m_nom[c]) / sd) ** 2))
            cols[c] = m[c] + rng.normal(0.0, sd, m[c].size)
        name = f"rec_{i}.csv"
        write_record(path / name, cols)
        recs.append({"file": name, "kind": "transient"})
        meta.append({**r, "noise": {c: round(v, 5) for c, v in noise.items()}})
    doc: dict[str, Any] = {
        "level": "system",
        "description": f"{n}-storey shear frame with a {'TMDI' if nom['tmd']['inerter_to'] != n else 'TMD-inerter'}, "
        "transient records (make-benchmark --suite frame)",
        "nominal": {"frame": nom["frame"], "tmd": nom["tmd"]},
    }
    if acq:
        doc["acquisition"] = acq
    doc["records"] = recs
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    f = modal_frequencies(nom["frame"]["mass"], nom["frame"]["stiffness"])
    return {
        "storeys": n,
        "truth": truths,
        "oov_kind": oov_kind,
        "oov": spec,
        "visible_chi2": round(chi2, 1),
        "fs": fs,
        "channels": ["force"] + accel,
        "acquisition": acq,
        "tmdi": nom["tmd"]["inerter_to"] != n,
        "frame_modes_hz": [round(float(x), 3) for x in f],
        "first_mode_damping": round(nom["zeta"], 4),
        "records": meta,
    }


def make_frame_benchmark(
    out: Path,
    n: int | None = None,
    seed: int = 1,
    n_clean: int | None = None,
    n_pair: int | None = None,
    n_oov: int | None = None,
    progress: Callable[..., Any] | None = None,
) -> list[dict[str, Any]]:
    """Write the frame suite to ``out``: one folder per dataset (fr000, ...) and manifest.json, rewritten
    after every dataset (a stopped run leaves a scorable part; ``complete`` says whether it is whole).
    ``progress(row)`` gets the public part of each row (name, seconds), never the labels."""
    nc, ns, npair, no = counts("frame", n, n_clean, n_pair, n_oov)
    rng = np.random.default_rng(seed)
    man: list[dict[str, Any]] = []
    items = plan(rng, nc + ns + npair + no, nc, npair, no)
    for i, (cls, effects, oov_kind) in enumerate(items):
        t0 = time.perf_counter()
        name = f"fr{i:03d}"
        sub = np.random.default_rng(int(rng.integers(1 << 31)))
        row = {"name": name, "class": cls, **write_dataset(out / name, sub, effects, oov_kind)}
        row["seconds"] = round(time.perf_counter() - t0, 2)
        man.append(row)
        doc = {"suite": "frame", "seed": seed, "complete": i == len(items) - 1, "datasets": man}
        write_manifest(out, doc)
        if progress:
            progress({"dataset": name, "seconds": row["seconds"]})
    return man
