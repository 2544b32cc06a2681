"""``reproduce``: reproduce the figures and claims of Brzeski & Perlikowski (2017) and write ``docs/reproduction.md``.

    reproduce [--quick] [--out docs] [--results results/paper] [--engine monolithic|cosim|both]
              [--executor local|dask|sequential] [--jobs N] [--scheduler ADDR]
              [--coarse NAME ...] [--only NAME ...] [--no-resume]

Runs every scenario of ``scenarios/paper/`` (the paper-resolution variants of ``scenarios/``) with
the scenario runner and the engine named by ``--engine`` (default monolithic; the report states it and
every ``summary.json`` records it with the settings it used), draws the paper's Figs. 2-6 from the
results (PNG under ``<out>/figures/``) and writes ``<out>/reproduction.md``: each claim of the paper
beside the computed number, the reference value, the threshold and the verdict of that comparison
(:mod:`pyfmu_wrapper.paper.claims`). Finished sweeps are checkpointed under ``<results>/.cache/``, keyed by
the code version and every setting, so rows computed by older code are never reused.

``--quick`` shrinks every grid (a minute on one core; used by the tests); ``--coarse NAME`` shrinks only
the named scenarios to a medium grid. Quick or coarse grids are stated in the report. Exit status 1
when a claim could not be computed because its computation failed (the row says why).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..paper.names import CASES, DEFAULT_ENGINE, NAMES
from ..safeio.files import OwnedFiles
from ..scenario.names import ENGINE_NAMES, EXECUTORS
from .common import add_version
from .errors import cli_main

#: the marker of the files reproduce writes into its --out folder (docs/ by default)
REPRODUCE_MARKER = ".reproduce.json"


@cli_main("reproduce")
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="reproduce", description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="docs", help="folder of reproduction.md (figures in <out>/figures/)")
    ap.add_argument("--results", default=None, help="results folder (default results/paper, or results/paper-quick)")
    ap.add_argument(
        "--engine",
        default=DEFAULT_ENGINE,
        choices=list(ENGINE_NAMES),
        help=f"engine of every scenario (default {DEFAULT_ENGINE}); stated in the report",
    )
    ap.add_argument("--quick", action="store_true", help="small grids everywhere (tests, smoke runs)")
    ap.add_argument("--coarse", nargs="*", default=[], help="scenario names to run on a medium grid")
    ap.add_argument("--only", nargs="*", default=None, help="run only these scenario names")
    ap.add_argument("--executor", default="local", choices=list(EXECUTORS))
    ap.add_argument("--jobs", type=int, default=0, help="local processes (0: all cores)")
    ap.add_argument("--scheduler", default=None, help="dask scheduler address")
    ap.add_argument("--no-resume", dest="resume", action="store_false")
    ap.add_argument("--dpi", type=int, default=80)
    ap.add_argument("--quiet", action="store_true")
    add_version(ap)
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
    for opt, p in (("--results", results),):
        if p.exists() and not p.is_dir():
            raise InputError(
                f"{opt} {p}: is a file, not a folder; reproduce writes a folder there and never overwrites a file"
            )
    # the command line is checked: now the engines, the claims and the figures (pandas, scipy, matplotlib)
    from ..paper.claims import Context, evaluate
    from ..paper.figures import FIGURES, draw_figures
    from ..paper.report import REPORT_FILES, write_report
    from ..paper.reproduce import run_all
    from ..scenario.executors import make_executor

    owned = OwnedFiles(out, "reproduce", REPRODUCE_MARKER)
    owned.check(REPORT_FILES + [f"figures/{f}.png" for f in FIGURES])  # before computing
    names = a.only if a.only else NAMES
    level_of = lambda n: "quick" if a.quick else ("coarse" if n in a.coarse else None)  # noqa: E731
    ex = make_executor(a.executor, jobs=a.jobs, scheduler=a.scheduler)
    t0 = time.perf_counter()
    try:
        runs: dict[str, Any] = run_all(  # the runs, and the simplified-model fits under '_fits'
            names, results, level_of, ex, resume=a.resume, progress=not a.quiet, engine=a.engine
        )
    finally:
        ex.close()
    ctx = Context(runs, quick=a.quick)
    rows = evaluate(ctx)
    if "fits" in ctx.shared or any(f"fig6_case{c}" in runs for c in CASES):
        try:
            runs["_fits"] = ctx.fits()
        except Exception as exc:  # noqa: BLE001 - the claims table already flags it
            print(f"reproduce: error: simplified-model fits failed: {type(exc).__name__}: {exc}", file=sys.stderr)
    cmd = "reproduce " + " ".join(argv if argv is not None else sys.argv[1:])
    missing = [n for n in NAMES if n not in runs]
    with tempfile.TemporaryDirectory(prefix="reproduce-") as stage_dir:  # drawn here, then put in place
        stage = Path(stage_dir)
        figs = draw_figures(runs, stage / "figures", dpi=a.dpi)
        write_report(
            runs,
            rows,
            figs,
            stage,
            stage / "figures",
            results,
            a.quick,
            a.engine,
            cmd.strip(),
            missing,
            time.perf_counter() - t0,
        )
        owned.write_tree(stage)
    path = out / "reproduction.md"
    for name, where in owned.diverted:
        print(
            f"reproduce: warning: {out / name} changed during the run and was kept; the new one is {where}",
            file=sys.stderr,
        )
    errors = [r for r in rows if r.status == "error"]
    print(f"reproduce: wrote {path} ({len(rows)} claims, {len(figs)} figures) in {time.perf_counter() - t0:.0f} s")
    for r in errors:
        print(f"reproduce: error: claim {r.claim!r}: {r.detail}", file=sys.stderr)
    return 1 if errors else 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
