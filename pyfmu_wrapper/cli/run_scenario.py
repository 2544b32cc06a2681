"""``run-scenario PATH [--out DIR] [--engine ENGINE] [--workers N]``: run a scenario file, write its results.

Exit codes: 0 success; 1 the run failed (nothing is left in the output folder); 2 bad input
(command line, missing or invalid scenario file, an output folder it will not replace: a file, a
folder of files it did not write, the current folder or one of its parents); 128 + signal number
when interrupted (130 SIGINT, 143 SIGTERM, 129 SIGHUP: workers ended, partial folder removed).
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import traceback
from pathlib import Path
from types import FrameType
from typing import Any, NoReturn

from ..errors import set_max_input_size
from ..scenario.names import DEFAULT_ENGINE, ENGINE_NAMES, EXECUTORS
from .common import add_version, check_creatable
from .errors import cli_main
from .progress import Progress

# The scenario reader (numpy, yaml) is imported in main, after the command line is parsed (--help,
# --version cost nothing); the engines (pandas, scipy, numba on first use) and the plots
# (matplotlib) after the scenario file and the output folder are checked: a refusal costs no heavy import.


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="run-scenario", description=__doc__.splitlines()[0])
    p.add_argument("path", help="scenario YAML file (see docs/scenarios.md)")
    p.add_argument(
        "--out",
        default=None,
        help="output folder (default: results/<scenario name>/); a new or empty folder or an earlier "
        "result of run-scenario, which is replaced in one step when the run is complete",
    )
    p.add_argument(
        "--engine",
        default=DEFAULT_ENGINE,
        choices=list(ENGINE_NAMES),
        help=f"computation engine (default: {DEFAULT_ENGINE}): cosim = co-simulation of the FMUs, "
        "monolithic = single-system solver, both = co-simulation with its difference to the "
        "monolithic solver in the summary and the plots",
    )
    p.add_argument(
        "--accuracy",
        type=float,
        default=None,
        help="co-simulation: relative amplitude accuracy asked for; sets the communication step "
        "(default 1e-3: 96 steps per forcing period; docs/cosimulation.md)",
    )
    p.add_argument(
        "--coupling",
        default=None,
        choices=["impulse", "force"],
        help="co-simulation coupling: impulse (default; momentum exchange, no algebraic loop) or force "
        "(tmd.force -> base.f_link, the inerter's algebraic loop solved by Newton every step)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="processes that compute sweeps in parallel, one FRC curve or map row each (default 0: "
        "all cores); the only parallelism switch. Every sweep is a strict continuation in one "
        "process, so the numbers do not depend on N. With --executor sequential: 1 only",
    )
    p.add_argument("--jobs", type=int, default=None, metavar="N", help="deprecated alias of --workers")
    p.add_argument(
        "--executor",
        default="local",
        choices=list(EXECUTORS),
        help="where sweeps (map rows, FRC curves) run: local process pool of --workers processes "
        "(default), a dask cluster (--scheduler; its workers decide), or sequential in this process",
    )
    p.add_argument("--scheduler", default=None, help="dask scheduler address, e.g. tcp://host:8786 (--executor dask)")
    p.add_argument(
        "--no-resume",
        dest="resume",
        action="store_false",
        help="recompute every sweep instead of reusing the checkpoints of an earlier (killed) run",
    )
    p.add_argument(
        "--cache", default=None, help="checkpoint folder (default: <out>.checkpoints/ beside the output folder)"
    )
    p.add_argument("--quiet", action="store_true", help="no progress report (the closing lines are still printed)")
    p.add_argument(
        "--progress-every",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="when stderr is not a terminal (a log, a pipe): one progress line every SECONDS "
        "(default 5); on a terminal the line is redrawn every second",
    )
    p.add_argument("--traceback", action="store_true", help="print the full traceback on failure")
    p.add_argument(
        "--max-input-size",
        type=float,
        default=None,
        metavar="MB",
        help="the largest scenario file read, in MB (default 16): a larger file is refused before it is read",
    )
    add_version(p)
    return p


class Interrupted(KeyboardInterrupt):
    """SIGTERM or SIGHUP turned into the same clean stop as SIGINT (Ctrl-C)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


