"""``run-scenario PATH [--out DIR] [--engine monolithic]``: run a scenario file, write its results.

Exit codes: 0 success; 1 the run failed (nothing is left in the output folder); 2 bad input
(command line, missing or invalid scenario file).
"""
from __future__ import annotations

import argparse
import sys
import traceback

from ..scenario import ScenarioError, load_scenario
from ..scenario.engines import ENGINES, RunSettings
from ..scenario.output import default_output_dir, run_scenario
from ..scenario.runner import work_units


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="run-scenario", description=__doc__.splitlines()[0])
    p.add_argument("path", help="scenario YAML file (see docs/scenarios.md)")
    p.add_argument("--out", default=None, help="output folder (default: results/<scenario name>/)")
    p.add_argument("--engine", default="monolithic", choices=sorted(ENGINES),
                   help="computation engine (default: monolithic)")
    p.add_argument("--workers", type=int, default=1,
                   help="processes per nonlinear sweep (default 1: strict continuation; 0: all cores)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument("--traceback", action="store_true", help="print the full traceback on failure")
    return p


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
    settings = RunSettings(engine=args.engine, solver=scn.solver, workers=args.workers)
    from tqdm import tqdm

    with tqdm(total=work_units(scn, settings), desc=scn.name, unit="pt", disable=True if args.quiet else None,
              file=sys.stderr) as bar:
        try:
            folder = run_scenario(scn, out, settings, progress=bar.update)
        except KeyboardInterrupt:
            print("\nrun-scenario: interrupted; no results written", file=sys.stderr)
            return 130
        except Exception as exc:  # a failed run: report it, leave nothing behind
            bar.close()
            if args.traceback:
                traceback.print_exc()
            print(f"run-scenario: error: running {args.path} failed: {type(exc).__name__}: {exc}\n"
                  f"run-scenario: no results were written to {out}", file=sys.stderr)
            return 1
    print(f"run-scenario: wrote {folder}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
