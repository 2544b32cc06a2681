"""``make-benchmark --suite transient``: system-level datasets of transient records under field
conditions (docs/diagnose-evidence.md, "Check 3"), their truths simulated by :mod:`.transient_truth` (its own
right-hand side and ``odeint``, not the project's kernels) and measured as a rig does.

Per dataset (drawn with the seed): nominal paper Case 1/2/3 (c = 10 or 15 N s/m); sampling rate
256-5000 Hz; 3 records of ``seconds`` (default 60 s) of kinds drawn from linear/log sweeps up or
down (1.2-6 Hz, 80-200 N), band-limited random force (1-10 Hz, 40-100 N rms), burst random,
hammer impulses on the base (4 ms, 300-800 N) and free decays from a displaced start; acquisition
none / filters on the accelerometers / on every channel (Butterworth or Bessel, order 2-8,
cut-off 0.25-0.45 fs, declared) and in 25 % a load-cell delay; one dataset in five acceleration-only;
white noise 0.5-2 % of the rms per channel (0.3-1 % on the force).
"""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from ..suites import counts, write_manifest
from .effects import VOCAB

if TYPE_CHECKING:
    from collections.abc import Callable
    from pathlib import Path

    from .transient_truth import Truth

#: in-vocabulary truths: effect -> (Truth keyword, range, signed); the manifest scores each by the
#: vocabulary's truth key (:attr:`~pyfmu_wrapper.physics.effects.Effect.truth_key`)
IN_VOCAB: dict[str, tuple[str, tuple[float, float], bool]] = {
    "viscous": ("dc", (2.0, 30.0), False),
    "friction": ("df", (1.5, 15.0), False),
    "play": ("eps", (1e-4, 1e-3), False),
    "mass_split": ("dI_split", (0.1, 0.8), True),
    "cubic": ("k3", (3e4, 3e5), False),
    "force_error": ("force_gain", (0.02, 0.15), True),
    "sensor_offset": ("x_offset", (3e-4, 3e-3), True),
    "base_mass": ("dM", (2.0, 8.0), True),
    "base_stiffness": ("dK", (800.0, 3200.0), True),
    "base_damping": ("dC", (10.0, 50.0), True),
    "tmd_stiffness": ("dk", (80.0, 320.0), True),
    "tmd_mass": ("dm", (0.2, 0.8), True),
    "inertance": ("dI", (0.1, 0.5), False),
}
#: out-of-vocabulary truths of this suite (Truth keyword, range, signed); the first four were
#: never looked at while the transient diagnosis was tuned (only quadratic damping was)
OOV: dict[str, tuple[str, tuple[float, float], bool]] = {
    "base_friction": ("mu", (2.0, 10.0), False),
    "base_hardening": ("K3", (1e5, 1e6), False),
    "elastic_inerter": ("kb", (2e3, 2e4), False),
    "stiffness_drift": ("drift", (0.05, 0.15), True),
    "asymmetric_spring": ("k2", (2e4, 2e5), True),
    "x_gain": ("x_gain", (0.03, 0.1), True),
    "quadratic_damping": ("c2", (5.0, 30.0), False),
}
RATES = (256.0, 500.0, 1000.0, 1024.0, 2000.0, 2560.0, 4000.0, 5000.0)
#: a truth that escapes (:class:`.transient_truth.TruthEscaped`) is drawn again this many times at
#: most, every change times ESCAPE_SCALE, the records' force and noise draws the same
ESCAPE_TRIES, ESCAPE_SCALE = 6, 0.5
#: the play truth's gear contact damping ci [N s/m], drawn log-uniform (its stiffness is the paper's 2e7 N/m)
PLAY_CI = (0.01, 100.0)
KINDS = ("sweep_lin", "sweep_log", "random", "burst", "hammer", "decay")


def _draw(rng: np.random.Generator, lo_hi: tuple[float, float], signed: bool, strength: float | None = None) -> float:
    lo, hi = lo_hi
    u = rng.uniform() if strength is None else strength
    v = math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))
    return -v if signed and rng.uniform() < 0.5 else v


def plan(
    rng: np.random.Generator, n: int, n_clean: int, n_pair: int, n_oov: int, effects: list[str] | None = None
) -> list[tuple[str, dict, dict]]:
    """The datasets' classes and truths; ``effects``: the in-vocabulary effects drawn (default all)."""
    eff, oov = list(IN_VOCAB) if effects is None else list(effects), list(OOV)
    if n_pair and len(eff) < 2:
        raise ValueError(f"pairs need two effects to draw from, not {eff}")
    items: list[tuple[str, dict, dict]] = [("clean", {}, {})] * n_clean
    for j in range(n - n_clean - n_pair - n_oov):
        e = eff[j % len(eff)]
        items.append(("single", {e: _draw(rng, IN_VOCAB[e][1], IN_VOCAB[e][2])}, {}))
    for _ in range(n_pair):
        e1, e2 = (str(e) for e in rng.choice(eff, 2, replace=False))
        items.append(
            ("pair", {e: _draw(rng, IN_VOCAB[e][1], IN_VOCAB[e][2], rng.uniform(0.3, 1)) for e in (e1, e2)}, {})
        )
    for j in range(n_oov):
        e = oov[j % len(oov)]
        items.append(("oov", {}, {e: _draw(rng, OOV[e][1], OOV[e][2])}))
    return [items[i] for i in rng.permutation(len(items))]


