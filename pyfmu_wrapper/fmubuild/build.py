"""Build the Python-hosted FMI 2.0 (and 3.0) co-simulation FMUs: compile the C stub, bundle the model code, pack
the archive. (``build-fmus`` builds the native FMUs by default: :mod:`.native_build`; these are the debugging
reference, bit for bit the same numbers.)

Command line (console script ``build-fmus``)::

    build-fmus --python                      # every model's Python-hosted FMU into fmu/build/
    build-fmus --python --out DIR --force    # elsewhere, rebuilding even when up to date
    build-fmus --python Trivial              # the stub-overhead benchmark model
    build-fmus --standalone                  # also bundle a Python runtime (fmu/build/standalone/)

API: :func:`build_fmu`, :func:`build_fmus`, :func:`ensure_fmus` (builds what is missing or stale,
judged by a hash of the sources: the C stub, the bundled modules and the build interpreter). Each takes
the declarations of the FMUs it builds (:class:`~pyfmu_wrapper.fmi.fmumodel.FmuModel`, e.g. a model
unit's ``fmus()`` or :data:`pyfmu_wrapper.models.catalog.FMUS`): nothing here knows a model or the list
of them.

An FMU is self-contained: it contains ``modelDescription.xml``, ``binaries/linux64/<id>.so`` (the
stub, compiled with the system gcc against the FMI 2.0 headers that fmpy ships) and
``resources/``:

- ``_pyfmu_<hash>/``: the modules of this package the model runs (``fmi/slave.py``, the slaves of the FMUs built and
  everything they import from the package, transitively: :mod:`.bundle`), copied verbatim under a package name
  that carries their hash, so no checkout or install of this project is needed to run it;
- ``model.py``: checks the bundle against its recorded hash, keys numba's on-disk cache of the
  bundled functions by that hash (a cache of other code can never be loaded), imports the slave;
- ``pyfmu.cfg``: GUID, the requirements (Python >= 3.11, numpy, numba) and the build's
  interpreter (one of the places a pure C host looks for a Python, see ``docs/fmus.md``);
- ``variables.tsv``: the stub's variable table (with each variable's range, enforced at set time);

and ``documentation/index.html`` (:mod:`.documentation`): the variables, their ranges, what the FMU
needs and refuses, generated from the same table; the stub's messages point there.

A *standalone* FMU (``build-fmus --standalone``, :func:`build_fmu` with ``standalone=True``) also
carries ``resources/python/``: the build interpreter's runtime and the installed numpy, numba and
llvmlite, collected by :mod:`.standalone`, so it runs on a Linux x86-64 machine with no Python at
all.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..fmi.contract import c_header
from ..fmi.fmumodel import FmuModel
from ..fmi.varspec import FmuSpec
from ..safeio.files import replace_checked
from .buildinfo import BuildError, version_of
from .bundle import PACKAGE_DIR, bundle_hash, bundle_package, bundled_files, model_py
from .documentation import documentation_html
from .model_description import guid_of, model_description_xml, variable_table_tsv
from .model_description3 import model_description3_xml

REPO_ROOT = PACKAGE_DIR.parent
STUB_DIR = REPO_ROOT / "fmu" / "src"
DEFAULT_OUT = REPO_ROOT / "fmu" / "build"
#: FMI versions build-fmus writes; an FMI 3.0 variant goes into <out>/fmi3/ (same file names)
FMI_VERSIONS = (2, 3)
#: where the binary is in the archive, per FMI version (platform tuple of FMI 2.0 and 3.0)
BINARY_DIR = {2: "binaries/linux64", 3: "binaries/x86_64-linux"}


def fmi_out_dir(out_dir: str | os.PathLike, fmi_version: int) -> Path:
    """The folder of the FMUs of one FMI version: out_dir (FMI 2.0) or out_dir/fmi3 (FMI 3.0)."""
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi_version!r}: this builder writes {FMI_VERSIONS}")
    return Path(out_dir) if fmi_version == 2 else Path(out_dir) / "fmi3"


#: What the bundled model code needs in the interpreter that runs it (mirrors pyproject.toml).
REQUIRES = ("numpy>=1.26", "numba>=0.59")
MIN_PYTHON = "3.11"


class OutputError(BuildError):
    """The output folder cannot take the FMUs (a file, not writable, or holding a file of the same
    name that this tool did not write): refused before anything is written."""


def check_output(out_dir: Path, fmus: Iterable[FmuModel]) -> None:
    """Refuse an output folder that is a file or cannot be written, and an existing target that
    is not an FMU built by this tool (a user's file is never overwritten); creates the folder."""
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise OutputError(f"--out {out_dir} is a file, not a folder; nothing was written")
    for fmu in fmus:
        target = out_dir / f"{fmu.spec.model_identifier}.fmu"
        if target.is_dir() or (target.exists() and fmu_source_hash(target) is None):
            raise OutputError(
                f"{target} exists and was not written by build-fmus (it is not an FMU with a "
                "resources/pyfmu.cfg of this tool); it is left as it is: move it away or choose "
                "another --out. Nothing was written"
            )
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".build-fmus-probe-", dir=out_dir)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise OutputError(f"cannot write into --out {out_dir}: {e.strerror or e}; nothing was written") from None


