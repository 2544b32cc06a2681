"""Reproduce the figures and claims of Brzeski & Perlikowski (2017) and write ``docs/reproduction.md``.

    python -m pyfmu_wrapper.reproduce [--quick] [--out docs] [--results results/paper] [--engine monolithic|cosim|both]
                                      [--executor local|dask|sequential] [--jobs N] [--scheduler ADDR]
                                      [--coarse NAME ...] [--only NAME ...] [--no-resume]

Runs every scenario of ``scenarios/paper/`` (the paper-resolution variants of ``scenarios/``) with
the scenario runner and the engine named by ``--engine`` (default monolithic; the report states it and
every ``summary.json`` records it with the settings it used), draws the paper's Figs. 2-6 from the
results (PNG under ``<out>/figures/``) and writes ``<out>/reproduction.md``: each claim of the paper
beside the computed number, the reference value, the threshold and the verdict of that comparison
(:mod:`pyfmu_wrapper.claims`). Finished sweeps are checkpointed under ``<results>/.cache/``, keyed by
the code version and every setting, so rows computed by older code are never reused.

``--quick`` shrinks every grid (a minute on one core; used by the tests); ``--coarse NAME`` shrinks only
the named scenarios to a medium grid. Quick or coarse grids are stated in the report. Exit status 1
when a claim could not be computed because its computation failed (the row says why).
"""
from __future__ import annotations

import argparse
import datetime as _dt
import json
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import yaml
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from . import plots
from .claim_data import FULL_C, PAPER_SIMPLIFIED, best_fit_viscous, curve, viscous_errors  # noqa: F401 (API)
from .claims import Claim, Context, evaluate
from .cli.errors import InputError, cli_main
from .scenario.engines import ENGINES, RunSettings
from .scenario.executors import code_version, make_executor
from .scenario.loader import _plain, parse_scenario
from .scenario.output import run_scenario
from .scenario.runner import work_units
from .scenario.yamlio import load_marked
from .solvers.frequency_response import exact_amplitude

ROOT = Path(__file__).resolve().parents[1]
PAPER_DIR = ROOT / "scenarios" / "paper"
CASES = (1, 2, 3)
NAMES = ["fig2_iratio"] + [f"fig{f}_case{c}" for f in (3, 4, 5, 6) for c in CASES]
DEFAULT_ENGINE = "monolithic"

# --- scenarios -------------------------------------------------------------------------------------

def _shrink(doc: dict, level: str, exact: bool) -> dict:
    """Smaller grids: 'quick' (tests) or 'coarse' (medium maps). Exact (linear) scenarios stay finer."""
    if level == "quick":
        nf_frc, nf_map, nv_map = (201, 101, 21) if exact else (9, 7, 3)
    else:
        nf_frc, nf_map, nv_map = (None, 41, 21)
    if nf_frc is not None:
        doc["frequencies"] = dict(start=15.0, stop=25.0, count=nf_frc)
    for st in doc["studies"]:
        if st["kind"] == "map":
            v = st["values"]
            st["values"] = dict(start=v["start"], stop=v["stop"], count=nv_map)
            st["frequencies"] = dict(start=15.0, stop=25.0, count=nf_map)
        elif st["kind"] == "phase_portrait" and level == "quick":
            st["n_periods"], st["samples_per_period"] = 1, 400
        elif st["kind"] == "frc" and level == "quick" and "frequencies" in st:
            st["frequencies"] = dict(start=15.0, stop=25.0, count=nf_frc)
    doc["description"] = f"[{level} grid] " + doc.get("description", "")
    return doc


def load_paper_scenario(name: str, level: str | None = None):
    """A scenario of scenarios/paper/, optionally shrunk ('quick' or 'coarse')."""
    path = PAPER_DIR / f"{name}.yaml"
    text = path.read_text(encoding="utf-8")
    if level:
        doc = _shrink(_plain(load_marked(text, name=str(path))), level, exact=name.startswith(("fig2", "fig3")))
        text = yaml.safe_dump(doc, sort_keys=False)
    return parse_scenario(text, str(path))


