"""Build the FMI 2.0 co-simulation FMUs: compile the C stub, generate the XML, pack the archive.

Command line (console script ``build-fmus``)::

    build-fmus                      # build BaseOscillator.fmu and TMDInerter.fmu into fmu/build/
    build-fmus --out DIR --force    # elsewhere, rebuilding even when up to date
    build-fmus Trivial              # the stub-overhead benchmark model

API: :func:`build_fmu`, :func:`build_fmus`, :func:`ensure_fmus` (builds what is missing or stale,
judged by a hash of the sources: the C stub, this package's fmi/physics/solver modules and the
Python environment).

An FMU contains ``modelDescription.xml``, ``binaries/linux64/<modelIdentifier>.so`` (the stub,
compiled with the system gcc against the FMI 2.0 headers that fmpy ships) and ``resources/``:
``pyfmu.cfg`` (GUID, the libpython to load in a host without Python, PYTHONHOME, the sys.path
entries of the build environment, the source hash), ``variables.tsv`` (the stub's variable table)
and ``model.py`` (the model code loaded under a unique module name per instance).
"""
from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import site
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from pathlib import Path

from .model_description import guid_of, model_description_xml, variable_table_tsv
from .variables import PROJECT_FMUS, SPECS, FmuSpec

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # pyfmu_wrapper/
REPO_ROOT = PACKAGE_DIR.parent
STUB_SOURCE = REPO_ROOT / "fmu" / "src" / "pyfmu_stub.c"
DEFAULT_OUT = REPO_ROOT / "fmu" / "build"


class BuildError(RuntimeError):
    """The FMU could not be built (no compiler, no headers, no shared libpython...)."""


def fmi_headers_dir() -> Path:
    """The directory with fmi2Functions.h shipped inside the installed fmpy package."""
    import fmpy

    d = Path(fmpy.__file__).parent / "c-code"
    if not (d / "fmi2Functions.h").is_file():
        raise BuildError(f"fmi2Functions.h not found in {d}; is fmpy installed?")
    return d


def libpython_path() -> Path:
    """The shared libpython of the running interpreter (dlopened by the stub in a C host)."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and name.endswith((".so", ".so.1.0")) or (name and ".so" in name):
            p = Path(libdir) / name
            if p.is_file():
                return p
    raise BuildError("no shared libpython found (Python must be built with --enable-shared)")


def python_paths() -> list[str]:
    """sys.path entries the slave needs: the environment's site-packages and the project root."""
    paths = list(site.getsitepackages())
    user = site.getusersitepackages()
    if isinstance(user, str) and os.path.isdir(user):
        paths.append(user)
    paths.append(str(REPO_ROOT))
    return [p for p in dict.fromkeys(paths) if os.path.isdir(p)]


def source_hash() -> str:
    """Hash of everything an FMU is built from (stale FMUs are rebuilt by ensure_fmus)."""
    h = hashlib.sha256()
    files = [STUB_SOURCE]
    for sub in ("fmi", "physics", "solvers"):
        files += sorted((PACKAGE_DIR / sub).glob("*.py"))
    for f in files:
        h.update(f.name.encode())
        h.update(f.read_bytes())
    h.update(sys.prefix.encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:24]