def stub_sources() -> list[Path]:
    """The C sources and headers of the stub (fmu/src)."""
    return sorted(STUB_DIR.glob("*.c")) + sorted(STUB_DIR.glob("*.h"))


def fmi_headers_dir() -> Path:
    """The directory with fmi2Functions.h shipped inside the installed fmpy package."""
    import fmpy

    d = Path(fmpy.__file__).parent / "c-code"
    if not (d / "fmi2Functions.h").is_file():
        raise BuildError(f"fmi2Functions.h not found in {d}; is fmpy installed?")
    return d


def build_python() -> str:
    """The build's interpreter as recorded in the FMU: the same path whichever name (python,
    python3, python3.11, a console script) started this process."""
    cand = Path(sys.prefix) / "bin" / f"python{sys.version_info[0]}.{sys.version_info[1]}"
    return str(cand) if cand.is_file() else sys.executable


def source_hash(fmus: Iterable[FmuModel]) -> str:
    """Hash of everything the FMUs ``fmus``, built together, are built from (stale FMUs are rebuilt by
    ensure_fmus): the stub, the bundle of their slaves (:func:`.bundle.bundled_files`), the writers, the
    build interpreter."""
    h = hashlib.sha256()
    for f in stub_sources():
        h.update(f.name.encode())
        h.update(f.read_bytes())
    h.update(bundle_hash(bundled_files(fmus)).encode())
    for writer in (
        "fmubuild/build.py",
        "fmubuild/bundle.py",
        "fmi/contract.py",
        "fmubuild/model_description.py",
        "fmubuild/model_description3.py",
        "fmubuild/documentation.py",
    ):  # what writes the archive
        h.update((PACKAGE_DIR / writer).read_bytes())
    h.update(build_python().encode())
    h.update(sys.version.encode())
    return h.hexdigest()[:24]


