"""``build-fmus``: build the FMUs (FMI 2.0, FMI 3.0 or both) into a folder.

The console entry point: the FMUs named are picked from the project's catalogue
(:mod:`pyfmu_wrapper.models.catalog`) and their declarations handed to the builders
(:mod:`pyfmu_wrapper.fmubuild.native_build`, the default; :mod:`pyfmu_wrapper.fmubuild.build` with
``--python`` or ``--standalone``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..fmubuild.build import (
    DEFAULT_OUT,
    BuildError,
    OutputError,
    build_fmus,
    ensure_fmus,
    fmi_out_dir,
)
from .common import add_version
from .errors import cli_main

#: what ``build-fmus`` builds with no variant flag: the native FMUs (the model compiled into the binary)
DEFAULT_VARIANT = "native"
# the catalogue of FMUs (their declarations import numba) is imported in main, after the command line
# is parsed: --help and --version cost nothing


@cli_main("build-fmus")
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="build-fmus",
        description="Build the FMUs (FMI 2.0, 3.0 or both) into a folder: by default native, the model compiled "
        "into the binary for linux64, win64 and aarch64-linux, no Python needed on the target.",
    )
    ap.add_argument(
        "names",
        nargs="*",
        default=[],
        help="FMUs to build, by name (default: every model's FMUs, native; with --python, every model's "
        "Python-hosted FMU); --list names them",
    )
    ap.add_argument("--list", action="store_true", help="list the FMUs that can be built, and exit")
    ap.add_argument("--out", default=None, help="output directory (default fmu/build/native; with --python fmu/build)")
    ap.add_argument("--force", action="store_true", help="rebuild even when up to date")
    ap.add_argument(
        "--native",
        action="store_true",
        help="the default, spelled out: the model compiled into the binary (linux64, win64 when mingw-w64 is "
        "installed, aarch64-linux; Linux binaries for glibc >= 2.17), no Python on the target",
    )
    ap.add_argument(
        "--python",
        action="store_true",
        help="the Python-hosted FMUs instead (linux64 only, run by the build's Python installation): the "
        "debugging reference, bit for bit the native FMUs' numbers (default --out fmu/build)",
    )
    ap.add_argument(
        "--standalone",
        action="store_true",
        help="a Python-hosted FMU that also bundles a relocatable Python runtime with numpy, numba and llvmlite "
        "(~100 MB, linux64; for an FMU whose declaration has no native functions yet; always rebuilt; default "
        "--out fmu/build/standalone)",
    )
    ap.add_argument(
        "--fmi-version",
        default="2",
        choices=["2", "3", "2,3", "both"],
        metavar="{2,3,both}",  # "2,3" is accepted as a spelling of "both"
        help="FMI version of the FMUs: 2 (default, into --out), 3 (FMI 3.0 co-simulation, into <out>/fmi3/), or both",
    )
    add_version(ap)
    args = ap.parse_args(argv)
    from ..models.catalog import BUILD_FMUS, NATIVE_FMUS, SPECS, pick

    if args.list:
        for n in sorted(SPECS):
            tags = [t for t, on in (("default", n in BUILD_FMUS), ("native", n in NATIVE_FMUS)) if on]
            print(n + (f" ({', '.join(tags)})" if tags else ""))
        return 0
    versions = [2, 3] if args.fmi_version in ("2,3", "both") else [int(args.fmi_version)]
    if args.native and (args.python or args.standalone):
        ap.error(f"--native excludes {'--python' if args.python else '--standalone'} (a native FMU runs no Python)")
    native = not (args.python or args.standalone)
    if not args.names:  # every model's FMU (native: every one with a native variant)
        args.names = list(NATIVE_FMUS if native else BUILD_FMUS)
    unknown = [n for n in args.names if n not in SPECS]
    if unknown:
        ap.error(f"unknown FMU(s) {unknown}; choose from {sorted(SPECS)}")
    no_native = [n for n in args.names if n not in NATIVE_FMUS]
    if native and no_native:
        ap.error(
            f"{', '.join(no_native)} has no native variant (those with one: {', '.join(NATIVE_FMUS)}); "
            "--python builds the Python-hosted FMU"
        )
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():  # before compiling
        ap.error(f"--out {args.out}: is a file, not a folder (build-fmus writes the FMUs into a folder)")
    fmus = pick(args.names)
    try:
        paths = []
        for v in versions:
            if native:
                from ..fmubuild.native_build import NATIVE_SUBDIR, build_native_fmus, ensure_native_fmus

                out = DEFAULT_OUT / NATIVE_SUBDIR if args.out is None else args.out
                if args.force:
                    paths += build_native_fmus(fmus, fmi_out_dir(out, v), fmi_version=v)
                else:
                    paths += list(ensure_native_fmus(fmus, out, fmi_version=v).values())
            elif args.standalone:
                out = DEFAULT_OUT / "standalone" if args.out is None else args.out
                paths += build_fmus(fmus, fmi_out_dir(out, v), standalone=True, fmi_version=v)
            elif args.force:
                paths += build_fmus(fmus, fmi_out_dir(args.out or DEFAULT_OUT, v), fmi_version=v)
            else:
                paths += list(ensure_fmus(fmus, args.out or DEFAULT_OUT, fmi_version=v).values())
    except OutputError as e:
        print(f"build-fmus: {e}", file=sys.stderr)
        return 2
    except BuildError as e:
        print(f"build-fmus: {e}", file=sys.stderr)
        return 1
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
