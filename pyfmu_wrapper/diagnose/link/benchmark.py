"""Withheld-effect benchmark: generate link-level datasets with hidden effects, then score diagnose.

Generation uses the project's force laws (physics kernels): the TMD link of the paper's Case 1
(k = 4e3 N/m, c = 40 N s/m, ideal inerter I = 1 kg, friction_slope 1e6) is driven on a virtual
test rig with d = A sin(w t) at w in {15, 20, 25} rad/s and A in {10, 20, 30} mm (3 periods each,
200 samples per period); the force through it is measured with Gaussian noise (0.5 N).
Hidden effects (the nominal model does not know them):

=============  ===========================================================  ====================
effect         how it is generated                                          severities
=============  ===========================================================  ====================
friction       kernels.friction_force(v, df, 1e6) added                     df = 3, 6, 12 N
play           spring through a gap: kernels.chain_force (ki = k, gap eps)  eps = 0.5, 1, 2 mm
viscous        c -> c + dc                                                  dc = 4, 8, 16 N s/m
mass_split     I -> I + dI (m + I fixed; m does not enter a link test)      dI = 0.2, 0.4, 0.8 kg
cubic          + k3 d^3 (not in the kernels: a test of a missing law)       k3 = 1e5, 2e5, 4e5 N/m^3
force_error    force reads (1 + alpha) x the true force (gain error)        alpha = 3, 6, 12 %
bias           displacement sensor offset b (the nominal sees d + b)        b = 0.5, 1, 2 mm
=============  ===========================================================  ====================

The labels go to ``manifest.json`` beside the dataset folders; ``diagnose`` never reads it.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from ...models.base_tmd.effects import VOCABULARY as VOCAB
from ...physics.kernels import chain_force
from ...physics.params import N_PARAMS, P_ci, P_eps, P_ki
from ..records import write_record
from .models import friction_vec

if TYPE_CHECKING:
    from typing import Any

    from numpy import ndarray

NOMINAL = dict(stiffness=4.0e3, damping=40.0, friction_force=0.0, friction_slope=1.0e6, inertance=1.0)
SEVERITY = {
    "friction": [3.0, 6.0, 12.0],
    "play": [0.5e-3, 1e-3, 2e-3],
    "viscous": [4.0, 8.0, 16.0],
    "mass_split": [0.2, 0.4, 0.8],
    "cubic": [1e5, 2e5, 4e5],
    "force_error": [0.03, 0.06, 0.12],
    "bias": [0.5e-3, 1e-3, 2e-3],
}
EFFECTS = list(SEVERITY)
NOISE = 0.5
OMEGAS = (15.0, 20.0, 25.0)
AMPS = (0.01, 0.02, 0.03)


def _truth_param(effect: str, value: float) -> tuple[str, float]:
    """(parameter key in the diagnosis, value) that the fit should recover."""
    key = VOCAB[effect].truth_key
    if effect == "bias":
        value = NOMINAL["stiffness"] * value  # nominal sees d + b: force offset k b to be added
    return key, value


def link_force(d: ndarray, v: ndarray, a: ndarray, hidden: dict) -> ndarray:
    k, c, I = NOMINAL["stiffness"], NOMINAL["damping"], NOMINAL["inertance"]
    c += hidden.get("viscous", 0.0)
    I += hidden.get("mass_split", 0.0)
    if "play" in hidden:
        p = np.zeros(N_PARAMS)
        p[P_ki], p[P_ci], p[P_eps] = k, 0.0, hidden["play"]
        spring = np.array([chain_force(x, 0.0, p) for x in d])
    else:
        spring = k * d
    F = spring + c * v + I * a + hidden.get("cubic", 0.0) * d**3
    F = F + friction_vec(v, hidden.get("friction", 0.0), NOMINAL["friction_slope"])
    return F * (1.0 + hidden.get("force_error", 0.0))


def make_dataset(folder: Path, hidden: dict, seed: int, noise: float = NOISE, periods: int = 3, spp: int = 200) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    recs = []
    for w in OMEGAS:
        for A in AMPS:
            t = np.arange(periods * spp) * (2 * math.pi / w) / spp
            ph = rng.uniform(0, 2 * math.pi)
            d = A * np.sin(w * t + ph)
            v = A * w * np.cos(w * t + ph)
            a = -A * w * w * np.sin(w * t + ph)
            F = link_force(d, v, a, hidden) + rng.normal(0, noise, t.size)
            dm = d - hidden.get("bias", 0.0)  # sensor offset: the nominal model sees the biased reading
            name = f"w{w:g}_A{1000 * A:g}mm.csv"
            write_record(folder / name, {"t": t, "displacement": dm, "velocity": v, "acceleration": a, "force": F})
            recs.append({"file": name, "omega": w})
    meta = {
        "level": "link",
        "description": "withheld-effect benchmark dataset (link level, synthetic)",
        "nominal": dict(NOMINAL),
        "records": recs,
    }
    (folder / "dataset.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))


def make_benchmark(
    out: Path,
    n: int = 40,
    seed: int = 1,
    clean_fraction: float = 0.25,
    pair_fraction: float = 0.2,
    noise: float = NOISE,
) -> list[Any]:
    """n link-level datasets (force noise std ``noise`` [N]): the link suite. The system suite is
    :func:`sysbench.make_system_benchmark`."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    n_clean = max(1, int(math.ceil(clean_fraction * n)))
    n_pair = int(round(pair_fraction * n))
    manifest = []
    for i in range(n):
        if i < n_clean:
            hidden = {}
        elif i < n_clean + n_pair:
            e1, e2 = rng.choice(EFFECTS, 2, replace=False)
            hidden = {str(e): SEVERITY[str(e)][int(rng.integers(1, 3))] for e in (e1, e2)}
        else:
            j = i - n_clean - n_pair
            e = EFFECTS[j % len(EFFECTS)]
            hidden = {e: SEVERITY[e][(j // len(EFFECTS)) % 3]}
        name = f"ds{i:03d}"
        make_dataset(out / name, hidden, seed=int(rng.integers(1 << 31)), noise=noise)
        truth = dict(_truth_param(e, v) for e, v in hidden.items())
        manifest.append({"dataset": name, "hidden": sorted(hidden), "severity": hidden, "truth": truth})
    (out / "manifest.json").write_text(json.dumps({"noise": noise, "nominal": NOMINAL, "datasets": manifest}, indent=1))
    return manifest


def score(bench: Path, results: dict | None = None, progress: Callable[..., Any] | None = None) -> dict:
    """Run the diagnosis on every dataset of a benchmark folder and compare with its manifest.

    A dataset is correct when the verdict's set of effects equals the hidden set (clean: empty);
    a pair counts as "both named" when both hidden effects are in the verdict. Parameter errors
    are taken for the hidden effects the verdict names. The system suite is scored by
    :func:`sysscore.score_system` (its own classes: out of vocabulary, unexplained)."""
    from ..system.score import is_system_suite, score_system

    if is_system_suite(bench):
        return score_system(bench, results, progress)
    import time

    from ..run import load_manifest, run_diagnosis

    bench = Path(bench)
    man = load_manifest(bench)  # InputError for a folder without a manifest or an empty benchmark
    rows = []
    for m in man:
        t0 = time.perf_counter()
        res = results[m["dataset"]] if results else run_diagnosis(bench / m["dataset"], out=None)
        got = res["attribution"]["effects"]
        hidden = m["hidden"]
        row = {
            "dataset": m["dataset"],
            "hidden": hidden,
            "found": got,
            "correct": sorted(got) == sorted(hidden),
            "top1_in_hidden": bool(got) and got[0] in hidden,
            "both_named": len(hidden) == 2 and set(hidden) <= set(got),
            "seconds": time.perf_counter() - t0,
        }
        errs = {}
        for k, v in m["truth"].items():
            est = res["attribution"]["params"].get(k)
            if est is not None and v != 0 and k.split(".")[0] in got:
                errs[k] = abs(est - v) / abs(v)
        row["param_rel_error"] = errs
        if hidden:
            row["gap_closed"] = res["held_out"]["gap_closed"]
        rows.append(row)
        if progress:
            progress(row)
    clean = [r for r in rows if not r["hidden"]]
    single = [r for r in rows if len(r["hidden"]) == 1]
    pair = [r for r in rows if len(r["hidden"]) == 2]
    effect_rows = single + pair
    perr = [e for r in rows for e in r.get("param_rel_error", {}).values()]
    closed = [r["gap_closed"] if r["gap_closed"] is not None else 0.0 for r in effect_rows]
    summary = {
        "n_datasets": len(rows),
        "n_clean": len(clean),
        "n_single": len(single),
        "n_pair": len(pair),
        "top1_accuracy": sum(r["correct"] for r in rows) / len(rows),
        "top1_accuracy_single": sum(r["correct"] for r in single) / max(len(single), 1),
        "pair_exact_accuracy": sum(r["correct"] for r in pair) / max(len(pair), 1),
        "pair_top1_in_hidden": sum(r["top1_in_hidden"] for r in pair) / max(len(pair), 1),
        "false_positive_rate": sum(bool(r["found"]) for r in clean) / max(len(clean), 1),
        "param_rel_error_median": statistics.median(perr) if perr else None,
        "param_rel_error_p90": float(np.percentile(perr, 90)) if perr else None,
        "gap_closed_median": statistics.median(closed) if closed else None,
        "gap_closed_min": min(closed) if closed else None,
        "pair_both_named": sum(r["both_named"] for r in pair) / max(len(pair), 1),
        "false_positives": sum(bool(r["found"]) for r in clean),
        "median_seconds": statistics.median(r["seconds"] for r in rows) if rows else None,
        "max_seconds": max(r["seconds"] for r in rows) if rows else None,
    }
    per: dict[str, dict[str, Any]] = {}  # per hidden effect
    for r in single:
        e = r["hidden"][0]
        d = per.setdefault(e, {"n": 0, "correct": 0, "param_errors": [], "gap_closed": []})
        d["n"] += 1
        d["correct"] += int(r["correct"])
        d["param_errors"] += list(r["param_rel_error"].values())
        d["gap_closed"].append(r["gap_closed"] if r["gap_closed"] is not None else 0.0)
    summary["per_effect"] = {
        e: {
            "n": d["n"],
            "top1": d["correct"] / d["n"],
            "param_error_median": statistics.median(d["param_errors"]) if d["param_errors"] else None,
            "gap_closed_median": statistics.median(d["gap_closed"]),
        }
        for e, d in sorted(per.items())
    }
    return {"summary": summary, "rows": rows}