# --- running ----------------------------------------------------------------------------------------

@dataclass
class Run:
    name: str
    scenario: object
    level: str | None
    datas: dict  #: study name -> data object
    summary: dict
    folder: Path


def run_all(names, results: Path, level_of, executor, resume=True, progress=True,
            engine: str = DEFAULT_ENGINE) -> dict:
    """Run the scenarios with ``engine`` (checkpointed under ``results/.cache``) and collect their data objects."""
    from tqdm import tqdm

    runs = {}
    for name in names:
        level = level_of(name)
        scn = load_paper_scenario(name, level)
        settings = RunSettings.for_scenario(scn, engine=engine)
        collect: list = []
        out = results / name
        with tqdm(total=work_units(scn, settings), desc=name, unit="pt", disable=not progress, file=sys.stderr,
                  leave=False) as bar:
            run_scenario(scn, out, settings, progress=bar.update, executor=executor,
                         checkpoint_dir=results / ".cache" / name, resume=resume, collect=collect)
        summary = json.loads((out / "summary.json").read_text())
        runs[name] = Run(name, scn, level, {d.study.name: d for d in collect}, summary, out)
    return runs


# --- figures --------------------------------------------------------------------------------------

def _fig(nrows, ncols, w=4.6, h=3.3) -> tuple[Figure, np.ndarray]:
    fig = Figure(figsize=(w * ncols, h * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=False)


def _letter(ax, k):
    ax.set_title(f"({'abcdefghi'[k]}) " + ax.get_title(), fontsize=9)


def _maps_and_frcs(runs, names, map_name, frc_name, path, dpi):
    fig, axes = _fig(len(names), 2)
    for i, n in enumerate(names):
        r = runs[n]
        plots.map_plot(r.datas[map_name], ax=axes[i, 0])
        plots.frc_plot(r.datas[frc_name], ax=axes[i, 1])
        order = [cv.label for cv in r.datas[frc_name].study.curves]
        colors = ["black", "gold", "red", "green", "blue"]  # the paper's: no TMD, 0, 10, optimum, 90
        for line in axes[i, 1].get_lines():
            lab = str(line.get_label()).split(" (up)")[0].split(" (down)")[0]
            if lab in order and order.index(lab) < len(colors):
                line.set_color(colors[order.index(lab)])
        axes[i, 1].legend(fontsize=6)
        for j in range(2):
            axes[i, j].set_title(axes[i, j].get_title(), fontsize=9)
        _letter(axes[i, 0], 2 * i)
        _letter(axes[i, 1], 2 * i + 1)
    fig.savefig(path, dpi=dpi)


def _rasterize(fig):
    for ax in fig.axes:
        for coll in ax.collections:
            coll.set_rasterized(True)


def draw_figures(runs: dict, figdir: Path, dpi: int = 80) -> dict:
    figdir.mkdir(parents=True, exist_ok=True)
    out = {}
    if "fig2_iratio" in runs:
        fig, axes = _fig(1, 2)
        plots.map_plot(runs["fig2_iratio"].datas["iratio_map"], ax=axes[0, 0])
        plots.frc_plot(runs["fig2_iratio"].datas["iratio_frc"], ax=axes[0, 1])
        axes[0, 1].legend(fontsize=6)
        _letter(axes[0, 0], 0), _letter(axes[0, 1], 1)
        fig.savefig(figdir / "fig2.png", dpi=dpi)
        out["fig2"] = "fig2.png"
    for f, mp, fr in ((3, "damping_map", "damping_frc"), (4, "friction_map", "friction_frc")):
        names = [f"fig{f}_case{c}" for c in CASES if f"fig{f}_case{c}" in runs]
        if names:
            _maps_and_frcs(runs, names, mp, fr, figdir / f"fig{f}.png", dpi)
            out[f"fig{f}"] = f"fig{f}.png"
    names = [f"fig5_case{c}" for c in CASES if f"fig5_case{c}" in runs]
    if names:
        fig, axes = _fig(3, len(names))
        colors = ["black", "green", "red", "blue"]
        for j, n in enumerate(names):
            plots.map_plot(runs[n].datas["play_map"], ax=axes[0, j])
            axes[0, j].set_title(axes[0, j].get_title(), fontsize=9)
            _letter(axes[0, j], j)
            ph = runs[n].datas["play_phase"]
            for i, w in enumerate((21.0, 19.0)):
                ax = axes[1 + i, j]
                for col, cv in zip(colors, ph.study.curves):
                    ts = ph.series.get((w, cv.label))
                    if ts is not None:
                        ax.plot(ts.states[:, 0], ts.states[:, 1], lw=0.7, color=col, label=cv.label)
                ax.set_xlabel("x [m]")
                ax.set_ylabel(r"$\dot x$ [m/s]")
                ax.set_title(f"Case {n[-1]}: phase portrait, w = {w:g} rad/s", fontsize=9)
                ax.legend(fontsize=6)
                ax.grid(alpha=0.3)
                _letter(ax, 3 * (1 + i) + j)
        fig.savefig(figdir / "fig5.png", dpi=dpi)
        out["fig5"] = "fig5.png"
    names = [f"fig6_case{c}" for c in CASES if f"fig6_case{c}" in runs]
    if names:
        fits = runs.get("_fits", {})
        fig, axes = _fig(len(names), 2)
        for i, n in enumerate(names):
            c = int(n[-1])
            d6 = runs[n].datas["full_frc"]
            plots.frc_plot(d6, ax=axes[i, 0])
            paper_colors = {"1:": "black", "2:": "gold", "3:": "blue", "4:": "red", "5:": "green", "6:": "orange"}
            for line in axes[i, 0].get_lines():
                color = paper_colors.get(str(line.get_label())[:2])
                if color:
                    line.set_color(color)
                    if str(line.get_label()).startswith("2:"):
                        line.set_linestyle("--")  # overlapped by curve 1, as in the paper
            axes[i, 0].legend(fontsize=6)
            axes[i, 0].set_title(f"Case {c}: the full model and its parts", fontsize=9)
            ax = axes[i, 1]
            w, full = curve(d6, "5:")
            ws, simp = curve(d6, "6:")
            ax.plot(w, full, color="green", lw=1.3, label="5: full model")
            ax.plot(ws, simp, color="orange", lw=1.3, label=f"6: simplified, c = {PAPER_SIMPLIFIED[c]:g} (+50 %)")
            ax.fill_between(w, full, np.interp(w, ws, simp), color="0.6", alpha=0.5, lw=0)
            if c in fits:
                tmd = next(cv.tmd for cv in d6.study.curves if cv.label.startswith("6:"))
                cb = fits[c]["area"]["c"]
                wd = np.linspace(w.min(), w.max(), 1001)
                ax.plot(wd, exact_amplitude(runs[n].scenario.base, replace(tmd, damping=cb), wd), ":", color="purple",
                        lw=1.2, label=f"best fit (area), c = {cb:.2f}")
            ax.set_xlim(w.min(), w.max())
            ax.set_ylim(bottom=0)
            ax.set_xlabel(r"$\omega$ [rad/s]")
            ax.set_ylabel("max |x| [m]")
            ax.set_title(f"Case {c}: full vs simplified (grey: area between)", fontsize=9)
            ax.grid(alpha=0.3)
            ax.legend(fontsize=6)
            _letter(axes[i, 0], 2 * i), _letter(ax, 2 * i + 1)
        fig.savefig(figdir / "fig6.png", dpi=dpi)
        out["fig6"] = "fig6.png"
    return out

# --- the report -------------------------------------------------------------------------------------

CAPTIONS = {
    "fig2": "Fig. 2: (a) max|x| over Iratio and w (m + I = 10 kg, c = 0, exact response); (b) FRCs for Iratio = 0, 0.1, 0.5, 0.9, 1 and the base alone (black).",
    "fig3": "Fig. 3: viscous damping. (a, c, e) max|x| over c and w for Cases 1-3 (exact response); (b, d, f) FRCs for c = 0, 10, c_opt (paper) and 90 N s/m.",
    "fig4": "Fig. 4: dry friction. (a, c, e) max|x| over df and w for Cases 1-3 (steady states, up-sweep with continuation); (b, d, f) FRCs for df = 0, 10, df_opt (paper) and 90 N.",
    "fig5": "Fig. 5: play in the inerter gear (ki = 2e7 N/m, ci = 0.01 N s/m). (a-c) max|x| over eps in [0, 2e-3] m and w; (d-f) phase portraits (x, xd) of the base at w = 21 rad/s and (g-i) at w = 19 rad/s, for eps = 0 (black), 5e-5 (green), 1e-4 (red), 1e-3 m (blue).",
    "fig6": "Fig. 6: the full model (c, df, eps = 1e-4) against its parts (left) and against the simplified model with the paper's +50 % c (right; the grey area is the area between the curves; dotted: the best-fit c of this project).",
}

SLIPS = [
    ("Units", "The paper's 'Hz' are rad/s (w_n = sqrt(K/M) = 20 rad/s = 3.18 Hz); the figures only match F cos(w t) with w in rad/s."),
    ("Table 1 vs text", "Table 1 gives ki = 1e7 N/m for the play model, the text 2e7 N/m; the text's value is used."),
    ("Signs", "Table 1 / Eq. (4) as extracted give negative damping and, for Case 3, an indefinite mass matrix; the passive convention is used (docs/physics.md)."),
    ("Sect. 5", "Points to Fig. 3 (d, f) and 'Fig. 3f' where it means Fig. 4; says '(c, d) for Case 3' for (e, f); the Fig. 4 caption says c where it means df."),
    ("Sect. 6", "'The amplitude of the damped body is at least 100 times bigger than the play gap': false near w = 20 rad/s (see the claims)."),
    ("Sect. 7", "Calls c = 15 N s/m 'c_opt(Case 1)'; it is the +50 % rule applied to c = 10 (1.5 x 10), not an optimum, and Case 2 uses the same 15 N s/m; the best-fit c is in the table above."),
]


def _settings_text(r) -> str:
    """The settings the engine used for a run, from its summary.json."""
    st = r.summary.get("settings", {})
    if all(s.kind != "phase_portrait" for s in r.scenario.studies) and r.name.startswith(("fig2", "fig3")) \
            and st.get("solver", {}).get("linear") == "exact" and st.get("engine") != "cosim":
        return "exact"
    parts = []
    if "solver" in st:
        s = st["solver"]
        parts.append(f"solver: rtol {s['rtol']:g}, atol {s['atol_scale']:g}, tol {s['tol']:g}"
                     + (f", window {s['window']}, tol_window {s['tol_window']:g}" if s.get("window") else ""))
    if "cosim" in st:
        c = st["cosim"]
        acc = "default" if c.get("accuracy") is None else f"{c['accuracy']:g}"
        parts.append(f"cosim: accuracy {acc}, {c['coupling']}" + (f", window {c['window']}" if c.get("window") else ""))
    if not st.get("sweep", {}).get("continuation", True):
        parts.append("independent points")
    return "; ".join(parts)


def _claim_cells(i: int, c: Claim) -> list[str]:
    checks = "; ".join(k.text() for k in c.checks) if c.checks else c.detail
    verdict = f"**{c.verdict}**" if c.status == "ok" else f"**{c.verdict}** ({c.detail})"
    return [str(i), c.section, c.claim, c.paper, c.project or "-", checks, verdict, c.note]


def write_report(runs: dict, rows: list, figs: dict, out: Path, figdir: Path, results: Path, quick: bool,
                 engine: str, command: str, missing: list, wall: float) -> Path:
    L = []
    L.append("# Reproduction of Brzeski & Perlikowski (2017)\n")
    L.append(f"Generated by `{command}` on {_dt.datetime.now(_dt.UTC).strftime('%Y-%m-%d %H:%M UTC')} "
             f"with code version `{code_version()}` (sha256 of the package sources) in {wall:.0f} s of wall time. "
             "Do not edit by hand: run the command again.\n")
    L.append(f"**Engine: `{engine}`** ({ENGINES[engine].description}); every results folder's `summary.json` "
             "records the engine and the settings it used. Checkpointed sweeps are keyed by the code version, so "
             "no row of this report comes from older code.\n")
    if quick:
        L.append("> **Quick configuration**: every grid is shrunk (tests and smoke runs). The numbers below are "
                 "not the paper-resolution ones.\n")
    if missing:
        L.append(f"> **Not generated**: {', '.join(f'`{m}`' for m in missing)} (not run by this command); the claims "
                 "that need them are flagged 'not computed' and their figures are missing panels.\n")
    L.append("Every figure is computed from the scenario files in `scenarios/paper/` (the paper-resolution "
             f"variants of `scenarios/`) by the scenario runner, as `run-scenario scenarios/paper/NAME.yaml --engine {engine}` "
             f"does; the results folders are under `{results}/`. Units are SI, frequencies in rad/s "
             "(the paper's 'Hz'). Maps: up-sweeps with continuation for friction (each parameter value one "
             "task), independent steady states from the linear response for play; the colour is max|x|.\n")
    L.append("## Scenarios and cost\n")
    L.append("| scenario | grid | maps (values x frequencies) | settings used | compute [s] | sweeps read back / computed | "
             "steady states not converged |")
    L.append("|---|---|---|---|---|---|---|")
    for name, r in runs.items():
        if name.startswith("_"):
            continue
        maps = [f"{len(s.values)} x {len(s.omegas)}" for s in r.scenario.studies if s.kind == "map"]
        tasks = r.summary.get("executor", {}).get("tasks", {})
        cached = sum(t["cached"] for t in tasks.values())
        computed = sum(t["computed"] for t in tasks.values())
        nc = sum(int((~d.table["converged"].astype(bool)).sum()) for d in r.datas.values() if hasattr(d, "table"))
        nc += sum(int(not ts.converged) for d in r.datas.values() if hasattr(d, "series") for ts in d.series.values())
        L.append(f"| `{name}` | {r.level or 'paper'} | {', '.join(maps) or '-'} | {_settings_text(r)} | "
                 f"{r.summary['timings']['compute']:.1f} | {cached} / {computed} | {nc} |")
    L.append("")
    L.append("'compute' is this run's time per scenario (sweeps read back from checkpoints of the same code "
             "version cost nothing; 'read back / computed' says how many there were).\n")
    bench = ROOT / "benchmarks" / "results" / "bench_maps.json"
    if bench.exists():
        b = json.loads(bench.read_text())
        L.append("Map benchmarks (`python benchmarks/bench_maps.py --which fig4a fig5a --jobs 2`, from scratch, "
                 "local process pool; each row with the date and code version of its measurement):\n")
        L.append("| map | grid | executor | wall [s] | target | ms / point | not converged | measured | code version |")
        L.append("|---|---|---|---|---|---|---|---|---|")
        target = {"fig4a": 60, "fig5a": 600}
        for k, v in sorted(b.items()):
            ver = v.get("code_version", "unknown")
            ver = f"`{ver}`" + ("" if ver == code_version() else " (not this code)")
            L.append(f"| {k} ({v['study']}) | {v['values']} x {v['omegas']} | {v['executor']} | {v['wall_s']:.1f} | "
                     f"<= {target.get(k, '-')} | {v['ms_per_point']:.1f} | {v['not_converged']} | "
                     f"{v.get('created', 'unknown')} | {ver} |")
        L.append("")
    L.append("## Figures\n")
    for k in ("fig2", "fig3", "fig4", "fig5", "fig6"):
        if k in figs:
            rel = (figdir / figs[k]).relative_to(out) if figdir.is_relative_to(out) else figdir / figs[k]
            L.append(f"![{k}]({rel.as_posix()})\n")
            L.append(f"*{CAPTIONS[k]}*\n")
    L.append("## Claims of the paper against this project\n")
    L.append("Each verdict is computed: 'agrees' when every check (computed value against the threshold beside it) "
             "passes, 'disagrees' when none does, 'partly' otherwise; a claim whose scenario was not run is 'not "
             "computed', one whose computation failed is 'error'. Thresholds that read a qualitative word of the "
             "paper ('slight', 'strongly') are stated in the note.\n")
    counts: dict[str, int] = {}
    for r in rows:
        counts[r.verdict] = counts.get(r.verdict, 0) + 1
    L.append("Summary: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())) + ".\n")
    L.append("| # | section | claim | paper | project (computed) | check: value vs threshold | verdict | note |")
    L.append("|---|---|---|---|---|---|---|---|")
    for i, r in enumerate(rows, 1):
        L.append("| " + " | ".join(str(c).replace("|", "/").replace("\n", " ") for c in _claim_cells(i, r)) + " |")
    L.append("")
    fits = runs.get("_fits")
    if fits:
        L.append("## The simplified model: best-fit c instead of +50 %\n")
        L.append("For each Case the full model's FRC (c, df, eps = 1e-4; steady states) is compared with the "
                 "simplified model (ideal inerter, viscous c only; exact response) on the same frequencies. "
                 "Area = integral of |A_simplified - A_full| over 15-25 rad/s (the grey area of Fig. 6), "
                 "max = largest pointwise difference. `best_fit_viscous` scans c in 0..100 N s/m and refines to 1e-4.\n")
        L.append("| Case | c of the full model | rule (+50 %) c | its max error | its area | best c (area) | max error | area | best c (max) | max error | area |")
        L.append("|---|---|---|---|---|---|---|---|---|---|---|")
        for c, f in sorted(fits.items()):
            p, a, m = f["paper"], f["area"], f["max"]
            L.append(f"| {c} | {FULL_C[c]:g} | {p['c']:g} | {p['max']:.2e} m ({p['rel_max']:.1%}) | {p['area']:.2e} ({p['rel_area']:.1%}) | "
                     f"{a['c']:.2f} | {a['max']:.2e} m ({a['rel_max']:.1%}) | {a['area']:.2e} ({a['rel_area']:.1%}) | "
                     f"{m['c']:.2f} | {m['max']:.2e} m ({m['rel_max']:.1%}) | {m['area']:.2e} ({m['rel_area']:.1%}) |")
        L.append("")
    L.append("## Slips of the paper\n")
    for k, v in SLIPS:
        L.append(f"- **{k}.** {v}")
    L.append("")
    L.append("## How to regenerate\n")
    L.append("```\npython -m pyfmu_wrapper.reproduce --out docs            # paper resolution, monolithic engine\n"
             "python -m pyfmu_wrapper.reproduce --quick --out /tmp/q    # small grids, about a minute\n"
             "python -m pyfmu_wrapper.reproduce --engine cosim          # the co-simulation engine instead\n"
             "python -m pyfmu_wrapper.reproduce --executor dask --scheduler tcp://HOST:8786   # on a Dask cluster\n```\n")
    L.append("Each scenario can also be run alone: `run-scenario scenarios/paper/fig4_case1.yaml --engine monolithic` "
             "(`--executor local|dask|sequential`, `--jobs N`, `--scheduler ADDRESS`, `--no-resume`).\n")
    path = out / "reproduction.md"
    path.write_text("\n".join(L) + "\n", encoding="utf-8")
    (out / "reproduction.json").write_text(json.dumps(dict(
        command=command, engine=engine, code_version=code_version(), quick=quick, missing=missing, wall_time=wall,
        created=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        claims=[r.as_row() for r in rows]), indent=1, default=float) + "\n", encoding="utf-8")
    return path


@cli_main("reproduce")
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pyfmu_wrapper.reproduce", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs", help="folder of reproduction.md (figures in <out>/figures/)")
    ap.add_argument("--results", default=None, help="results folder (default results/paper, or results/paper-quick)")
    ap.add_argument("--engine", default=DEFAULT_ENGINE, choices=sorted(ENGINES),
                    help=f"engine of every scenario (default {DEFAULT_ENGINE}); stated in the report")
    ap.add_argument("--quick", action="store_true", help="small grids everywhere (tests, smoke runs)")
    ap.add_argument("--coarse", nargs="*", default=[], help="scenario names to run on a medium grid")
    ap.add_argument("--only", nargs="*", default=None, help="run only these scenario names")
    ap.add_argument("--executor", default="local", choices=["local", "dask", "sequential"])
    ap.add_argument("--jobs", type=int, default=0, help="local processes (0: all cores)")
    ap.add_argument("--scheduler", default=None, help="dask scheduler address")
    ap.add_argument("--no-resume", dest="resume", action="store_false")
    ap.add_argument("--dpi", type=int, default=80)
    ap.add_argument("--quiet", action="store_true")
    a = ap.parse_args(argv)
    unknown = [n for n in (a.coarse + (a.only or [])) if n not in NAMES]
    if unknown:
        ap.error(f"unknown scenario names {unknown}; available: {NAMES}")
    out = Path(a.out)
    results = Path(a.results) if a.results else Path("results") / ("paper-quick" if a.quick else "paper")
    if a.jobs < 0:
        raise InputError(f"--jobs {a.jobs}: must be >= 0 (0: all cores)")
    if a.dpi < 10:
        raise InputError(f"--dpi {a.dpi}: must be >= 10")
    if a.executor == "dask" and not a.scheduler:
        raise InputError("--executor dask needs --scheduler ADDRESS")
    for opt, p in (("--out", out), ("--results", results)):
        if p.exists() and not p.is_dir():
            raise InputError(f"{opt} {p}: is a file, not a folder; reproduce writes a folder there and never "
                             "overwrites a file")
    names = a.only if a.only else NAMES
    level_of = lambda n: "quick" if a.quick else ("coarse" if n in a.coarse else None)  # noqa: E731
    ex = make_executor(a.executor, jobs=a.jobs, scheduler=a.scheduler)
    t0 = time.perf_counter()
    try:
        runs = run_all(names, results, level_of, ex, resume=a.resume, progress=not a.quiet, engine=a.engine)
    finally:
        ex.close()
    ctx = Context(runs, quick=a.quick)
    rows = evaluate(ctx)
    if "fits" in ctx.shared or any(f"fig6_case{c}" in runs for c in CASES):
        try:
            runs["_fits"] = ctx.fits()
        except Exception as exc:  # noqa: BLE001 - the claims table already flags it
            print(f"reproduce: error: simplified-model fits failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    figdir = out / "figures"
    figs = draw_figures(runs, figdir, dpi=a.dpi)
    cmd = "python -m pyfmu_wrapper.reproduce " + " ".join(argv if argv is not None else sys.argv[1:])
    missing = [n for n in NAMES if n not in runs]
    path = write_report(runs, rows, figs, out, figdir, results, a.quick, a.engine, cmd.strip(), missing,
                        time.perf_counter() - t0)
    errors = [r for r in rows if r.status == "error"]
    print(f"reproduce: wrote {path} ({len(rows)} claims, {len(figs)} figures) in {time.perf_counter() - t0:.0f} s")
    for r in errors:
        print(f"reproduce: error: claim {r.claim!r}: {r.detail}", file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
