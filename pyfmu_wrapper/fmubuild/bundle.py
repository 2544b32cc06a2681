"""What an FMU bundles of this package: the import closure of the slaves of the FMUs built (:func:`bundled_files`,
found by reading the import statements, with the ``__init__.py`` of every package on the way, within the
parts an FMU runs, :data:`RUNTIME_PARTS`), its
identity (:func:`bundle_hash`, the name it is imported under, :func:`bundle_package`) and the FMU's
``resources/model.py`` that hands over to the bundled loader (:data:`MODEL_PY`). The archive is
written by :mod:`.build`.

The builders give the FMUs (:class:`~pyfmu_wrapper.fmi.fmumodel.FmuModel`) whose slave classes the bundle
must run; the closure starts at those classes' modules and at :data:`ROOTS`. A model's FMU folder lies below
the registry (``models/__init__.py``), which imports every registered unit, and each unit's ``fmus()``
imports its FMU code: so every FMU of a model carries the same bundle, whichever FMUs of the project are
built together, and the FMUs of one build share one bundled package in a process.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..fmi.fmumodel import FmuModel

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # pyfmu_wrapper/

#: The module the slaves' machinery lives in.
SLAVE_MODULE = "fmi/slave.py"
#: the bundled loader of the model code (loaded by the FMU's model.py)
LOADER_MODULE = "fmi/fmu_loader.py"
#: what every bundle starts from besides the slaves of the FMUs built: the slaves' machinery, the loader and
#: the support FMU Trivial (part of the runtime, so a build with or without it bundles the same package)
ROOTS = (SLAVE_MODULE, LOADER_MODULE, "fmi/trivial.py")
#: the parts of the package an FMU runs (the layers below the models, and the models): an import into any
#: other part is not followed. A model's folder also reaches the co-simulation engine, the master and the
#: builders (its unit's ``cosim()``, the FMUs' builds) and the scenario reader (its ``scenario_reader``), which
#: never run inside an FMU.
RUNTIME_PARTS = (
    "__init__.py",
    "_jit.py",
    "codeversion.py",
    "errors.py",
    "physics/",
    "solvers/",
    "fmi/",
    "inputs/",
    "models/",
)


def _relative_imports(rel: str, source: bytes) -> set[str]:
    """Package-relative files that the module ``rel`` imports from this package."""
    found: set[str] = set()
    pkg = rel.split("/")[:-1]

    def files(target: list[str]) -> list[str]:
        path = "/".join(target)
        return [
            c
            for c in ((f"{path}.py" if path else None), (f"{path}/__init__.py" if path else "__init__.py"))
            if c and (PACKAGE_DIR / c).is_file()
        ]

    for node in ast.walk(ast.parse(source)):
        mods: list[list[str]] = []
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg[: len(pkg) - (node.level - 1)] if node.level > 1 else list(pkg)
            elif node.module and node.module.split(".")[0] == PACKAGE_DIR.name:
                base = []
            else:
                continue
            mod = node.module.split(".") if node.module else []
            if not node.level:
                mod = mod[1:]
            mods.append(base + mod)
            mods += [base + mod + [a.name] for a in node.names]  # "from . import x" names a module
        elif isinstance(node, ast.Import):
            mods += [a.name.split(".")[1:] for a in node.names if a.name.split(".")[0] == PACKAGE_DIR.name]
        for m in mods:
            found.update(files(m))
    return found


#: _closure's answers, kept while no module of the package has changed (key: every module's name, size and
#: modification time, and the roots): parsing the import closure is most of what a hash costs
_CLOSURE: dict[tuple, list[str]] = {}


def slave_file(fmu: FmuModel) -> str:
    """The package-relative file of an FMU's slave class (refused if the class is not this package's:
    only this package is bundled)."""
    module = fmu.slave.__module__
    top, _, rest = module.partition(".")
    path = sys.modules[module].__file__ if module in sys.modules else None
    if top != PACKAGE_DIR.name or not rest or path is None or not Path(path).resolve().is_relative_to(PACKAGE_DIR):
        raise ValueError(
            f"{fmu.name}: its slave {fmu.slave.__qualname__} is not in {PACKAGE_DIR}: it cannot be bundled"
        )
    return Path(path).resolve().relative_to(PACKAGE_DIR).as_posix()


def bundled_files(fmus: Iterable[FmuModel]) -> list[str]:
    """Package-relative files the slaves of ``fmus`` need: :data:`ROOTS`, their slave classes' modules and
    their package imports, transitively, with the ``__init__.py`` of every package on the way."""
    roots = tuple(sorted({*ROOTS, *(slave_file(f) for f in fmus)}))
    files = tuple((str(f), st.st_size, st.st_mtime_ns) for f in sorted(PACKAGE_DIR.rglob("*.py")) if (st := f.stat()))
    key = (files, roots)
    if key not in _CLOSURE:
        if len(_CLOSURE) > 16 or any(k[0] != files for k in _CLOSURE):
            _CLOSURE.clear()
        _CLOSURE[key] = _stored_closure(key, roots)
    return list(_CLOSURE[key])


#: where :func:`_stored_closure` keeps the closures it computed, beside the FMUs built from them (git-ignored)
CLOSURE_CACHE = PACKAGE_DIR.parent / "fmu" / "build" / ".closure"


def _stored_closure(key: tuple, roots: tuple[str, ...]) -> list[str]:
    """:func:`_closure` of ``roots``, kept on disk under the key (every module's name, size and modification
    time, and the roots): the worker processes of a run, each checking its FMUs, parse the package once between
    them instead of once each (0.3-0.8 s of CPU a process). A missing, unreadable or unwritable cache only
    costs the parse."""
    path = CLOSURE_CACHE / (hashlib.sha256(repr(key).encode()).hexdigest()[:32] + ".json")
    try:
        found = json.loads(path.read_text())
        if isinstance(found, list) and all(isinstance(f, str) and (PACKAGE_DIR / f).is_file() for f in found):
            return found
    except (OSError, ValueError):
        pass
    result = _closure(roots)
    try:
        CLOSURE_CACHE.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(result))
        os.replace(tmp, path)
    except OSError:
        pass
    return result


def _closure(roots: Iterable[str]) -> list[str]:
    todo, seen = sorted(roots), set()
    while todo:
        rel = todo.pop()
        if rel in seen:
            continue
        seen.add(rel)
        parts = rel.split("/")
        for k in range(len(parts)):
            init = "/".join(parts[:k] + ["__init__.py"])
            if (PACKAGE_DIR / init).is_file() and init not in seen:
                todo.append(init)
        found = _relative_imports(rel, (PACKAGE_DIR / rel).read_bytes())
        todo.extend(f for f in found - seen if f.startswith(RUNTIME_PARTS) and f != "models/catalog.py")
    return sorted(seen)


def bundle_hash(files: list[str]) -> str:
    """SHA-256 over the bundled files (names and contents): the bundle's identity."""
    h = hashlib.sha256()
    for rel in files:
        h.update(rel.encode() + b"\0" + hashlib.sha256((PACKAGE_DIR / rel).read_bytes()).digest())
    return h.hexdigest()


