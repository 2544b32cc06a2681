"""``optimise SCENARIO|--case N --parameter P [--objective NAME] [--band LO HI] [--bounds LO HI]``.

Minimise an objective of the base's frequency response over one parameter (see
docs/optimisation.md). The configuration comes from a scenario file (its base, tmd, frequency
grid and solver block) or from one of the paper's Cases (``--case 1|2|3``: ideal inerter, c = 0,
df = 0, default base). ``--set tmd.damping=10`` changes other parameters first.

Examples::

    optimise --case 1 --parameter damping                      # -> 56.45 (paper: 56.38)
    optimise --case 3 --parameter friction_force --bounds 0 40 # -> 15.44 (paper: 15.44)
    optimise scenarios/viscous_case2.yaml --parameter tmd.damping --objective peak

Exit codes: 0 success; 1 the optimisation failed; 2 bad input.
"""

from __future__ import annotations

import argparse
import json
import sys
import traceback
from typing import Any

from ..errors import plain_text
from ..paper.objectives import OBJECTIVES, OptimisationError
from ..paper.optimise import OptimiseConfig, optimise, split_parameter, with_parameter
from ..physics.params import BaseParams, ParameterError, paper_case
from ..safeio.files import OwnedFiles
from ..safeio.tree import OutputError
from .common import add_version
from .errors import cli_main

# scipy, pandas and numba are imported when the optimiser first runs (paper/optimise.py, _jit.py),
# after the command line and the scenario file are checked


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="optimise",
        description=__doc__.splitlines()[0].strip("`"),
        epilog="objectives: " + "; ".join(f"{o.name}: {o.summary}" for o in OBJECTIVES.values()),
    )
    p.add_argument("scenario", nargs="?", help="scenario YAML file (see docs/scenarios.md)")
    p.add_argument("--case", type=int, choices=(1, 2, 3), help="the paper's Case instead of a scenario file")
    p.add_argument(
        "--parameter",
        "-p",
        required=False,
        help="parameter to optimise: tmd.damping, tmd.friction_force, ... (bare name: the TMD's)",
    )
    p.add_argument(
        "--objective",
        "-o",
        default="h2",
        choices=sorted(OBJECTIVES),
        help="objective to minimise (default h2, the one that reproduces the paper's values)",
    )
    p.add_argument(
        "--band",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        default=None,
        help="frequency band [rad/s] (default: the scenario's frequencies, or 15 25 with --case)",
    )
    p.add_argument(
        "--points", type=int, default=None, help="frequencies in the band (default 2001 linear, 101 nonlinear)"
    )
    p.add_argument(
        "--bounds",
        nargs=2,
        type=float,
        metavar=("LO", "HI"),
        default=None,
        help="search interval of the parameter (default 0 100 for damping and friction_force)",
    )
    p.add_argument(
        "--direction",
        choices=("up", "down", "both"),
        default=None,
        help="sweep direction for nonlinear configurations (default: the scenario's, or up)",
    )
    p.add_argument("--scan", type=int, default=None, help="points of the coarse scan before refinement")
    p.add_argument("--xtol", type=float, default=None, help="absolute tolerance on the parameter")
    p.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="set a parameter before optimising, e.g. --set tmd.damping=10 (repeatable)",
    )
    p.add_argument(
        "--json",
        dest="json_out",
        default=None,
        metavar="FILE",
        help="also write the result and all evaluations as JSON ('-' for stdout)",
    )
    p.add_argument("--list-objectives", action="store_true", help="list the objectives and exit")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--traceback", action="store_true", help="print the full traceback on failure")
    add_version(p)
    return p


def _fail(msg: str) -> int:
    print(f"optimise: error: {' '.join(plain_text(msg).split())}", file=sys.stderr)
    return 2


def _json_target(path: str | None) -> OwnedFiles | None:
    """Where --json PATH goes: a file optimise owns in its folder (:mod:`pyfmu_wrapper.safeio.files`:
    a new file, or one optimise wrote and nobody changed since); refused before optimising otherwise."""
    if path in (None, "-"):
        return None
    import os

    if os.path.isdir(path):
        raise OutputError(f"--json {path}: is a folder; give a file name")
    p = os.path.abspath(path)
    owned = OwnedFiles(os.path.dirname(p), "optimise", ".optimise.json", option="--json")
    owned.check([os.path.basename(p)])
    return owned


