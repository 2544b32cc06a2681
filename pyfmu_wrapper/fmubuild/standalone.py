"""Standalone runtime of an FMU (``build-fmus --standalone``): what it bundles besides the model.

A standalone FMU carries, in ``resources/python/``, the build interpreter's runtime, so it runs on a
Linux x86-64 machine with no Python at all:

- ``python/lib/libpythonX.Y.so``: the shared libpython of the build interpreter (stripped of debug
  information when ``strip`` exists);
- ``python/lib/pythonX.Y/``: its standard library and ``lib-dynload``, without tests, IDLE, tkinter,
  installers and build files (:data:`STDLIB_EXCLUDE`, :data:`DYNLOAD_EXCLUDE`);
- ``python/lib/pythonX.Y/site-packages/``: every file of the installed :data:`RUNTIME_PACKAGES`
  distributions (numpy, numba, llvmlite, with their ``.dist-info``), without their tests;
- byte code compiled at build time as unchecked-hash ``.pyc``.

:func:`runtime_files` collects it (once for several FMUs, see :func:`.build.build_fmus`),
:func:`runtime_config` is what ``pyfmu.cfg`` records about it. The stub of a standalone FMU is
compiled with :func:`stub_flags`: against the build interpreter's headers, so that it starts this
runtime isolated with the PyConfig API (``fmu/src/py_config.c``); see docs/fmus.md.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

from .buildinfo import BuildError, version_of
from .elfpath import run_paths, set_run_path

#: Distributions bundled into a standalone FMU (with what they import at run time: numba needs
#: numpy and llvmlite; llvmlite's libllvmlite.so and numpy's numpy.libs are in their file lists).
RUNTIME_PACKAGES = ("numpy", "numba", "llvmlite")
#: Parts of the standard library a model never imports (tests, IDEs, GUI, installers, build files).
STDLIB_EXCLUDE = {
    "test",
    "idlelib",
    "tkinter",
    "turtledemo",
    "ensurepip",
    "lib2to3",
    "site-packages",
    "__pycache__",
    "pydoc_data",
    "venv",
    "turtle.py",
}
DYNLOAD_EXCLUDE = ("_test", "_tkinter", "xxlimited", "_ctypes_test", "_xxtestfuzz", "_xxsubinterpreters")
RUNTIME_DIR = "python"


def _pyver() -> str:
    return f"python{sys.version_info[0]}.{sys.version_info[1]}"


def runtime_config() -> dict:
    """What ``pyfmu.cfg`` records about the bundled runtime (paths relative to ``resources/``)."""
    return {
        "runtime": RUNTIME_DIR,
        "runtime_libpython": f"{RUNTIME_DIR}/lib/lib{_pyver()}.so",
        "runtime_version": sys.version.split()[0],
        "runtime_packages": " ".join(f"{n}=={version_of(n)}" for n in RUNTIME_PACKAGES),
    }


def _pyc(src: Path, arc: str, pyc_dir: Path, out: list) -> None:
    """Add the source and, compiled now, its byte code (unchecked-hash pyc: valid whatever file times
    the extraction gives, and nothing is written into the FMU folder at run time)."""
    import py_compile

    out.append((src, arc))
    if not arc.endswith(".py"):
        return
    d, _, name = arc.rpartition("/")
    pyc_arc = f"{d}/__pycache__/{name[:-3]}.{sys.implementation.cache_tag}.pyc"
    target = pyc_dir / pyc_arc
    try:
        py_compile.compile(
            str(src),
            cfile=str(target),
            dfile=arc,
            doraise=True,
            invalidation_mode=py_compile.PycInvalidationMode.UNCHECKED_HASH,
        )
    except (py_compile.PyCompileError, SyntaxError, ValueError):
        return  # files that are not valid Python 3 (templates): shipped as is, never imported
    out.append((target, pyc_arc))


def runtime_files(pyc_dir: Path) -> list[tuple[Path, str]]:
    """(source file, name under ``resources/``) of the runtime of a standalone FMU.

    ``python/lib/libpythonX.Y.so`` (the build interpreter's shared library), the standard library
    of ``sys.base_prefix`` under ``python/lib/pythonX.Y/`` without :data:`STDLIB_EXCLUDE` and test
    extension modules, and every file of the :data:`RUNTIME_PACKAGES` distributions under
    ``python/lib/pythonX.Y/site-packages/`` (where the runtime's ``site`` finds them), with byte
    code compiled into ``pyc_dir``."""
    from importlib import metadata

    if sys.platform != "linux" or sysconfig.get_platform() != "linux-x86_64":
        raise BuildError(f"a standalone FMU is built on Linux x86-64 only, not {sysconfig.get_platform()}")
    lib = libpython_path()
    stdlib = Path(sysconfig.get_paths(vars={"base": sys.base_prefix, "installed_base": sys.base_prefix})["stdlib"])
    if not (stdlib / "os.py").is_file():
        raise BuildError(f"the standard library of {sys.base_prefix} was not found at {stdlib}")
    pre = f"{RUNTIME_DIR}/lib/{_pyver()}"
    pyc_dir.mkdir(parents=True, exist_ok=True)
    if shutil.which("strip"):  # its debug information is 3/4 of the file
        shutil.copyfile(lib, pyc_dir / lib.name)
        lib = pyc_dir / lib.name
        subprocess.run(["strip", "--strip-unneeded", str(lib)], check=True, capture_output=True)
    out: list[tuple[Path, str]] = [(lib, f"{RUNTIME_DIR}/lib/lib{_pyver()}.so")]
    for root, dirs, names in os.walk(stdlib):
        rel = Path(root).relative_to(stdlib)
        dirs[:] = sorted(
            d
            for d in dirs
            if not (
                d in STDLIB_EXCLUDE or d.startswith("config-") or (rel.parts and d in ("tests", "test", "idle_test"))
            )
        )
        for n in sorted(names):
            if n in STDLIB_EXCLUDE or n.endswith((".pyc", ".exe", ".a")):
                continue
            if rel.parts[:1] == ("lib-dynload",) and n.startswith(DYNLOAD_EXCLUDE):
                continue
            _pyc(Path(root) / n, "/".join((pre, *rel.parts, n)), pyc_dir, out)
    for name in RUNTIME_PACKAGES:
        try:
            dist = metadata.distribution(name)
        except metadata.PackageNotFoundError:
            raise BuildError(f"{name} is not installed in the build interpreter {sys.executable}") from None
        for f in dist.files or ():
            src = Path(str(dist.locate_file(f))).resolve()
            if "__pycache__" in f.parts or f.parts[0] == ".." or not src.is_file() or src.suffix == ".pyc":
                continue
            if "tests" in f.parts[1:-1]:
                continue
            _pyc(src, f"{pre}/site-packages/{f.as_posix()}", pyc_dir, out)
    return [_relocated(src, arc, pyc_dir) for src, arc in out]


def _relocated(src: Path, arc: str, pyc_dir: Path) -> tuple[Path, str]:
    """(src, arc), or a copy of src whose run path names the bundled runtime's ``lib`` folder relative
    to the file (``$ORIGIN/...``) instead of the build interpreter's folders (:mod:`.elfpath`)."""
    if ".so" not in src.name:
        return src, arc
    paths = run_paths(src)
    if not paths or all(p.startswith("$ORIGIN") for path in paths for p in path.split(":") if p):
        return src, arc
    up = arc.count("/") - f"{RUNTIME_DIR}/lib/x".count("/")
    rel = "/".join(["$ORIGIN", *[".."] * up]) if up > 0 else "$ORIGIN"
    keep = [p for path in paths for p in path.split(":") if p.startswith("$ORIGIN")]
    copy = pyc_dir / "relocated" / arc
    copy.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(src, copy)
    set_run_path(copy, ":".join(dict.fromkeys([*keep, rel])))
    return copy, arc


def libpython_path() -> Path:
    """The shared libpython of the running interpreter (dlopened by the stub in a C host)."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    for name in (sysconfig.get_config_var("INSTSONAME"), sysconfig.get_config_var("LDLIBRARY")):
        if name and name.endswith((".so", ".so.1.0")) or (name and ".so" in name):
            p = Path(libdir) / name
            if p.is_file():
                return p
    raise BuildError("no shared libpython found (Python must be built with --enable-shared)")


def stub_flags() -> tuple[str, ...]:
    """Compiler flags of a standalone FMU's stub: ``-DPYFMU_PYCONFIG`` and the build interpreter's
    include folder (``fmu/src/py_config.c`` needs the PyConfig layout of the bundled runtime's
    Python version, which is the build interpreter's)."""
    inc = Path(sysconfig.get_paths()["include"])
    if not (inc / "Python.h").is_file():
        raise BuildError(
            f"Python.h of the build interpreter not found in {inc}: a standalone FMU's stub is compiled "
            f"against it (install the Python development headers)"
        )
    return ("-DPYFMU_PYCONFIG", f"-I{inc}")
