"""``njit`` for the package: numba's on-disk cache keyed by the compiled layer's source hash.

numba checks a cached function against its own source file only: a cached function that calls a
compiled function of another file keeps the callee's old machine code when only the callee's file
changes (numba's documented limitation). Every compiled module of this package therefore imports
``njit`` from here; for functions defined in this package the cache lives in
``__pycache__/numba-<hash>`` beside the module (or, when that is not writable, in the user's cache
directory), where ``<hash>`` is :func:`pyfmu_wrapper.codeversion.compiled_hash`: any change to any
file of the compiled layer moves every function to a fresh directory, so nothing stale can load.
Functions of other packages keep numba's own locators.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from numba import njit as _numba_njit
from numba.core import caching as _caching

from .codeversion import PACKAGE_DIR, compiled_hash

__all__ = ["njit", "use_bundle_cache"]


#: Set when this package is an FMU's bundled copy (:func:`use_bundle_cache`, called by the FMU's
#: loader, pyfmu_wrapper/fmi/fmu_loader.py): (cache root, bundle hash).
_BUNDLE: tuple[str, str] | None = None


def use_bundle_cache(root: str | None, bundle_hash: str) -> None:
    """This package is the bundled copy inside an FMU: cache its compiled functions in
    ``<root>/<package folder name>/<subfolders>`` stamped with the bundle hash (the FMU's extraction
    folder is temporary: a cache there would be lost, and recompiled, with every extraction). Without
    a root, numba's own locators (beside the source files)."""
    global _BUNDLE
    _BUNDLE = (root, bundle_hash) if root else None


class _HashedCacheLocator(_caching._SourceFileBackedLocatorMixin, _caching._CacheLocator):
    """The package's one cache locator: a directory per compiled-layer hash (a checkout), or per
    bundle hash (the bundled copy inside an FMU, :func:`use_bundle_cache`)."""

    _user_dir: str | None = None

    def __init__(self, py_func: Callable[..., Any], py_file: str, root: str | Path) -> None:
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        sub = os.path.dirname(os.path.relpath(py_file, root))
        if _BUNDLE is not None:
            cache_root, self._stamp = _BUNDLE
            self._cache_path = os.path.normpath(os.path.join(cache_root, Path(root).name, sub))
        else:
            self._stamp = compiled_hash(root)
            self._cache_path = os.path.join(root, sub, "__pycache__", f"numba-{self._stamp[:16]}")

    def get_cache_path(self) -> str:
        return self._cache_path

    def get_source_stamp(self) -> str:
        return self._stamp

    @classmethod
    def from_function(cls, py_func: Callable[..., Any], py_file: str) -> _HashedCacheLocator | None:
        try:
            path = Path(os.path.abspath(py_file))
        except (OSError, TypeError):
            return None
        if _BUNDLE is not None:
            # the bundled copy of an FMU: found by the package's (unique) folder name, not on disk: several
            # FMUs of one build share the imported package, whose first folder a host may have deleted
            if PACKAGE_DIR.name not in path.parts[:-1]:
                return None
            root = Path(*path.parts[: path.parts.index(PACKAGE_DIR.name) + 1])
        else:
            # the package root: the closest ancestor holding codeversion.py
            root = path.resolve().parent
            while not (root / "codeversion.py").is_file():
                if root.parent == root:
                    return None
                root = root.parent
            if root != PACKAGE_DIR:
                return None
        self = cls(py_func, py_file, root)
        try:
            self.ensure_cache_path()
        except OSError:
            if _BUNDLE is not None:
                return None  # numba's own locators
            user = os.path.join(
                os.path.expanduser("~"),
                ".cache",
                "pyfmu_wrapper",
                "numba",
                self._stamp[:16],
                self.get_suitable_cache_subpath(py_file),
            )
            self._cache_path = user
            try:
                self.ensure_cache_path()
            except OSError:
                return None
        return self


# numba >= 0.61 names the class CacheImpl, older releases _CacheImpl
_IMPL = getattr(_caching, "CacheImpl", None) or _caching._CacheImpl  # type: ignore[attr-defined]
if _HashedCacheLocator not in _IMPL._locator_classes:
    _IMPL._locator_classes.insert(0, _HashedCacheLocator)


def njit(*args: Any, **kwargs: Any) -> Any:
    """numba.njit, with this package's cache locator installed (see the module doc)."""
    return _numba_njit(*args, **kwargs)
