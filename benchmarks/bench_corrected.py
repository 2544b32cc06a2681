"""Close the loop (issue 41): is the corrected model ``diagnose`` writes right?

    python benchmarks/bench_corrected.py [--out /tmp/bench_corrected] [--seed 41]

Five system-level datasets of the steady benchmark generator
(:func:`pyfmu_wrapper.diagnose.system.bench.make_system_dataset`: four steady time records at drawn
frequencies and forces + one FRC at 200 N, noise 0.5-2 % per channel, 0.5 % on x_max), one per model
effect of its table (friction, play, cubic, viscous, mass_split), the size drawn log-uniformly from the
generator's range with ``--seed``. For each:

1. ``diagnose DS --out D`` (the console script): what it names, and ``D/corrected/``;
2. ``run-scenario F --out ...`` for every ``D/corrected/*.yaml`` (the console script), then chi2 / n
   of the records against the corrected curve, each residual in units of the point's noise
   (:func:`pyfmu_wrapper.diagnose.corrected.measured_points`: the FRC path's x_max noise estimated
   against the corrected nominal, a steady record's max |x| with its harmonic series' variance);
   the same for the nominal curve, and for the FRC points also with the generator's true 0.5 % noise.
   The FRC noise is the one the diagnosis of the dataset against the corrected nominal uses (the
   residual its best FRC candidate leaves, degrees of freedom counted). Each kind of point against
   run-scenario's amplitude of the same definition: a steady record's max |x - mean| of its harmonic
   series against the CSV's ``amplitude_periodic`` (the series fitted over run-scenario's steady
   windows); an FRC point's x_max (the generator's: the monolithic solver's largest window maximum)
   against ``amplitude``, its noise added in quadrature to the corrected model's own scatter
   (:func:`~pyfmu_wrapper.diagnose.corrected.read_scatter`: half the spread of run-scenario's steady
   windows -- the play chain rattles). chi2 / n of 25 points of a right model scatters by
   sqrt(2 / 25) = 0.28 about 1 (more with an estimated noise);
3. ``diagnose DS --model D/corrected/<one>.yaml`` (the dataset against the corrected nominal): what
   is named now (the target: nothing).

With ``--fmus DIR`` (built FMUs, e.g. ``fmu/build``), also :func:`ssp_check`: the .ssv with the FMUs
in fmpy against the solver. Writes ``OUT/bench_corrected.json`` and prints one line per dataset.
"""

from __future__ import annotations

import argparse
import json
import math
import resource
import subprocess
import time
from pathlib import Path

import numpy as np

from pyfmu_wrapper.diagnose.corrected import chi2_per_point, measured_points, read_curve, read_scatter
from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.run import _load_model
from pyfmu_wrapper.diagnose.system.bench import FRC_NOISE, RANGES, make_system_dataset

EFFECTS = ("friction", "play", "cubic", "viscous", "mass_split")


def draw(rng: np.random.Generator, effect: str) -> float:
    lo, hi = RANGES[effect]
    v = float(math.exp(rng.uniform(math.log(lo), math.log(hi))))
    if effect == "mass_split":  # signed; Case 1 keeps dI > -0.5 (m + I fixed, I = 1)
        v = v if rng.uniform() < 0.5 or v > 0.5 else -v
    return v


def named(res_json: Path) -> tuple[list[str], dict, dict]:
    """(effects named, their parameters, the verdict's flags: structural, unexplained, text)."""
    d = json.loads(res_json.read_text())
    v = d.get("verdict") or {}
    flags = {"structural": bool(v.get("structural")), "unexplained": bool(v.get("unexplained")), "text": v.get("text")}
    return list(v.get("effects") or []), {k: p["value"] for k, p in (v.get("parameters") or {}).items()}, flags


CPU: dict[str, float] = {}  #: CPU seconds (user + system) of the last command run, by its first word


def run(cmd: list[str]) -> tuple[float, str]:
    t = time.perf_counter()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, capture_output=True, text=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU[cmd[0]] = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({p.returncode}): {p.stderr[-2000:]}")
    return time.perf_counter() - t, p.stdout