def _acquisition(rng: np.random.Generator, fs: float) -> dict[str, Any] | None:
    u = rng.uniform()
    if u < 0.3:
        return None
    f = {
        "type": str(rng.choice(["butterworth", "bessel"])),
        "order": int(rng.integers(2, 9)),
        "cutoff_hz": round(float(rng.uniform(0.25, 0.45)) * fs, 1),
    }
    acq: dict[str, Any] = {"xdd": {"filter": f}, "ydd": {"filter": f}} if u < 0.6 else {"all": {"filter": f}}
    if rng.uniform() < 0.25:
        acq["force"] = {"delay_s": round(float(rng.uniform(1e-4, 1e-3)), 5)}
    return acq


def _record(rng: np.random.Generator, kind: str, T: float) -> tuple[dict[str, Any], float]:
    up = rng.uniform() < 0.5
    f0, f1 = float(rng.uniform(1.2, 2.0)), float(rng.uniform(4.5, 6.0))
    if kind in ("sweep_lin", "sweep_log"):
        return ({"f0": f0, "f1": f1} if up else {"f0": f1, "f1": f0}), float(rng.uniform(80, 200))
    if kind in ("random", "burst"):
        return {"f_lo": 1.0, "f_hi": float(rng.uniform(6.0, 10.0))}, float(rng.uniform(40, 100))
    if kind == "hammer":
        return {"n_hits": int(rng.integers(4, 9))}, float(rng.uniform(300, 800))
    return {}, 0.0


def write_dataset(path: Path, rng: np.random.Generator, hidden: dict, oov: dict, T: float) -> dict[str, Any]:
    from ...physics.params import paper_case
    from .transient_truth import Truth, TruthEscaped

    case = int(rng.integers(1, 4))
    t = paper_case(case)
    c = float(rng.choice([10.0, 15.0]))
    base = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
    tmd: dict[str, Any] = {
        "mass": float(t.mass),
        "stiffness": float(t.stiffness),
        "damping": c,
        "inertance": float(t.inertance),
        "inerter": "ideal",
    }
    fs = float(rng.choice(RATES))
    accel_only = rng.uniform() < 0.2 and not ({"sensor_offset"} & set(hidden) or {"x_gain"} & set(oov))
    acq = _acquisition(rng, fs)
    ch: dict[str, float] = {IN_VOCAB[e][0]: v for e, v in hidden.items()} | {OOV[e][0]: v for e, v in oov.items()}
    gain = ch.pop("force_gain", 0.0)
    x_off = ch.pop("x_offset", 0.0)
    x_gain = ch.pop("x_gain", 0.0)
    if "eps" in ch:  # the gear's contact: the paper's stiffness, a damping from nearly elastic (the paper) up
        ch["ci"] = float(math.exp(rng.uniform(math.log(PLAY_CI[0]), math.log(PLAY_CI[1]))))
    if "dI_split" in ch:  # keep m and I positive
        ch["dI_split"] = float(np.clip(ch["dI_split"], -0.45 * tmd["inertance"], 0.45 * tmd["mass"]))
        hidden["mass_split"] = ch["dI_split"]
    step = max(1, int(math.ceil(4000.0 / fs)))
    kinds = [str(k) for k in rng.choice(KINDS, 3, replace=False)]
    state = rng.bit_generator.state  # the records' draws: the same again for a weaker truth
    note = None
    for attempt in range(ESCAPE_TRIES + 1):
        try:
            truth = Truth(base, tmd, T, **ch)
            written = _records(path, rng, truth, kinds, T, fs, step, gain, x_off, x_gain, acq, accel_only)
            break
        except TruthEscaped as e:
            if attempt == ESCAPE_TRIES:
                raise
            note = f"drawn {attempt + 1} time(s) weaker by {ESCAPE_SCALE:g}: {e}"
            rng.bit_generator.state = state
            for key in ch:  # every change of the dynamics weaker; the manifest's truth with it
                if key != "ci":  # (the play's contact is the gear's, not a change)
                    ch[key] *= ESCAPE_SCALE
            for d, table in ((hidden, IN_VOCAB), (oov, OOV)):
                for e in d:
                    if table[e][0] in ch:
                        d[e] = ch[table[e][0]]
    recs, meta = written
    doc: dict[str, Any] = {
        "level": "system",
        "description": "transient records (make-benchmark --suite transient)",
        "nominal": {"base": base, "tmd": tmd},
        "records": recs,
    }
    if acq:
        doc["acquisition"] = acq
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc, sort_keys=False))
    out = {"case": case, "fs": fs, "accel_only": bool(accel_only), "acquisition": acq, "records": meta}
    if "ci" in ch:
        out["play_contact"] = {"ki": truth.ki, "ci": ch["ci"]}
    return out if note is None else {**out, "truth_redrawn": note}