def compile_stub(out_so: Path, cc: str | None = None, extra_flags: tuple = (), fmi_version: int = 2) -> None:
    """Compile the C stub into a shared library with the system C compiler (``extra_flags``: the
    standalone stub's, :func:`.standalone.stub_flags`). One core and both API layers are compiled;
    a linker version script exports the functions of ``fmi_version`` only (fmi2* or fmi3*)."""
    cc = cc or os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        raise BuildError(f"C compiler {cc!r} not found")
    out_so.parent.mkdir(parents=True, exist_ok=True)
    gen = Path(tempfile.mkdtemp(prefix=f".{out_so.name}.gen-", dir=out_so.parent))  # generated sources
    version_script = gen / f"fmi{fmi_version}.map"
    version_script.write_text(f"{{ global: fmi{fmi_version}*; local: *; }};\n")
    (gen / "pyfmu_contract.h").write_text(c_header())  # the doStep contract, from fmi/contract.py
    cmd = [
        cc,
        "-shared",
        "-fPIC",
        "-O2",
        "-std=gnu11",
        "-Wall",
        "-Wextra",
        "-Wno-unused-parameter",
        "-Wno-format-truncation",
        "-fvisibility=hidden",
        f"-I{gen}",
        f"-I{fmi_headers_dir()}",
        *extra_flags,
        *[str(f) for f in stub_sources() if f.suffix == ".c"],
        "-o",
        str(out_so),
        # keep libdl NEEDED: on glibc < 2.34 the pre-2.34 dl* symbols the stub binds to live there
        "-Wl,--no-as-needed",
        "-l:libdl.so.2",
        "-Wl,--as-needed",
        "-lpthread",
        "-lm",
        f"-Wl,--version-script={version_script}",
    ]
    try:
        r = subprocess.run(cmd, capture_output=True, text=True)
    finally:
        shutil.rmtree(gen, ignore_errors=True)
    if r.returncode != 0:
        raise BuildError(f"compiling the stub failed:\n{' '.join(cmd)}\n{r.stderr}")


def _config(spec: FmuSpec, guid: str, shash: str, bhash: str, runtime: dict | None = None) -> str:
    lines = [
        f"guid={guid}",
        f"model_identifier={spec.model_identifier}",
        "model=model.py",
        f"python={build_python()}",
        f"python_version={sys.version.split()[0]}",
        f"min_python={MIN_PYTHON}",
        f"requires={' '.join(REQUIRES)}",
        f"built_with=numpy=={version_of('numpy')} numba=={version_of('numba')}",
        f"bundle={bundle_package(bhash)}",
        f"bundle_hash={bhash}",
        f"source_hash={shash}",
    ]
    lines += [f"{k}={v}" for k, v in (runtime or {}).items()]
    return "\n".join(lines) + "\n"


def build_fmu(
    fmu: FmuModel,
    out_dir: str | os.PathLike = DEFAULT_OUT,
    stub_so: Path | None = None,
    standalone: bool = False,
    runtime: list | None = None,
    fmi_version: int = 2,
    bundle: Iterable[FmuModel] = (),
) -> Path:
    """Build one FMU from its declaration; return the path of the .fmu.

    standalone: also bundle the Python runtime and numpy/numba/llvmlite (``resources/python/``);
    runtime: the (source, archive name) pairs of that runtime, if already collected
    (:func:`.standalone.runtime_files`); stub_so: the compiled stub, if already compiled (for a
    standalone FMU, with :func:`.standalone.stub_flags`; for ``fmi_version``); fmi_version: 2 or 3
    (written into ``out_dir`` itself: :func:`fmi_out_dir` is the caller's choice of folder); bundle: the
    other FMUs of the build, whose slaves the bundled package carries too (the FMUs of one build share it)."""
    spec = fmu.spec
    together = (fmu, *bundle)
    out_dir = Path(out_dir)
    if fmi_version not in FMI_VERSIONS:
        raise ValueError(f"FMI version {fmi_version!r}: this builder writes {FMI_VERSIONS}")
    check_output(out_dir, [fmu])
    shash = source_hash(together)
    guid = guid_of(spec, shash)
    files = bundled_files(together)
    bhash = bundle_hash(files)
    package = bundle_package(bhash)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        rt_cfg = None
        flags: tuple[str, ...] = ()
        if standalone:
            from .standalone import runtime_config, runtime_files, stub_flags

            if runtime is None:
                runtime = runtime_files(tmp / "pyc")
            rt_cfg, flags = runtime_config(), stub_flags()
        so = stub_so
        if so is None:
            so = tmp / "stub.so"
            compile_stub(so, extra_flags=flags, fmi_version=fmi_version)
        target = out_dir / f"{spec.model_identifier}.fmu"
        # unique per builder: parallel workers may build the same stale FMU at once
        part = out_dir / f".{spec.model_identifier}.fmu.{os.getpid()}.{os.urandom(4).hex()}.part"
        try:
            _write_archive(part, fmu, guid, shash, bhash, rt_cfg, so, package, files, runtime, fmi_version)
        except BaseException:
            part.unlink(missing_ok=True)  # ours: never left behind
            raise
        replace_checked(part, target, lambda f: fmu_source_hash(f) is not None, "build-fmus")
    return target