def bench_one(root: Path, effect: str, size: float, seed: int) -> dict:
    ds = root / f"ds_{effect}"
    if not (ds / "dataset.yaml").is_file():
        make_system_dataset(ds, {effect: size}, seed=seed, case=1)
    out = root / f"diag_{effect}"
    t_diag, _ = run(["diagnose", str(ds), "--out", str(out)])
    cpu_diag = CPU["diagnose"]
    found, params, flags = named(out / "diagnosis.json")
    ymls = sorted((out / "corrected").glob("*.yaml"))
    curves: dict[str, dict[float, dict[float, float]]] = {"corrected": {}, "nominal": {}, "scatter": {}, "periodic": {}}
    t_rs = 0.0
    for y in ymls:
        rs = root / f"rs_{effect}" / y.stem
        dt, _ = run(["run-scenario", str(y), "--out", str(rs), "--quiet", "--workers", "1"])
        t_rs += dt
        F = float(y.stem[len("corrected_F") : -1])
        curves["corrected"][F] = read_curve(rs / "corrected.csv")  # the first curve: the corrected model
        curves["nominal"][F] = read_curve(rs / "corrected.csv", "nominal")
        curves["scatter"][F] = read_scatter(rs / "corrected.csv")  # the corrected model's window scatter
        curves["periodic"][F] = read_curve(rs / "corrected.csv", column="amplitude_periodic")
    sc, per = curves["scatter"], curves["periodic"]
    dsc = load_dataset(ds, _load_model(str(ymls[0])))  # the noise estimated against the corrected nominal
    pts = measured_points(dsc)
    steady = [p for p in pts if p["kind"] == "steady"]
    frc = [p for p in pts if p["kind"] == "frc"]
    frc_true = [{**p, "sigma": FRC_NOISE * p["x"]} for p in frc]
    re_out = root / f"rediag_{effect}"
    t_re, _ = run(["diagnose", str(ds), "--model", str(ymls[0]), "--out", str(re_out)])
    cpu_re = CPU["diagnose"]
    left, left_params, left_flags = named(re_out / "diagnosis.json")
    row = {
        "effect": effect,
        "truth": size,
        "named": found,
        "parameters": params,
        "verdict": flags,
        "scenario_files": [y.name for y in ymls],
        "chi2_per_point": chi2_per_point(pts, curves["corrected"], sc, per),
        "chi2_steady": chi2_per_point(steady, curves["corrected"], sc, per),
        "chi2_frc": chi2_per_point(frc, curves["corrected"], sc),
        "chi2_frc_true_noise": chi2_per_point(frc_true, curves["corrected"], sc),
        "chi2_per_point_true_frc_noise": chi2_per_point(steady + frc_true, curves["corrected"], sc, per),
        "chi2_per_point_no_scatter": chi2_per_point(pts, curves["corrected"], None, per),
        "chi2_steady_window_max": chi2_per_point(steady, curves["corrected"], sc),  # the former definition
        "chi2_nominal": chi2_per_point(pts, curves["nominal"]),
        "frc_noise_relative": [p["sigma"] / p["x"] for p in frc[:1]],
        "rediagnosis_named": left,
        "rediagnosis_parameters": left_params,
        "rediagnosis_verdict": left_flags,
        "nothing_left": not left and not left_flags["structural"] and not left_flags["unexplained"],
        "seconds": {"diagnose": t_diag, "run_scenario": t_rs, "rediagnose": t_re},
        "cpu_seconds": {"diagnose": cpu_diag, "rediagnose": cpu_re},
    }
    return row


