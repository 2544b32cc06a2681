"""The table of the native FMUs' sizes in ``docs/fmus.md``, generated from a build (never written by hand).

``python -m pyfmu_wrapper.generate.fmu_sizes`` builds what a plain ``build-fmus --fmi-version both`` builds
(every FMU with a native variant, FMI 2.0 and 3.0, every platform this machine can build) into a temporary
folder and writes the archive and binary sizes between the markers :data:`SIZES_BEGIN` ... :data:`SIZES_END`;
``--from DIR`` reads an existing build (``DIR`` and ``DIR/fmi3``) instead. tests/test_native_platforms.py
holds the table against a fresh build (:func:`read_size_table`).
"""

from __future__ import annotations

import argparse
import re
import sys
import tempfile
import zipfile
from pathlib import Path

from ..fmubuild.build import fmi_out_dir
from ..fmubuild.native_build import PLATFORM_DIR, SUFFIX, build_native_fmus
from ..models.catalog import NATIVE_FMUS, pick
from .docs import FMUS_FILE

SIZES_BEGIN = "<!-- BEGIN native FMU sizes"
SIZES_END = "<!-- END native FMU sizes -->"
#: the platform columns of the table, in FMI 2.0's folder names
PLATFORMS = ("linux64", "win64", "aarch64-linux")


def kb(n: int) -> str:
    return f"{n / 1000:.1f}"


def sizes(fmu: Path, fmi_version: int) -> tuple[int, dict[str, int]]:
    """(the archive's size, platform -> the size of its binary) of one built native FMU [bytes]."""
    with zipfile.ZipFile(fmu) as z:
        info = {i.filename: i.file_size for i in z.infolist()}
    binaries = {}
    for plat in PLATFORMS:
        name = f"{PLATFORM_DIR[(fmi_version, plat)]}/{fmu.stem}{SUFFIX[plat]}"
        if name in info:
            binaries[plat] = info[name]
    return fmu.stat().st_size, binaries


def size_table(build: dict[int, list[Path]]) -> str:
    """The markdown table of a build: FMI version -> its FMUs."""
    lines = [
        "| FMU | FMI | archive kB | " + " | ".join(f"{p} binary kB" for p in PLATFORMS) + " |",
        "|---|---|---|" + "---|" * len(PLATFORMS),
    ]
    for v in sorted(build):
        for fmu in build[v]:
            total, binaries = sizes(fmu, v)
            cells = [kb(binaries[p]) if p in binaries else "-" for p in PLATFORMS]
            lines.append(f"| {fmu.stem} | {v}.0 | {kb(total)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def read_size_table(text: str) -> dict[tuple[str, int], tuple[float, dict[str, float]]]:
    """(FMU, FMI version) -> (archive kB, platform -> binary kB) of the table in ``text``."""
    i, j = text.find(SIZES_BEGIN), text.find(SIZES_END)
    if i < 0 or j < i:
        raise ValueError(f"the markers {SIZES_BEGIN!r} ... {SIZES_END!r} are missing")
    out = {}
    for row in re.findall(r"^\| (\w+) \| ([23])\.0 \| ([\d.]+) \| (.*) \|$", text[i:j], re.M):
        cells = [c.strip() for c in row[3].split("|")]
        out[(row[0], int(row[1]))] = (float(row[2]), {p: float(c) for p, c in zip(PLATFORMS, cells) if c != "-"})
    return out


def with_table(text: str, table: str) -> str:
    """``text`` with the table between the markers replaced."""
    i, j = text.find(SIZES_BEGIN), text.find(SIZES_END)
    if i < 0 or j < i:
        raise SystemExit(f"{FMUS_FILE}: the markers {SIZES_BEGIN!r} ... {SIZES_END!r} are missing")
    i = text.index("\n", i) + 1
    return text[:i] + "\n" + table + "\n\n" + text[j:]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m pyfmu_wrapper.generate.fmu_sizes", description=__doc__)
    ap.add_argument("--from", dest="src", help="a build folder of build-fmus --fmi-version both (default: build now)")
    args = ap.parse_args(argv)
    fmus = pick(NATIVE_FMUS)
    with tempfile.TemporaryDirectory() as tmp:
        if args.src:
            build = {v: [fmi_out_dir(args.src, v) / f"{f.spec.model_identifier}.fmu" for f in fmus] for v in (2, 3)}
        else:
            build = {v: build_native_fmus(fmus, fmi_out_dir(tmp, v), fmi_version=v) for v in (2, 3)}
        table = size_table(build)
    FMUS_FILE.write_text(with_table(FMUS_FILE.read_text(encoding="utf-8"), table), encoding="utf-8")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