def _raise_interrupt(signum: int, frame: FrameType | None) -> NoReturn:
    for name in ("SIGTERM", "SIGHUP"):  # one clean stop: a second signal does not break the cleanup
        if getattr(signal, name, None) is not None:
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    raise Interrupted(signum)


def _install_signals() -> dict:
    """SIGTERM and SIGHUP behave as SIGINT (only possible from the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    old = {}
    for name in ("SIGTERM", "SIGHUP"):
        sig = getattr(signal, name, None)
        if sig is not None:
            old[sig] = signal.signal(sig, _raise_interrupt)
    return old


def _err(msg: str) -> int:
    print(f"run-scenario: error: {msg}", file=sys.stderr)
    return 2


def _workers(args: argparse.Namespace) -> tuple[int | None, str | None]:
    """The one parallelism switch (--workers, --jobs its deprecated alias): (value, error)."""
    if args.jobs is not None:
        print("run-scenario: note: --jobs is deprecated; use --workers (the same number of processes)", file=sys.stderr)
        if args.workers is not None and args.workers != args.jobs:
            return None, f"--jobs {args.jobs} and --workers {args.workers} disagree; give --workers only"
    n = args.workers if args.workers is not None else args.jobs
    opt = "--workers" if args.workers is not None else "--jobs"
    if n is not None and n < 0:
        return None, f"{opt} must be >= 0 (0: all cores), got {n}"
    if args.executor == "sequential" and n not in (None, 1):
        return (
            None,
            f"--executor sequential computes in this process only; {opt} {n} would not be used (drop it, "
            "or use --executor local)",
        )
    if args.executor == "dask" and n is not None:
        return None, f"with --executor dask the cluster's workers compute; {opt} {n} would not be used (drop it)"
    return (0 if n is None else n), None


@cli_main("run-scenario")
def main(argv: list[str] | None = None) -> int:
    args = _parser().parse_args(argv)  # exits 2 on bad options
    set_max_input_size(args.max_input_size)
    from ..safeio import Diverted, OutputError
    from ..scenario import ScenarioError, load_scenario
    from ..scenario.outdir import check_output_dir, default_checkpoint_dir, default_output_dir

    try:
        scn = load_scenario(args.path)
    except ScenarioError as exc:
        return _err(str(exc))
    out = args.out if args.out is not None else default_output_dir(scn)
    if args.cache is not None and (Path(args.cache).is_file() or Path(args.cache).is_symlink()):
        return _err(f"--cache {args.cache}: is a file or a link; give a folder for the checkpoints")
    workers, problem = _workers(args)
    if problem:
        return _err(problem)
    if args.accuracy is not None or args.coupling is not None:
        if args.engine == "monolithic":
            return _err(
                "--accuracy and --coupling are co-simulation settings; the monolithic engine "
                "does not use them (use --engine cosim or both)"
            )
        if args.accuracy is not None and not (0 < args.accuracy < 1):
            return _err(f"--accuracy must be in (0, 1), got {args.accuracy}")
    if args.executor == "dask" and not args.scheduler:
        return _err("--executor dask needs --scheduler ADDRESS")
    if not args.progress_every > 0:
        return _err(f"--progress-every must be > 0 seconds, got {args.progress_every}")
    try:  # before anything is computed: never replace what run-scenario did not write
        cache = args.cache if args.cache is not None else default_checkpoint_dir(out)
        notes = check_output_dir(out, scn.path, cache)
    except OutputError as exc:
        return _err(str(exc))
    check_creatable(out)  # a folder it cannot make (--out /proc/foo): one line, exit 2

    # the command line, the scenario and the output folder are checked: now the engines
    from ..scenario.engines import RunSettings
    from ..scenario.executors import make_executor
    from ..scenario.output import run_scenario
    from ..scenario.runner import instant_units, work_units

    cosim = None
    if args.accuracy is not None or args.coupling is not None:
        from dataclasses import replace

        cosim = scn.cosim.settings()  # the scenario's cosim block, then the command line over it
        if args.accuracy is not None:
            cosim = replace(cosim, accuracy=args.accuracy, steps_per_period=None)
        if args.coupling is not None:
            cosim = replace(cosim, coupling=args.coupling)
    settings = RunSettings.for_scenario(scn, engine=args.engine, workers=1, cosim=cosim)
    refused = _refused_curves(scn, settings) if args.engine != "monolithic" else []
    for full, text in refused:
        if full:
            return _err(text)
        print(f"run-scenario: warning: {text}", file=sys.stderr)
    for note in notes:
        print(f"run-scenario: note: {note}", file=sys.stderr)
    try:
        executor = make_executor(args.executor, jobs=workers, scheduler=args.scheduler)
    except Exception as exc:
        return _err(f"cannot start the {args.executor} executor: {exc}")
    datas: list = []
    stats: dict = {}
    old_handlers = _install_signals()
    try:
        with Progress(
            work_units(scn, settings),
            scn.name,
            interval=args.progress_every,
            enabled=not args.quiet,
            instant=instant_units(scn, settings),
        ) as bar:
            folder = run_scenario(
                scn,
                out,
                settings,
                progress=bar,
                executor=executor,
                checkpoint_dir=cache,
                resume=args.resume,
                collect=datas,
                stats_out=stats,
            )
    except KeyboardInterrupt as exc:
        executor.abort()
        signum = getattr(exc, "signum", signal.SIGINT)
        name = signal.Signals(signum).name
        print(
            f"\nrun-scenario: interrupted ({name}); workers ended, no results written to {out} (finished sweeps "
            f"are kept in {cache}: run the same command again to resume); exit status {128 + signum}",
            file=sys.stderr,
        )
        return 128 + signum
    except Diverted as exc:  # the folder changed during the run: the result is beside it
        _report(datas, stats, cache)
        return _err(str(exc))
    except OutputError as exc:
        executor.abort()
        return _err(str(exc))
    except Exception as exc:  # a failed run: report it, leave nothing behind
        executor.abort()
        if args.traceback:
            traceback.print_exc()
        print(
            f"run-scenario: error: running {args.path} failed: {type(exc).__name__}: {exc}\n"
            f"run-scenario: no results were written to {out}",
            file=sys.stderr,
        )
        return 1
    finally:
        for sig, h in old_handlers.items():
            signal.signal(sig, h)
        executor.close()
    _report(datas, stats, cache)
    print(f"run-scenario: wrote {folder}" + (f" (checkpoints: {cache})" if Path(cache).exists() else ""))
    return 0


def _refused_curves(scn: Any, settings: Any) -> list[tuple[bool, str]]:
    """The configurations whose structure the co-simulation cannot step at some frequency (a time scale
    far below the forcing period): (every frequency refused, the sentence naming the parameters)."""
    from ..cosim.settings import CosimSettings
    from ..scenario.engines import cosim_engine
    from ..scenario.runner import study_configurations

    cs = settings.cosim if isinstance(settings.cosim, CosimSettings) else CosimSettings()
    cap = cs.max_steps_per_period
    out = []
    engine = cosim_engine(scn.base)
    refusal = None if engine is None else engine.refusal
    if refusal is None:  # the model's co-simulation takes its steps from the accuracy asked for
        return []
    for where, tmd, omegas in study_configurations(scn):
        why = refusal(scn.base, tmd, omegas, cap)
        if why is not None:
            full = why.startswith(f"{len(omegas)} of {len(omegas)} ")
            out.append(
                (
                    full,
                    f"{scn.path}: {where}: the co-simulation cannot resolve {why}"
                    + ("" if full else "; those points are reported not converged"),
                )
            )
    return out


def _report(datas: list, stats: dict, cache: str | Path) -> None:
    """The closing lines: per study, what did not converge; and how much came from checkpoints."""
    from ..scenario.summary import study_report

    for d in datas:
        for line in study_report(d):
            print(f"run-scenario: {line}")
    for v in stats.values():
        for r in v.rejected:
            print(f"run-scenario: note: checkpoint not used, computed again: {r}")
    cached = sum(v.cached for v in stats.values())
    total = cached + sum(v.computed for v in stats.values())
    if cached:
        print(
            f"run-scenario: note: {cached} of {total} sweeps were read from the checkpoints of an earlier run in "
            f"{cache}, not computed now (--no-resume recomputes them)"
        )


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
