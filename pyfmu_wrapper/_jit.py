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
from pathlib import Path

from numba import njit as _numba_njit
from numba.core import caching as _caching

from .codeversion import PACKAGE_DIR, compiled_hash

__all__ = ["njit"]


class _HashedCacheLocator(_caching._SourceFileBackedLocatorMixin, _caching._CacheLocator):
    """Cache locator for this package's functions: a directory per compiled-layer hash."""

    _user_dir: str | None = None

    def __init__(self, py_func, py_file, root):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._stamp = compiled_hash(root)
        self._cache_path = os.path.join(root, os.path.dirname(os.path.relpath(py_file, root)), "__pycache__",
                                        f"numba-{self._stamp[:16]}")

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return self._stamp

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            root = Path(py_file).resolve().parent
        except (OSError, TypeError):
            return None
        # the package root: the closest ancestor holding codeversion.py (works for bundled copies)
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
            user = os.path.join(os.path.expanduser("~"), ".cache", "pyfmu_wrapper", "numba",
                                self._stamp[:16], self.get_suitable_cache_subpath(py_file))
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


def njit(*args, **kwargs):
    """numba.njit, with this package's cache locator installed (see the module doc)."""
    return _numba_njit(*args, **kwargs)