@cli_main("optimise")
def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)  # exits 2 on bad options
    if args.list_objectives:
        for o in OBJECTIVES.values():
            print(f"{o.name:14s} {o.summary}")
        return 0
    if args.parameter is None:
        return _fail("--parameter is required")
    if (args.scenario is None) == (args.case is None):
        return _fail("give either a scenario file or --case N (not both)")
    if args.xtol is not None and not 0 < args.xtol < float("inf"):
        return _fail(f"--xtol must be a tolerance > 0, got {args.xtol}")
    if args.scan is not None and args.scan < 3:
        return _fail(f"--scan must be >= 3 points, got {args.scan}")
    try:
        owned = _json_target(args.json_out)
    except OutputError as exc:
        return _fail(str(exc))
    kw: dict[str, Any] = {}  # OptimiseConfig's settings from the scenario
    if args.scenario is not None:
        from ..scenario import ScenarioError, load_scenario

        try:
            scn = load_scenario(args.scenario)
        except ScenarioError as exc:
            return _fail(str(exc))
        base, tmd = scn.base, scn.tmd
        kw.update(settings=scn.solver.settings(), linear=scn.solver.linear)
        direction = args.direction or scn.sweep.direction
        if args.band is None:
            kw["omegas"] = scn.frequencies
        label = scn.name
    else:
        base, tmd = BaseParams(), paper_case(args.case)
        direction = args.direction or "up"
        label = f"Case {args.case}"
    try:
        for item in args.set:
            name, sep, value = item.partition("=")
            if not sep:
                return _fail(f"--set wants NAME=VALUE, got {item!r}")
            split_parameter(name.strip())
            try:
                number = float(value)
            except ValueError:
                return _fail(f"--set {item}: {value.strip()!r} is not a number")
            try:
                base, tmd = with_parameter(base, tmd, name.strip(), number)
            except (OptimisationError, ParameterError) as exc:
                return _fail(f"--set {item}: {exc}")
        split_parameter(args.parameter)
    except (OptimisationError, ParameterError, ValueError) as exc:
        return _fail(str(exc))

    def progress(v: float, J: float) -> None:
        if not args.quiet:
            print(f"  {args.parameter} = {v:<12.6g} {args.objective} = {J:.8g}", file=sys.stderr, flush=True)

    try:
        cfg = OptimiseConfig(
            band=tuple(args.band or (15.0, 25.0)),
            bounds=args.bounds,
            points=args.points,
            direction=direction,
            scan=args.scan,
            xtol=args.xtol,
            **kw,
        )
        res = optimise(base, tmd, args.parameter, args.objective, cfg, progress=progress)
    except (OptimisationError, ParameterError) as exc:
        return _fail(str(exc))
    except KeyboardInterrupt:
        print("\noptimise: interrupted", file=sys.stderr)
        return 1
    except Exception as exc:  # noqa: BLE001 - report, exit 1
        if args.traceback:
            traceback.print_exc()
        print(f"optimise: failed: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print(f"{label}: {res.summary()}")
    if not res.evaluations["converged"].all():
        print("optimise: warning: some steady states did not converge (see --json)", file=sys.stderr)
    if args.json_out:
        doc = dict(
            source=args.scenario or f"case {args.case}",
            parameter=res.parameter,
            objective=res.objective,
            value=res.value,
            objective_value=res.objective_value,
            bounds=list(res.bounds),
            band=None if res.band is None else list(res.band),
            direction=direction,
            at_bound=res.at_bound,
            wall_time=res.wall_time,
            evaluations=res.evaluations.to_dict(orient="records"),
        )
        text = json.dumps(doc, indent=2)
        if args.json_out == "-":
            print(text)
        elif owned is not None:
            import os

            owned.write(os.path.basename(os.path.abspath(args.json_out)), (text + "\n").encode())
            for _, beside in owned.diverted:
                print(
                    f"optimise: error: {args.json_out} changed during the run and was kept; wrote {beside}",
                    file=sys.stderr,
                )
                return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
