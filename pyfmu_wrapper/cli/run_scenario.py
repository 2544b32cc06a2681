"""``run-scenario PATH [--out DIR] [--engine cosim|monolithic|both]``: run a scenario file, write its results.

Exit codes: 0 success; 1 the run failed (nothing is left in the output folder); 2 bad input
(command line, missing or invalid scenario file).
"""
from __future__ import annotations

import argparse
import sys
import traceback

from ..scenario import ScenarioError, load_scenario
from .errors import cli_main
from ..scenario.engines import DEFAULT_ENGINE, ENGINES, RunSettings
from ..scenario.executors import EXECUTORS, make_executor
from ..scenario.output import default_checkpoint_dir, default_output_dir, run_scenario
from ..scenario.runner import work_units


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="run-scenario", description=__doc__.splitlines()[0])
    p.add_argument("path", help="scenario YAML file (see docs/scenarios.md)")
    p.add_argument("--out", default=None, help="output folder (default: results/<scenario name>/)")
    p.add_argument("--engine", default=DEFAULT_ENGINE, choices=sorted(ENGINES),
                   help=f"computation engine (default: {DEFAULT_ENGINE}): cosim = co-simulation of the FMUs, "
                        "monolithic = single-system solver, both = co-simulation with its difference to the "
                        "monolithic solver in the summary and the plots")
    p.add_argument("--accuracy", type=float, default=None,
                   help="co-simulation: relative amplitude accuracy asked for; sets the communication step "
                        "(default 1e-3: 96 steps per forcing period; docs/cosimulation.md)")
    p.add_argument("--coupling", default=None, choices=["impulse", "force"],
                   help="co-simulation coupling: impulse (default; momentum exchange, no algebraic loop) or force "
                        "(tmd.force -> base.f_link, the inerter's algebraic loop solved by Newton every step)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes per nonlinear sweep (default 1: strict continuation; 0: all cores); "
                        "only with --executor sequential (the other executors parallelise over sweeps)")
    p.add_argument("--executor", default="local", choices=list(EXECUTORS),
                   help="where sweeps (map rows, FRC curves) run: local process pool over the cores (default), "
                        "a dask cluster (--scheduler), or sequential in this process")
    p.add_argument("--jobs", type=int, default=0, help="processes of the local executor (default 0: all cores)")
    p.add_argument("--scheduler", default=None, help="dask scheduler address, e.g. tcp://host:8786 (--executor dask)")
    p.add_argument("--no-resume", dest="resume", action="store_false",
                   help="recompute every sweep instead of reusing the checkpoints of an earlier (killed) run")
    p.add_argument("--cache", default=None,
                   help="checkpoint folder (default: <out parent>/.cache/<out name>/)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--traceback", action="store_true", help="print the full traceback on failure")
    return p


@cli_main("run-scenario")
def main(argv=None) -> int:
    args = _parser().parse_args(argv)  # exits 2 on bad options
    try:
        scn = load_scenario(args.path)
    except ScenarioError as exc:
        print(f"run-scenario: error: {exc}", file=sys.stderr)
        return 2
    out = args.out if args.out is not None else default_output_dir(scn)
    if args.workers < 0:
        print(f"run-scenario: error: --workers must be >= 0, got {args.workers}", file=sys.stderr)
        return 2
    cosim = None
    if args.accuracy is not None or args.coupling is not None:
        from dataclasses import replace

        if args.engine == "monolithic":
            print("run-scenario: error: --accuracy and --coupling are co-simulation settings; the monolithic engine "
                  "does not use them (use --engine cosim or both)", file=sys.stderr)
            return 2
        if args.accuracy is not None and not (0 < args.accuracy < 1):
            print(f"run-scenario: error: --accuracy must be in (0, 1), got {args.accuracy}", file=sys.stderr)
            return 2
        cosim = scn.cosim.settings()  # the scenario's cosim block, then the command line over it
        if args.accuracy is not None:
            cosim = replace(cosim, accuracy=args.accuracy, steps_per_period=None)
        if args.coupling is not None:
            cosim = replace(cosim, coupling=args.coupling)
    settings = RunSettings.for_scenario(scn, engine=args.engine, workers=args.workers, cosim=cosim)
    if args.jobs < 0:
        print(f"run-scenario: error: --jobs must be >= 0, got {args.jobs}", file=sys.stderr)
        return 2
    if args.executor == "dask" and not args.scheduler:
        print("run-scenario: error: --executor dask needs --scheduler ADDRESS", file=sys.stderr)
        return 2
    try:
        executor = make_executor(args.executor, jobs=args.jobs, scheduler=args.scheduler)
    except Exception as exc:
        print(f"run-scenario: error: cannot start the {args.executor} executor: {exc}", file=sys.stderr)
        return 2
    cache = args.cache if args.cache is not None else default_checkpoint_dir(out)
    from tqdm import tqdm

    with tqdm(total=work_units(scn, settings), desc=scn.name, unit="pt", disable=True if args.quiet else None,
              file=sys.stderr) as bar:
        try:
            folder = run_scenario(scn, out, settings, progress=bar.update, executor=executor, checkpoint_dir=cache,
                                  resume=args.resume)
        except KeyboardInterrupt:
            print(f"\nrun-scenario: interrupted; no results written (finished sweeps are kept in {cache}: "
                  "run again to resume)", file=sys.stderr)
            return 130
        except Exception as exc:  # a failed run: report it, leave nothing behind
            bar.close()
            if args.traceback:
                traceback.print_exc()
            print(f"run-scenario: error: running {args.path} failed: {type(exc).__name__}: {exc}\n"
                  f"run-scenario: no results were written to {out}", file=sys.stderr)
            return 1
        finally:
            executor.close()
    print(f"run-scenario: wrote {folder}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