def bundle_package(bhash: str) -> str:
    """Name the bundled package is imported under (unique per content)."""
    return f"_pyfmu_{bhash[:16]}"


#: The FMU's resources/model.py: it names the bundle and hands over to the bundled loader
#: (pyfmu_wrapper/fmi/fmu_loader.py, a real module of this package).
MODEL_PY = """\"\"\"Model code of the {model} FMU: the slave from the package bundled beside this file, loaded
by the bundled pyfmu_wrapper/fmi/fmu_loader.py (see its documentation).\"\"\"
import importlib.util
import os

_HERE = os.path.dirname(os.path.abspath(__file__))
_spec = importlib.util.spec_from_file_location(__name__ + "_loader", os.path.join(_HERE, {package!r}, "fmi",
                                                                                    "fmu_loader.py"))
_loader = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_loader)
create = _loader.Bundle(_HERE, {package!r}, {bhash!r}, {files!r}, {slave!r}).create
"""


def model_py(fmu: FmuModel, package: str, bhash: str, files: list[str]) -> str:
    """The FMU's ``resources/model.py`` (:data:`MODEL_PY`) for its slave class in the bundle ``package``
    (the class named for the loader by its module and qualified name, relative to the package)."""
    slave_file(fmu)  # this package's
    module = fmu.slave.__module__.split(".", 1)[1]
    return MODEL_PY.format(
        model=fmu.spec.model_name, package=package, bhash=bhash, files=files, slave=f"{module}:{fmu.slave.__qualname__}"
    )
