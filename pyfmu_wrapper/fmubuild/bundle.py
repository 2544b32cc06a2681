"""What an FMU bundles of this package: the import closure of the slaves module (:func:`bundled_files`,
found by reading the import statements, with the ``__init__.py`` of every package on the way), its
identity (:func:`bundle_hash`, the name it is imported under, :func:`bundle_package`) and the FMU's
``resources/model.py`` that hands over to the bundled loader (:data:`MODEL_PY`). The archive is
written by :mod:`.build`.
"""

from __future__ import annotations

import ast
import hashlib
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..fmi.varspec import FmuSpec

PACKAGE_DIR = Path(__file__).resolve().parents[1]  # pyfmu_wrapper/

#: The module the slaves live in (the root of the bundled import closure).
SLAVE_MODULE = "fmi/slave.py"
#: the bundled loader of the model code (loaded by the FMU's model.py)
LOADER_MODULE = "fmi/fmu_loader.py"


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


#: bundled_files' last answer, kept while no module of the package has changed (key: every module's
#: name, size and modification time): parsing the import closure is most of what a hash costs
_CLOSURE: dict[tuple, list[str]] = {}


def bundled_files() -> list[str]:
    """Package-relative files the slaves need: the slave machinery (fmi/slave.py), the modules of every FMU's slave (those
    :data:`~pyfmu_wrapper.fmi.catalog.SPECS` name) and their package imports, transitively, with the
    ``__init__.py`` of every package on the way."""
    key = tuple((str(f), st.st_size, st.st_mtime_ns) for f in sorted(PACKAGE_DIR.rglob("*.py")) if (st := f.stat()))
    if key not in _CLOSURE:
        _CLOSURE.clear()
        _CLOSURE[key] = _closure()
    return list(_CLOSURE[key])


def _closure() -> list[str]:
    from ..fmi.catalog import SPECS

    roots = {SLAVE_MODULE, LOADER_MODULE}
    roots |= {spec.slave.split(":")[0].split(".", 1)[1].replace(".", "/") + ".py" for spec in SPECS.values()}
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
        todo.extend(_relative_imports(rel, (PACKAGE_DIR / rel).read_bytes()) - seen)
    return sorted(seen)


def bundle_hash(files: list[str] | None = None) -> str:
    """SHA-256 over the bundled files (names and contents): the bundle's identity."""
    h = hashlib.sha256()
    for rel in files or bundled_files():
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


def model_py(spec: FmuSpec, package: str, bhash: str, files: list[str]) -> str:
    """The FMU's ``resources/model.py`` (:data:`MODEL_PY`) for ``spec``'s slave in the bundle ``package``."""
    module, _, cls = spec.slave.partition(":")
    rel = module.split(".", 1)[1] if module.startswith(PACKAGE_DIR.name + ".") else module
    return MODEL_PY.format(model=spec.model_name, package=package, bhash=bhash, files=files, slave=f"{rel}:{cls}")
