"""Console scripts: ``diagnose``, ``make-benchmark``, ``score``.

Bad input (data, model file, command line, output folder) is one line on stderr naming the file,
row/line and key, exit status 2 (:mod:`pyfmu_wrapper.cli.errors`). The diagnosis and the output
folders are :mod:`pyfmu_wrapper.diagnose.run`.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..diagnose.outfolder import BENCHMARK_MARKER, DIAGNOSE_MARKER, ResultFolder, check_out_file, check_out_folder
from ..diagnose.record_checks import set_max_record_size
from ..diagnose.suites import SUITES, counts_from_fractions, defaults_help
from ..errors import InputError, set_max_input_size
from .common import add_version, check_creatable
from .errors import cli_main

# the diagnosis (numpy, pandas when a record's rows are read, scipy, numba, matplotlib) is imported in
# each main after its command line is parsed; diagnose checks dataset.yaml and every record's header
# before reading any record (pyfmu_wrapper/diagnose/data.py)


@cli_main("diagnose")
def main_diagnose(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="diagnose",
        description="Localise, attribute and quantify the gap "
        "between a nominal model and measurements (see docs/diagnose.md).",
    )
    ap.add_argument("dataset", help="folder with dataset.yaml and CSV records")
    ap.add_argument("--model", help="YAML with the nominal model (overrides the dataset's 'nominal')")
    ap.add_argument(
        "--out",
        required=True,
        help="output folder (report.md, diagnosis.json, PNGs): new, empty, or "
        "a previous diagnose result (replaced as a whole)",
    )
    ap.add_argument(
        "--max-record-size",
        type=float,
        default=None,
        metavar="MB",
        help="the largest record file read (default 1024 MB)",
    )
    ap.add_argument(
        "--max-input-size", type=float, default=None, metavar="MB", help="the largest YAML file read (default 16 MB)"
    )
    ap.add_argument("--quiet", action="store_true", help="no progress report (the verdict is still printed)")
    ap.add_argument(
        "--progress-every",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="when stderr is not a terminal (a log, a pipe): one progress line every SECONDS while candidates "
        "are fitted (default 5); on a terminal the line is redrawn every second",
    )
    add_version(ap)
    a = ap.parse_args(argv)
    from ..diagnose.run import flagged_lines, run_diagnosis

    set_max_record_size(a.max_record_size)
    set_max_input_size(a.max_input_size)
    if not a.progress_every > 0:
        raise InputError(f"--progress-every must be > 0 seconds, got {a.progress_every}")
    out = check_out_folder(a.out, "diagnose", DIAGNOSE_MARKER)
    check_creatable(out)
    from ..diagnose import progress
    from .progress import StageProgress

    with StageProgress("diagnose", interval=a.progress_every, enabled=not a.quiet) as bar:
        old = progress.set_reporter(bar)
        try:
            with ResultFolder(out, DIAGNOSE_MARKER) as tmp:
                res = run_diagnosis(a.dataset, tmp, a.model)
        finally:
            progress.set_reporter(old)
    if "verdict" in res:
        print(res["verdict"]["text"])
        for d in res["verdict"].get("disagreements", []):
            print("note:", d)
    else:
        print(res["attribution"]["verdict"])
    for line in flagged_lines(res):
        print("flagged:", line)
    for r in res.get("input_reduced", []):
        print(f"reduced: {r['record']}: {r['rows']:,} rows -> {r['samples']:,} samples (averages of {r['block']})")
    h = res.get("held_out")
    if h and "nrmse_before" in h:
        gc = h["gap_closed"]
        print(
            f"held-out NRMSE {h['nrmse_before']:.4f} -> {h['nrmse_after']:.4f}"
            + ("" if gc is None else f", gap closed {100 * gc:.1f} %")
        )
    if res.get("corrected"):
        print(f"corrected model: {out / 'corrected'}")
    print(f"report: {out / 'report.md'}")
    return 0


@cli_main("make-benchmark")
def main_make_benchmark(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="make-benchmark",
        description="Generate withheld-effect datasets "
        "(labels in OUT/manifest.json, never read by diagnose and never printed).",
    )
    ap.add_argument(
        "folder",
        nargs="?",
        default=None,
        help="output folder (the same as --out): new, empty, or a previous make-benchmark result",
    )
    ap.add_argument("--out", default=None, help="output folder: new, empty, or a previous make-benchmark result")
    ap.add_argument(
        "--example",
        choices=["swept-sine"],
        default=None,
        help="write one example dataset instead of a benchmark: swept-sine is the worked example of "
        "docs/diagnose.md (three records, accelerations only; run diagnose on the folder)",
    )
    ap.add_argument(
        "--suite",
        choices=["system", "link", "transient", "frame"],
        default="system",
        help="system: the coupled base + TMD simulated and measured as a rig does (default); "
        "link: one TMD link on a displacement-controlled rig; transient: the coupled system under "
        "swept sines, random force, hammer impulses and free decays (docs/diagnose.md, Check 3); "
        "frame: shear frames of 3 or 5 storeys with a TMD or TMDI, accelerations under sweeps, random "
        "force and hammer impulses (issue 41; score with benchmarks/bench_diagnose_frame.py)",
    )
    ap.add_argument(
        "--seconds", type=float, default=None, help="transient suite only: length of each record [s] (default 60)"
    )
    ap.add_argument(
        "--effects",
        default=None,
        metavar="E1,E2",
        help="transient suite only: draw the singles and pairs from these in-vocabulary effects (e.g. play,friction)",
    )
    ap.add_argument(
        "--part",
        default=None,
        metavar="K/N",
        help="transient suite only: write part K of N (the datasets i with i %% N == K - 1, the same ones a "
        "whole run writes), so N processes or machines share a long generation; score each folder on its own",
    )
    ap.add_argument("-n", type=int, default=None, help=f"number of datasets (default: {defaults_help('n')})")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--clean-fraction",
        type=float,
        default=None,
        help=f"share of clean datasets (default: {defaults_help('clean')})",
    )
    ap.add_argument(
        "--pair-fraction",
        type=float,
        default=None,
        help=f"share of two-effect datasets (default: {defaults_help('pair')})",
    )
    ap.add_argument(
        "--oov-fraction",
        type=float,
        default=None,
        help=f"system, transient and frame suites: share of out-of-vocabulary datasets (default: "
        f"{defaults_help('oov')}; with --clean-fraction or --pair-fraction given, at most what they leave)",
    )
    ap.add_argument("--noise", type=float, default=None, help="link suite only: force noise std [N] (default 0.5)")
    ap.add_argument(
        "--held-out-oov",
        action="store_true",
        help="system suite: draw the out-of-vocabulary datasets from the kinds diagnose was never tuned on "
        "(asymmetric TMD spring, quadratic base drag; docs/diagnose.md)",
    )
    add_version(ap)
    a = ap.parse_args(argv)
    if a.folder is not None and a.out is not None and a.folder != a.out:
        raise InputError(f"give the output folder once: {a.folder} and --out {a.out} differ")
    a.out = a.out if a.out is not None else a.folder
    if a.out is None:
        ap.error("the output folder is required (FOLDER or --out FOLDER)")
    if a.example is not None:
        from ..diagnose.system.example import write_example

        out = check_out_folder(a.out, "make-benchmark", BENCHMARK_MARKER)
        check_creatable(out)
        with ResultFolder(out, BENCHMARK_MARKER) as tmp:
            files = write_example(a.example, tmp)
        print(f"wrote the {a.example} example dataset ({', '.join(files)}) to {out}; run: diagnose {out} --out OUT")
        return 0
    if a.n is not None and a.n < 1:
        raise InputError(f"-n {a.n}: the number of datasets must be >= 1")
    for name, v in (
        ("--clean-fraction", a.clean_fraction),
        ("--pair-fraction", a.pair_fraction),
        ("--oov-fraction", a.oov_fraction),
    ):
        if v is not None and not 0.0 <= v <= 1.0:
            raise InputError(f"{name} {v}: must be in [0, 1]")
    total = sum(v or 0.0 for v in (a.clean_fraction, a.pair_fraction, a.oov_fraction))
    if total > 1.0:
        raise InputError(f"--clean-fraction + --pair-fraction + --oov-fraction = {total:g}: must be <= 1")
    if a.noise is not None and (not a.noise >= 0.0 or a.noise == float("inf")):
        raise InputError(f"--noise {a.noise}: must be a finite force noise std >= 0 N")
    if a.seconds is not None and (a.suite != "transient" or not 1.0 <= a.seconds <= 3600.0):
        raise InputError(f"--seconds {a.seconds}: only for --suite transient, from 1 to 3600 s")
    part = None
    if a.part is not None:
        k, _, n_parts = a.part.partition("/")
        if a.suite != "transient" or not (k.isdigit() and n_parts.isdigit() and 1 <= int(k) <= int(n_parts)):
            raise InputError(f"--part {a.part}: only for --suite transient, written K/N with 1 <= K <= N (e.g. 1/2)")
        part = (int(k) - 1, int(n_parts))
    if a.suite != "link" and a.noise is not None:
        raise InputError(
            f"--noise {a.noise}: the {a.suite} suite draws its sensor noise per channel and record (a share of "
            "the rms, docs/diagnose.md); --noise is the link suite's force noise: leave it out or use --suite link"
        )
    effects = None
    if a.effects is not None:
        from ..diagnose.system.transient_suite import IN_VOCAB

        effects = [e.strip() for e in a.effects.split(",") if e.strip()]
        bad = [e for e in effects if e not in IN_VOCAB]
        if a.suite != "transient" or bad or not effects:
            raise InputError(
                f"--effects {a.effects}: only for --suite transient, a comma-separated list of {', '.join(IN_VOCAB)}"
            )
    if a.held_out_oov and a.suite != "system":
        raise InputError(f"--held-out-oov: only for --suite system (the {a.suite} suite has its own kinds)")
    if a.suite == "link" and a.oov_fraction is not None:
        raise InputError("--oov-fraction: the link suite has no out-of-vocabulary class; use --suite system")
    composition = None
    if a.suite != "link":  # the OOV share not given is cut to what the others leave
        composition = counts_from_fractions(a.suite, a.n, a.clean_fraction, a.pair_fraction, a.oov_fraction)
    else:
        link = SUITES["link"]
        if (link.clean if a.clean_fraction is None else a.clean_fraction) + (
            link.pair if a.pair_fraction is None else a.pair_fraction
        ) > 1.0:
            raise InputError(
                f"--clean-fraction + --pair-fraction (link defaults {link.clean:g} and {link.pair:g} for the one "
                "not given) must be <= 1"
            )
    from ..diagnose.link.benchmark import make_benchmark

    out = check_out_folder(a.out, "make-benchmark", BENCHMARK_MARKER)
    check_creatable(out)
    with ResultFolder(out, BENCHMARK_MARKER) as tmp:
        if a.suite != "link":
            make: Callable[..., list[Any]]
            if a.suite == "system":
                from ..diagnose.system.suite import make_system_benchmark

                make, extra = make_system_benchmark, {"held_out_oov": a.held_out_oov}
            elif a.suite == "frame":
                from ..diagnose.framebench.suite import make_frame_benchmark

                make, extra = make_frame_benchmark, {}
            else:
                from ..diagnose.system.transient_suite import make_transient_benchmark

                make = make_transient_benchmark
                extra = {"seconds": 60.0 if a.seconds is None else a.seconds, "part": part, "effects": effects}
            assert composition is not None
            nc, _, npair, noov = composition
            # progress without the labels: a blind benchmark does not print what it hides
            man = make(
                tmp,
                n=sum(composition),
                seed=a.seed,
                n_clean=nc,
                n_pair=npair,
                n_oov=noov,
                progress=lambda r: print(
                    f"{r['dataset']}: written" + (f" ({r['seconds']:.1f} s)" if "seconds" in r else ""), flush=True
                ),
                **extra,
            )
        else:
            link = SUITES["link"]
            man = make_benchmark(
                tmp,
                n=link.n if a.n is None else a.n,
                seed=a.seed,
                clean_fraction=link.clean if a.clean_fraction is None else a.clean_fraction,
                pair_fraction=link.pair if a.pair_fraction is None else a.pair_fraction,
                noise=0.5 if a.noise is None else a.noise,
            )
    print(
        f"wrote {len(man)} {a.suite if a.suite != 'system' else 'system-level'} datasets and manifest.json "
        f"(the hidden labels) to {out}" + (f" (part {a.part})" if part else "")
    )
    return 0


@cli_main("score")
def main_score(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="score", description="Run diagnose on a benchmark and score it.")
    ap.add_argument("benchmark", help="folder written by make-benchmark")
    ap.add_argument("--out", help="write score.json here (a new file, or a previous score.json)")
    add_version(ap)
    a = ap.parse_args(argv)
    from ..diagnose.link.benchmark import score
    from ..diagnose.run import load_manifest

    try:
        suite = json.loads((Path(a.benchmark) / "manifest.json").read_text(encoding="utf-8")).get("suite")
    except (OSError, ValueError, AttributeError):
        suite = None  # load_manifest says what is wrong
    if suite == "frame":
        raise InputError(
            f"{a.benchmark}: a frame benchmark (make-benchmark --suite frame) is scored by "
            "benchmarks/bench_diagnose_frame.py BENCH --out RESULTS"
        )
    load_manifest(Path(a.benchmark))
    if a.out:
        o = check_out_file(a.out)
        if o.exists():
            try:
                prev = json.loads(o.read_text(encoding="utf-8"))
                ours = isinstance(prev, dict) and {"summary", "rows"} <= set(prev)
            except (ValueError, OSError):
                ours = False
            if not ours:
                raise InputError(
                    f"--out {o}: the file exists and is not a previous score result: choose a new name "
                    "(score never overwrites files it did not write)"
                )
    res = score(
        Path(a.benchmark),
        progress=lambda r: print(
            f"{r['dataset']}: hidden {r['hidden'] or '-'} found {r['found'] or '-'} {'ok' if r['correct'] else 'WRONG'}"
        ),
    )
    print(json.dumps(res["summary"], indent=1))
    if res.get("suite") == "system":  # the system suite's table (OOV classes, unexplained), docs/diagnose.md
        from ..diagnose.system.score import tables

        print(tables(res["summary"]))
    if a.out:
        tmp = Path(a.out).with_name(f".{Path(a.out).name}.partial-{os.getpid()}")
        tmp.write_text(json.dumps(res, indent=1))
        os.replace(tmp, a.out)
    return 0