def ssp_check(ds: Path, yml: Path, fmus: Path, omega: float = 18.0) -> dict:
    """The corrected .ssv with the FMUs (built FMUs in ``fmus``): the project's SSP of the dataset's
    nominal (``master.ssp.export_ssp``, instances base and tmd), its parameter set overridden by the
    .ssv, simulated by fmpy's ``simulate_ssp`` for 0.5 s; base x against the monolithic solver's
    corrected and nominal models (relative to max |x|)."""
    from fmpy.ssp.simulation import simulate_ssp
    from fmpy.ssp.ssd import read_ssv

    from pyfmu_wrapper.master.ssp import export_ssp, ssp_parameter_set
    from pyfmu_wrapper.models.base_tmd import UNIT
    from pyfmu_wrapper.models.base_tmd.cosim import CONNECTIONS, fmu_parameters
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams
    from pyfmu_wrapper.scenario.loader import load_scenario
    from pyfmu_wrapper.solvers import monolithic as mono

    sc = load_scenario(yml)
    nom = load_dataset(ds).nominal
    bn, tn = BaseParams(**nom["base"]), TMDParams(**nom["tmd"])
    z0 = mono.initial_guess(UNIT, sc.base, sc.tmd, omega)
    fm = {"base": fmus / "BaseOscillator.fmu", "tmd": fmus / "TMDInerter.fmu"}
    p = export_ssp(yml.parent.parent.parent / "nominal.ssp", fm, CONNECTIONS, fmu_parameters(bn, tn, omega, z0))
    ps = ssp_parameter_set(p)
    corr = read_ssv(str(yml.with_suffix(".ssv")))  # validated against the SSP 1.0 schema
    names = {q.name for q in corr.parameters}
    ps.parameters = [q for q in ps.parameters if q.name not in names] + list(corr.parameters)
    h = 1e-4
    res = simulate_ssp(str(p), stop_time=0.5, step_size=h, parameter_set=ps)
    t = res["time"] + h  # fmpy records the values after the step under the step's start time
    _, st = mono.simulate(UNIT, sc.base, sc.tmd, omega, 0.6, z0, sample_times=t)
    _, sn = mono.simulate(UNIT, bn, tn, omega, 0.6, z0, sample_times=t)
    scale = float(np.max(np.abs(st[:, 0])))
    return {
        "vs_corrected": float(np.max(np.abs(res["base.x"] - st[:, 0])) / scale),
        "vs_nominal": float(np.max(np.abs(res["base.x"] - sn[:, 0])) / scale),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", default="/tmp/bench_corrected")
    ap.add_argument("--seed", type=int, default=41)
    ap.add_argument("--effects", default=",".join(EFFECTS))
    ap.add_argument(
        "--fmus", default=None, help="folder with built BaseOscillator.fmu, TMDInerter.fmu: also run ssp_check"
    )
    a = ap.parse_args()
    root = Path(a.out)
    root.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(a.seed)
    rows = []
    sizes = {e: draw(rng, e) for e in EFFECTS}  # the same draws whichever --effects are run
    for e in a.effects.split(","):
        size = sizes[e]
        r = bench_one(root, e, size, seed=a.seed * 100 + EFFECTS.index(e))
        if a.fmus:
            ymls = sorted((root / f"diag_{e}" / "corrected").glob("*.yaml"))
            r["ssp"] = ssp_check(root / f"ds_{e}", ymls[-1], Path(a.fmus))
            print(f"{e}: .ssv in fmpy: base x {r['ssp']}", flush=True)
        rows.append(r)
        print(
            f"{e} {size:.4g}: named {r['named'] or '-'}; chi2/n corrected {r['chi2_per_point']['chi2_per_point']:.3g} "
            f"(n {r['chi2_per_point']['n']}; steady {r['chi2_steady']['chi2_per_point']:.3g}, FRC "
            f"{r['chi2_frc']['chi2_per_point']:.3g}, FRC with the true noise {r['chi2_frc_true_noise']['chi2_per_point']:.3g}; "
            f"all with the FRC's true noise {r['chi2_per_point_true_frc_noise']['chi2_per_point']:.3g}), "
            f"nominal {r['chi2_nominal']['chi2_per_point']:.3g}; re-diagnosis names {r['rediagnosis_named'] or 'nothing'}"
            + (" (nothing left)" if r["nothing_left"] else f" (structural gap: {r['rediagnosis_verdict']['text']})")
            + f"; CPU diagnose {r['cpu_seconds']['diagnose']:.0f} s, re-diagnosis {r['cpu_seconds']['rediagnose']:.0f} s",
            flush=True,
        )
        (root / "bench_corrected.json").write_text(json.dumps(rows, indent=1, default=float))
    ok = sum(r["chi2_per_point"]["chi2_per_point"] <= 1.2 for r in rows)
    clean = sum(r["nothing_left"] for r in rows)
    print(f"chi2/n <= 1.2: {ok}/{len(rows)}; re-diagnosis finds nothing left: {clean}/{len(rows)}")


if __name__ == "__main__":
    main()
