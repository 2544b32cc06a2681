"""Code version of the package: hashes of its sources.

* :func:`source_hash` hashes every ``.py`` file of the package: it changes whenever any code that
  could change a number changes. Checkpoints and summaries record it.
* :func:`compiled_hash` hashes the compiled layer only: the modules that use numba and every
  package module they import, transitively (found by reading their import statements). The numba
  cache is keyed by it (:mod:`pyfmu_wrapper._jit`), so editing any kernel, in any file, can never
  leave a stale compiled function behind, while editing, say, the report writer recompiles
  nothing.

Both are computed from the files on disk next to this module (so a copy of the package bundled
into an FMU has its own version) and cached for the life of the process.
"""

from __future__ import annotations

import ast
import functools
import hashlib
import json
import os
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
PACKAGE = PACKAGE_DIR.name


def _sources(root: Path) -> dict[str, bytes]:
    return {
        p.relative_to(root).as_posix(): p.read_bytes()
        for p in sorted(root.rglob("*.py"))
        if "__pycache__" not in p.parts
    }


def _digest(files: dict[str, bytes]) -> str:
    h = hashlib.sha256()
    for name in sorted(files):
        h.update(name.encode() + b"\0" + hashlib.sha256(files[name]).digest())
    return h.hexdigest()


@functools.cache
def source_hash(root: Path = PACKAGE_DIR) -> str:
    """SHA-256 over every ``.py`` file of the package (names and contents)."""
    return _digest(_sources(Path(root)))


@functools.cache
def numbers_hash(root: Path = PACKAGE_DIR) -> str:
    """SHA-256 over every source that can change a number: the package's ``.py`` files, its C sources
    (the master's compiled loop) and, in a checkout, the FMUs' C stub (``fmu/src`` beside the
    package). Checkpoints and results are keyed by it."""
    root = Path(root)
    files = _sources(root)
    stub = root.parent / "fmu" / "src"
    for p in sorted(root.rglob("*")):
        if p.suffix in (".c", ".h") and "__pycache__" not in p.parts:
            files[p.relative_to(root).as_posix()] = p.read_bytes()
    for p in sorted(stub.glob("*")) if stub.is_dir() else []:
        if p.suffix in (".c", ".h"):
            files[f"../fmu/src/{p.name}"] = p.read_bytes()
    return _digest(files)


def _module_file(root: Path, rel: str, module: str | None, level: int) -> list[str]:
    """Package-relative files an import statement in ``rel`` can refer to."""
    parts = rel.split("/")[:-1]  # the importing module's package, relative to root
    if level == 0:
        if not module or not (module == PACKAGE or module.startswith(PACKAGE + ".")):
            return []
        target = module.split(".")[1:]
    else:
        base = parts[: len(parts) - (level - 1)] if level > 1 else parts
        target = base + (module.split(".") if module else [])
    out = []
    path = "/".join(target)
    for cand in (f"{path}.py" if path else None, f"{path}/__init__.py" if path else "__init__.py"):
        if cand and (root / cand).is_file():
            out.append(cand)
    return out


def _imports(root: Path, rel: str, source: bytes) -> set[str]:
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom):
            found.update(_module_file(root, rel, node.module, node.level))
            for alias in node.names:  # "from . import registry" names a module
                mod = f"{node.module}.{alias.name}" if node.module else alias.name
                found.update(_module_file(root, rel, mod, node.level))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                found.update(_module_file(root, rel, alias.name, 0))
    return found


#: where :func:`compiled_files` keeps its answer while no module of the package has changed (git-ignored)
COMPILED_FILES_CACHE = "__pycache__/compiled_files.json"


@functools.cache
def compiled_files(root: Path = PACKAGE_DIR) -> tuple[str, ...]:
    """Package-relative files of the compiled layer: numba users and their imports, transitively.

    Reading every module's imports is most of what :func:`compiled_hash` costs (0.5 s: a process that loads
    numba pays it, a co-simulation's included); the answer is kept in ``__pycache__`` under a key of every
    module's name, size and modification time, and found again while none has changed (the hash itself
    always reads the files it lists)."""
    root = Path(root)
    modules = [p for p in sorted(root.rglob("*.py")) if "__pycache__" not in p.parts]
    stats = [(p.relative_to(root).as_posix(), p.stat().st_size, p.stat().st_mtime_ns) for p in modules]
    key = hashlib.sha256(json.dumps(stats).encode()).hexdigest()
    cache = root / COMPILED_FILES_CACHE
    try:
        kept = json.loads(cache.read_text())
        if kept.get("key") == key:
            return tuple(kept["files"])
    except (OSError, ValueError, AttributeError):
        pass
    found = _compiled_files(root)
    try:
        cache.parent.mkdir(exist_ok=True)
        tmp = cache.with_name(f"{cache.name}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps({"key": key, "files": list(found)}))
        os.replace(tmp, cache)  # atomic: concurrent processes write the same answer
    except OSError:
        pass  # a read-only installation: computed again next time
    return found


def _compiled_files(root: Path) -> tuple[str, ...]:
    files = _sources(root)
    todo = [n for n, src in files.items() if (b"numba" in src or b"njit" in src) and n != "codeversion.py"]
    seen: set[str] = set()
    while todo:
        n = todo.pop()
        if n in seen or n not in files:
            continue
        seen.add(n)
        todo.extend(_imports(root, n, files[n]) - seen)
    return tuple(sorted(seen))


@functools.cache
def compiled_hash(root: Path = PACKAGE_DIR) -> str:
    """SHA-256 over the compiled layer (:func:`compiled_files`)."""
    root = Path(root)
    return _digest({n: (root / n).read_bytes() for n in compiled_files(root)})
