"""A second, independently written field check of ``diagnose`` on system-level measurements.

Written apart from ``diagnose/benchmark.py`` (``make-benchmark``) on purpose: a tool that scores
well only on its own generator has learnt the generator. The datasets follow the description of
what a test rig records (issue 10): paper Case 1 or Case 2 nominal (ideal inerter, c = 15 N s/m, no
friction, no play); four steady-state time records (x, y, xdd, ydd sampled at 1 kHz over 10
forcing periods, the force signal, no velocity channel) at forcing amplitudes 100-300 N and
frequencies 16-24 rad/s, with independent white noise of 0.5-2 % of each channel's RMS, different
per channel and per record; one stepped-sine FRC at 200 N over 15-25 rad/s with 0.5 % noise on
x_max. The truth holds zero, one or two of: dry friction, play in the inerter gear, extra viscous
damping, a different m / I split (m + I fixed), a cubic TMD spring, a forcing-amplitude error, a
displacement-sensor offset; severities drawn log-uniformly from barely visible to large.

    python benchmarks/field_check.py generate OUT [-n 24] [--seed 7]
    python benchmarks/field_check.py run OUT            # runs `diagnose` on every dataset
    python benchmarks/field_check.py score OUT          # scores diagnosis.json["verdict"]

The truth of each dataset is in OUT/truth.json, outside the dataset folders.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from pyfmu_wrapper.models.solve import simulate, steady_state
from pyfmu_wrapper.physics import kernels
from pyfmu_wrapper.physics.params import BaseParams, InerterModel, pack, paper_case

EFFECTS = ("friction", "play", "damping", "mass_split", "cubic", "forcing", "offset")
#: (low, high) severity of each effect's parameter (log-uniform in magnitude)
RANGES = {
    "friction": (1.5, 30.0),
    "play": (2e-5, 6e-4),
    "damping": (2.0, 40.0),
    "mass_split": (0.3, 2.5),
    "cubic": (5e4, 3e6),
    "forcing": (0.02, 0.2),
    "offset": (1e-4, 3e-3),
}
#: words that name each effect in a verdict (any one suffices)
KEYWORDS = {
    "friction": ("friction",),
    "play": ("play", "backlash", "gap"),
    "damping": ("viscous", "damping"),
    "mass_split": ("mass", "inertance", "split"),
    "cubic": ("cubic",),
    "forcing": ("forc", "gain", "amplitude"),
    "offset": ("offset", "bias"),
}


def _truth_params(case: int, effects: dict):
    base = BaseParams()
    tmd = paper_case(case, damping=15.0)
    F_scale, offset = 1.0, 0.0
    for name, v in effects.items():
        if name == "friction":
            tmd = replace(tmd, friction_force=v)
        elif name == "play":
            tmd = replace(tmd, inerter=InerterModel.PLAY, play_gap=v)
        elif name == "damping":
            tmd = replace(tmd, damping=tmd.damping + v)
        elif name == "mass_split":
            tmd = replace(tmd, mass=tmd.mass - v, inertance=tmd.inertance + v)
        elif name == "cubic":
            tmd = replace(tmd, cubic_stiffness=v)
        elif name == "forcing":
            F_scale = 1.0 + v
        elif name == "offset":
            offset = v
    return base, tmd, F_scale, offset


def _record(base, tmd, F, omega, F_scale, offset, rng):
    true_base = replace(base, force_amplitude=F * F_scale)
    ss = steady_state(true_base, tmd, omega)
    T = 2 * math.pi / omega
    t = np.arange(0.0, 10 * T, 1e-3)
    _, z = simulate(true_base, tmd, omega, t[-1] * (1 + 1e-12), z0=ss.state, sample_times=t, rtol=1e-9)
    p = pack(true_base, tmd, omega)
    dz = np.zeros(6)
    acc = np.empty((t.size, 2))
    for i in range(t.size):
        kernels.rhs(t[i], z[i], p, dz)
        acc[i] = dz[1], dz[3]
    cols = {"force": F * np.cos(omega * t), "x": z[:, 0] + offset, "y": z[:, 2], "xdd": acc[:, 0], "ydd": acc[:, 1]}
    for k, v in cols.items():
        rms = float(np.sqrt(np.mean((v - (offset if k == "x" else 0.0)) ** 2)))
        cols[k] = v + rng.normal(0.0, rng.uniform(0.005, 0.02) * rms, v.size)
    return t, cols, bool(ss.converged)


def generate(out: Path, n: int, seed: int):
    rng = np.random.default_rng(seed)
    out.mkdir(parents=True, exist_ok=True)
    plan = []
    n_clean, n_pair = max(2, n // 6), max(2, n // 8)
    for i in range(n):
        if i < n_clean:
            eff = []
        elif i < n_clean + n_pair:
            eff = list(rng.choice([e for e in EFFECTS if e != "play"], 2, replace=False))
        else:
            eff = [EFFECTS[(i - n_clean - n_pair) % len(EFFECTS)]]
        plan.append(eff)
    truth = {}
    for i, eff in enumerate(plan):
        case = int(rng.choice([1, 2]))
        effects = {}
        for e in eff:
            lo, hi = RANGES[e]
            v = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
            if e in ("forcing", "offset") and rng.random() < 0.5:
                v = -v
            if e == "mass_split":
                v = min(v, 0.6 * (9.0 if case == 1 else 5.0)) * (1 if rng.random() < 0.5 else -1)
                v = max(v, -0.8 * (1.0 if case == 1 else 5.0))
            effects[e] = v
        name = f"ds{i:02d}"
        d = out / name
        d.mkdir(exist_ok=True)
        base, tmd, F_scale, offset = _truth_params(case, effects)
        t0 = time.time()
        records = []
        omegas = np.sort(rng.choice(np.arange(16.0, 24.5, 0.5), 4, replace=False))
        for w in omegas:
            F = float(rng.choice([100.0, 150.0, 200.0, 250.0, 300.0]))
            t, cols, conv = _record(base, tmd, F, float(w), F_scale, offset, rng)
            fname = f"w{w:g}_F{F:g}.csv"
            arr = np.column_stack([t] + [cols[c] for c in ("force", "x", "y", "xdd", "ydd")])
            np.savetxt(d / fname, arr, delimiter=",", header="t,force,x,y,xdd,ydd", comments="", fmt="%.10g")
            records.append({"file": fname, "omega": float(w), "force_amplitude": F})
        ws = np.arange(15.0, 25.01, 0.5)
        true_base = replace(base, force_amplitude=200.0 * F_scale)
        xm = np.array([steady_state(true_base, tmd, float(w)).amplitude for w in ws]) + abs(offset)
        xm = xm * (1 + rng.normal(0.0, 0.005, xm.size))
        np.savetxt(
            d / "frc.csv",
            np.column_stack([ws, np.full(ws.size, 200.0), xm]),
            delimiter=",",
            header="omega,force_amplitude,x_max",
            comments="",
            fmt="%.10g",
        )
        records.append({"file": "frc.csv"})
        nominal = {
            "base": {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0},
            "tmd": {
                "mass": 9.0 if case == 1 else 5.0,
                "stiffness": 4000.0,
                "damping": 15.0,
                "inertance": 1.0 if case == 1 else 5.0,
                "inerter": "ideal",
            },
        }
        (d / "dataset.yaml").write_text(
            yaml.safe_dump(
                {"level": "system", "description": f"field check {name}", "nominal": nominal, "records": records},
                sort_keys=False,
            )
        )
        truth[name] = {"case": case, "effects": effects}
        print(f"{name}: case {case} {effects} ({time.time() - t0:.1f} s)", flush=True)
    (out / "truth.json").write_text(json.dumps(truth, indent=1))


def run(out: Path):
    truth = json.loads((out / "truth.json").read_text())
    for name in truth:
        res = out / "results" / name
        t0 = time.time()
        p = subprocess.run(["diagnose", str(out / name), "--out", str(res)], capture_output=True, text=True)
        (out / "results").mkdir(exist_ok=True)
        (out / "results" / f"{name}.stdout").write_text(p.stdout + "\n--- stderr\n" + p.stderr)
        print(f"{name}: exit {p.returncode} in {time.time() - t0:.1f} s", flush=True)


def _named(verdict_names: list[str]) -> set[str]:
    found = set()
    for v in verdict_names:
        low = v.lower()
        for e, words in KEYWORDS.items():
            if any(w in low for w in words):
                found.add(e)
                break
    return found


def score(out: Path):
    truth = json.loads((out / "truth.json").read_text())
    rows = []
    for name, tr in truth.items():
        f = out / "results" / name / "diagnosis.json"
        if not f.is_file():
            rows.append((name, tr, None))
            continue
        v = json.loads(f.read_text()).get("verdict", {})
        effs = v.get("effects", [])
        names = [e.get("name", "") if isinstance(e, dict) else str(e) for e in effs]
        rows.append((name, tr, _named(names)))
    singles = [(n, t, g) for n, t, g in rows if len(t["effects"]) == 1]
    clean = [(n, t, g) for n, t, g in rows if not t["effects"]]
    pairs = [(n, t, g) for n, t, g in rows if len(t["effects"]) == 2]
    ok1 = sum(1 for _, t, g in singles if g is not None and set(t["effects"]) <= g and len(g) <= 1)
    fp = sum(1 for _, t, g in clean if g)
    both = sum(1 for _, t, g in pairs if g is not None and set(t["effects"]) <= g)
    print(
        f"singles right {ok1}/{len(singles)}; clean with a false effect {fp}/{len(clean)}; "
        f"pairs with both named {both}/{len(pairs)}"
    )
    for n, t, g in rows:
        print(f"  {n}: truth {sorted(t['effects'])} -> {sorted(g) if g is not None else 'NO RESULT'}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("cmd", choices=("generate", "run", "score"))
    ap.add_argument("out", type=Path)
    ap.add_argument("-n", type=int, default=24)
    ap.add_argument("--seed", type=int, default=7)
    a = ap.parse_args(argv)
    {"generate": lambda: generate(a.out, a.n, a.seed), "run": lambda: run(a.out), "score": lambda: score(a.out)}[
        a.cmd
    ]()


if __name__ == "__main__":
    sys.exit(main())