def compile_stub(out_so: Path, cc: str | None = None) -> None:
    """Compile the C stub into a shared library with the system C compiler."""
    cc = cc or os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        raise BuildError(f"C compiler {cc!r} not found")
    out_so.parent.mkdir(parents=True, exist_ok=True)
    cmd = [cc, "-shared", "-fPIC", "-O2", "-std=gnu11", "-Wall", "-Wextra", "-Wno-unused-parameter",
           f"-I{fmi_headers_dir()}", str(STUB_SOURCE), "-o", str(out_so), "-ldl", "-lpthread"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise BuildError(f"compiling the stub failed:\n{' '.join(cmd)}\n{r.stderr}")


def _config(spec: FmuSpec, guid: str, shash: str) -> str:
    lines = [f"guid={guid}", f"model_identifier={spec.model_identifier}", f"libpython={libpython_path()}",
             f"pythonhome={sys.base_prefix}", f"prefix={sys.prefix}", f"python_version={sys.version.split()[0]}",
             "model=model.py", f"source_hash={shash}"]
    lines += [f"path={p}" for p in python_paths()]
    return "\n".join(lines) + "\n"


def _model_py(spec: FmuSpec) -> str:
    return (f'"""Model code of the {spec.model_name} FMU (loaded by the stub under a unique module name)."""\n'
            "from pyfmu_wrapper.fmi.slaves import create as _create\n\n"
            f"SLAVE = {spec.slave!r}\n\n\n"
            "def create(reals, ints, derivs, scratch, instance_name, resources):\n"
            "    return _create(SLAVE, reals, ints, derivs, scratch, instance_name, resources)\n")


def build_fmu(name: str, out_dir: str | os.PathLike = DEFAULT_OUT, stub_so: Path | None = None) -> Path:
    """Build one FMU (name: a key of :data:`~.variables.SPECS`); return the path of the .fmu."""
    spec = SPECS[name]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    shash = source_hash()
    guid = guid_of(spec, shash)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        so = stub_so
        if so is None:
            so = tmp / "stub.so"
            compile_stub(so)
        target = out_dir / f"{spec.model_identifier}.fmu"
        part = out_dir / f".{spec.model_identifier}.fmu.part"
        with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
            z.writestr("modelDescription.xml", model_description_xml(spec, guid))
            z.write(so, f"binaries/linux64/{spec.model_identifier}.so")
            z.writestr("resources/pyfmu.cfg", _config(spec, guid, shash))
            z.writestr("resources/variables.tsv", variable_table_tsv(spec))
            z.writestr("resources/model.py", _model_py(spec))
        os.replace(part, target)
    return target


def build_fmus(names=PROJECT_FMUS, out_dir: str | os.PathLike = DEFAULT_OUT) -> list[Path]:
    """Build several FMUs (the stub is compiled once)."""
    with tempfile.TemporaryDirectory() as tmp:
        so = Path(tmp) / "stub.so"
        compile_stub(so)
        return [build_fmu(n, out_dir, stub_so=so) for n in names]


def fmu_source_hash(fmu: Path) -> str | None:
    """The source hash recorded in a built FMU (None if unreadable)."""
    try:
        with zipfile.ZipFile(fmu) as z:
            for line in z.read("resources/pyfmu.cfg").decode().splitlines():
                if line.startswith("source_hash="):
                    return line.split("=", 1)[1]
    except (OSError, KeyError, zipfile.BadZipFile):
        return None
    return None


def ensure_fmus(out_dir: str | os.PathLike = DEFAULT_OUT, names=PROJECT_FMUS) -> dict[str, Path]:
    """Paths of the FMUs, building those that are missing or stale (source hash)."""
    out_dir = Path(out_dir)
    shash = source_hash()
    paths = {n: out_dir / f"{SPECS[n].model_identifier}.fmu" for n in names}
    stale = [n for n, p in paths.items() if fmu_source_hash(p) != shash]
    if stale:
        build_fmus(stale, out_dir)
    return paths


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="build-fmus", description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", default=list(PROJECT_FMUS), help=f"FMUs to build, of {sorted(SPECS)}")
    ap.add_argument("--out", default=str(DEFAULT_OUT), help="output directory (default fmu/build)")
    ap.add_argument("--force", action="store_true", help="rebuild even when up to date")
    args = ap.parse_args(argv)
    unknown = [n for n in args.names if n not in SPECS]
    if unknown:
        ap.error(f"unknown FMU(s) {unknown}; choose from {sorted(SPECS)}")
    try:
        if args.force:
            paths = build_fmus(args.names, args.out)
        else:
            paths = list(ensure_fmus(args.out, args.names).values())
    except BuildError as e:
        print(f"build-fmus: {e}", file=sys.stderr)
        return 1
    for p in paths:
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