def _records(
    path: Path,
    rng: np.random.Generator,
    truth: Truth,
    kinds: list[str],
    T: float,
    fs: float,
    step: int,
    gain: float,
    x_off: float,
    x_gain: float,
    acq: dict[str, Any] | None,
    accel_only: bool,
) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Simulate and write the dataset's records under ``truth``; nothing is written when a record's
    truth escapes (:class:`.transient_truth.TruthEscaped` raised before any file)."""
    from ..records import write_record
    from .transient_truth import force_signal, measure

    recs, meta, out = [], [], []
    for i, kind in enumerate(kinds):
        kw, amp = _record(rng, kind, T)
        tt = np.arange(0.0, T, 1.0 / (fs * step))
        F = force_signal(kind, rng, T, amp, **kw)
        F_true = (lambda Fr: lambda s: (1.0 + gain) * Fr(s))(F)
        z0 = np.array([0.004, 0.0, 0.012, 0.0]) * rng.uniform(0.5, 1.5) if kind == "decay" else None
        sig = truth.simulate(F_true, tt, z0, max_step=5e-4 if kind == "hammer" else 2e-3)
        sig.pop("mode", None)  # (the stick-slip truth's modes: not a channel)
        sig["force"] = np.asarray(F(tt), float)  # the load cell reads the recorded force
        if kind == "decay":
            sig.pop("force")
        noise = {k: float(rng.uniform(0.005, 0.02)) for k in ("x", "y", "xdd", "ydd")}
        noise["force"] = float(rng.uniform(0.003, 0.01))
        m = measure(sig, tt, step, rng, noise, acq, gains={"x": x_gain}, offsets={"x": x_off})
        if accel_only:
            m.pop("x"), m.pop("y")
        out.append((f"{kind}_{i}.csv", m))
        recs.append({"file": f"{kind}_{i}.csv", "kind": "decay" if kind == "decay" else "transient"})
        meta.append({"kind": kind, **kw, "amp": amp, "noise": noise})
    path.mkdir(parents=True, exist_ok=True)
    for name, m in out:
        write_record(path / name, m)
    return recs, meta


def make_transient_benchmark(
    out: Path,
    n: int | None = None,
    seed: int = 1,
    n_clean: int | None = None,
    n_pair: int | None = None,
    n_oov: int | None = None,
    seconds: float = 60.0,
    progress: Callable[..., Any] | None = None,
    part: tuple[int, int] | None = None,
    effects: list[str] | None = None,
) -> list[Any]:
    """Write the transient suite to ``out`` (one folder per dataset + manifest.json). ``part = (k, K)``
    writes only the datasets i with i % K == k (the same datasets as the whole run: K processes
    share the work, each folder scored on its own). ``effects``: the in-vocabulary effects of the
    singles and pairs (default every one of IN_VOCAB)."""
    if effects is not None:
        bad = [e for e in effects if e not in IN_VOCAB]
        if bad or not effects:
            raise ValueError(f"effects {bad or effects}: the transient suite draws {', '.join(IN_VOCAB)}")
    nc, ns, npair, no = counts("transient", n, n_clean, n_pair, n_oov)
    n = nc + ns + npair + no
    rng = np.random.default_rng(seed)
    man = []
    for i, (cls, hidden, oov) in enumerate(plan(rng, n, nc, npair, no, effects)):
        t0 = time.perf_counter()
        name = f"tr{i:03d}"
        sub = np.random.default_rng(int(rng.integers(1 << 31)))
        if part is not None and i % part[1] != part[0]:
            continue
        spec = write_dataset(out / name, sub, hidden, oov, seconds)
        row = {
            "dataset": name,
            "class": cls,
            "record_kind": "transient",
            **spec,
            "hidden": sorted(hidden) + sorted(oov),
            "severity": {**hidden, **oov},
            "truth": {VOCAB[e].truth_key: v for e, v in hidden.items()},
            "oov": oov,
            "visibility": {"visible": True, "note": "OOV strengths drawn visible; not computed"},
            "seconds": round(time.perf_counter() - t0, 2),
        }
        man.append(row)
        # the manifest is rewritten after every dataset: a run stopped early leaves a scorable part
        doc = {"suite": "system", "generator": "transient", "seed": seed, "seconds": seconds, "datasets": man}
        if effects is not None:
            doc["effects"] = list(effects)
        doc["complete"] = i >= n - (part[1] if part else 1)
        write_manifest(out, doc)
        if progress:
            progress({"dataset": name, "seconds": row["seconds"]})
    return man