def _write_archive(
    part: Path,
    fmu: FmuModel,
    guid: str,
    shash: str,
    bhash: str,
    rt_cfg: dict[str, Any] | None,
    so: Path,
    package: str,
    files: list[str],
    runtime: list[tuple[Path, str]] | None,
    fmi_version: int = 2,
) -> None:
    spec = fmu.spec
    md = model_description_xml(spec, guid) if fmi_version == 2 else model_description3_xml(spec, guid)
    with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
        z.writestr("modelDescription.xml", md)
        z.writestr("documentation/index.html", documentation_html(spec, guid, REQUIRES, MIN_PYTHON))
        z.write(so, f"{BINARY_DIR[fmi_version]}/{spec.model_identifier}.so")
        z.writestr("resources/pyfmu.cfg", _config(spec, guid, shash, bhash, rt_cfg))
        z.writestr("resources/variables.tsv", variable_table_tsv(spec))
        z.writestr("resources/model.py", model_py(fmu, package, bhash, files))
        for rel in files:
            z.write(PACKAGE_DIR / rel, f"resources/{package}/{rel}")
        for src, arc in runtime or ():
            z.write(src, f"resources/{arc}")


def build_fmus(
    fmus: Iterable[FmuModel],
    out_dir: str | os.PathLike[str] = DEFAULT_OUT,
    standalone: bool = False,
    fmi_version: int = 2,
    bundle: Iterable[FmuModel] = (),
) -> list[Path]:
    """Build several FMUs from their declarations (the stub is compiled once, a standalone runtime
    collected once) of one FMI version into ``out_dir``, sharing one bundled package (with the slaves of
    ``bundle`` too: :func:`ensure_fmus` passes all the FMUs it was asked for when it rebuilds a few)."""
    fmus = list(fmus)
    together = [*fmus, *(f for f in bundle if f not in fmus)]
    check_output(Path(out_dir), fmus)  # all refused before any is written
    with tempfile.TemporaryDirectory() as tmp:
        so = Path(tmp) / "stub.so"
        runtime = None
        flags: tuple[str, ...] = ()
        if standalone:
            from .standalone import runtime_files, stub_flags

            runtime, flags = runtime_files(Path(tmp) / "pyc"), stub_flags()
        compile_stub(so, extra_flags=flags, fmi_version=fmi_version)
        return [
            build_fmu(
                f,
                out_dir,
                stub_so=so,
                standalone=standalone,
                runtime=runtime,
                fmi_version=fmi_version,
                bundle=[g for g in together if g is not f],
            )
            for f in fmus
        ]


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


def ensure_fmus(
    fmus: Iterable[FmuModel], out_dir: str | os.PathLike[str] = DEFAULT_OUT, fmi_version: int = 2
) -> dict[str, Path]:
    """Paths of the FMUs (model identifier -> path), building those that are missing or stale (source
    hash); FMI 3.0 ones in ``out_dir/fmi3`` (:func:`fmi_out_dir`)."""
    fmus = list(fmus)
    out_dir = fmi_out_dir(out_dir, fmi_version)
    shash = source_hash(fmus)
    paths = {f.name: out_dir / f"{f.spec.model_identifier}.fmu" for f in fmus}
    stale = [f for f in fmus if fmu_source_hash(paths[f.name]) != shash]
    if stale:
        build_fmus(stale, out_dir, fmi_version=fmi_version, bundle=fmus)
    return paths
