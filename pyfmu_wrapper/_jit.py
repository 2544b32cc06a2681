"""``njit`` for the package: numba's on-disk cache keyed by the compiled layer's source hash, and
numba imported only when compiled code is first needed.

numba checks a cached function against its own source file only: a cached function that calls a
compiled function of another file keeps the callee's old machine code when only the callee's file
changes (numba's documented limitation). Every compiled module of this package therefore imports
``njit`` from here; for functions defined in this package the cache lives in
``__pycache__/numba-<hash>`` beside the module (or, when that is not writable, in the user's cache
directory), where ``<hash>`` is :func:`pyfmu_wrapper.codeversion.compiled_hash`: any change to any
file of the compiled layer moves every function to a fresh directory, so nothing stale can load.
Functions of other packages keep numba's own locators.

Importing numba costs about a second of CPU (more on a loaded machine). A console script must read
and refuse a bad input file before that (docs/scenarios.md, "Refusals"), and the input checks live
beside the equations, in modules that define compiled functions. So until compiled code is needed,
the ``njit`` decorator returns a :class:`LazyJit`: the Python function with numba's decorator arguments. Its
``py_func`` is the plain function (input checks call a small compiled check through it); calling it,
or asking it for any of the dispatcher's attributes, imports numba (:func:`load`), makes the real
dispatcher, and replaces every lazy function in the package's loaded modules by its dispatcher (a
compiled function calling another one, a Python loop calling a kernel: the same objects, the same
speed as an eager ``numba.njit``). Compiled code that refers to a lazy function still held
elsewhere (in a tuple, a closure) types it as its dispatcher (a ``typeof`` registered for
:class:`LazyJit`). Once numba is imported (by :func:`load` or by anyone), ``njit`` is numba's.
:func:`on_load` runs a module's numba-only registrations (``overload``) at that moment.
"""

from __future__ import annotations

import os
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .codeversion import PACKAGE_DIR, compiled_hash

__all__ = ["njit", "use_bundle_cache", "on_load", "load", "LazyJit", "numba_loaded"]


#: Set when this package is an FMU's bundled copy (:func:`use_bundle_cache`, called by the FMU's
#: loader, pyfmu_wrapper/fmi/fmu_loader.py): (cache root, bundle hash).
_BUNDLE: tuple[str, str] | None = None

_NUMBA_NJIT: Callable[..., Any] | None = None  #: numba.njit, once :func:`load` ran
_LOCK = threading.RLock()
_HOOKS: list[Callable[[], None]] = []
_LAZY: list[LazyJit] = []


def use_bundle_cache(root: str | None, bundle_hash: str) -> None:
    """This package is the bundled copy inside an FMU: cache its compiled functions in
    ``<root>/<package folder name>/<subfolders>`` stamped with the bundle hash (the FMU's extraction
    folder is temporary: a cache there would be lost, and recompiled, with every extraction). Without
    a root, numba's own locators (beside the source files)."""
    global _BUNDLE
    _BUNDLE = (root, bundle_hash) if root else None


def numba_loaded() -> bool:
    """True once :func:`load` has imported numba for this package."""
    return _NUMBA_NJIT is not None


def on_load(hook: Callable[[], None]) -> None:
    """Run ``hook`` when numba is loaded (now, if it already is): a module's registrations that need
    numba itself (``numba.extending.overload``), kept out of its import."""
    with _LOCK:
        if _NUMBA_NJIT is None:
            _HOOKS.append(hook)
            return
    hook()


class LazyJit:
    """A function decorated with :func:`njit` before numba is loaded (see the module doc)."""

    def __init__(self, py_func: Callable[..., Any], args: tuple, kwargs: dict) -> None:
        self.py_func = py_func
        self._args, self._kwargs = args, kwargs
        self._disp: Any = None
        for name in ("__name__", "__qualname__", "__module__", "__doc__"):
            setattr(self, name, getattr(py_func, name, None))
        self.__wrapped__ = py_func

    def dispatcher(self) -> Any:
        """numba's dispatcher of the function (numba is loaded when it is not yet)."""
        if self._disp is None:
            load()
            with _LOCK:
                if self._disp is None:
                    assert _NUMBA_NJIT is not None
                    self._disp = _NUMBA_NJIT(*self._args, **self._kwargs)(self.py_func)
        return self._disp

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        d = self._disp  # held in a container (a tuple, a dataclass), a proxy stays: one attribute read more
        return (d if d is not None else self.dispatcher())(*args, **kwargs)

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__") or name in ("_disp", "_args", "_kwargs", "py_func"):
            raise AttributeError(name)
        return getattr(self.dispatcher(), name)

    def __reduce__(self) -> Any:  # pickled as numba pickles its dispatcher
        return self.dispatcher().__reduce__()

    def __repr__(self) -> str:
        return f"LazyJit({self.__qualname__})"


def njit(*args: Any, **kwargs: Any) -> Any:
    """numba.njit, with this package's cache locator installed; lazy until numba is needed (see the
    module doc). Used bare, with keywords (``cache=True``) or with a signature, as numba.njit."""
    if len(args) == 1 and callable(args[0]) and not isinstance(args[0], str) and not kwargs:
        return njit()(args[0])
    if _NUMBA_NJIT is None and "numba" in sys.modules:
        load()  # numba is already paid for (a cfunc module imported it): no reason to wait
    if _NUMBA_NJIT is not None:
        return _NUMBA_NJIT(*args, **kwargs)

    def deco(func: Callable[..., Any]) -> Any:
        if _NUMBA_NJIT is not None:
            return _NUMBA_NJIT(*args, **kwargs)(func)
        lazy = LazyJit(func, args, kwargs)
        with _LOCK:
            _LAZY.append(lazy)
        return lazy

    return deco


def load() -> None:
    """Import numba, install the package's cache locator, run the :func:`on_load` hooks, and replace
    the lazy functions in the package's loaded modules by their dispatchers. Idempotent."""
    global _NUMBA_NJIT
    if _NUMBA_NJIT is not None:
        return
    with _LOCK:
        if _NUMBA_NJIT is not None:
            return
        import numba
        from numba.core.typing.typeof import typeof
        from numba.extending import typeof_impl

        _install_locator()

        @typeof_impl.register(LazyJit)
        def _typeof_lazy(val: LazyJit, c: Any) -> Any:
            return typeof(val.dispatcher(), c.purpose)

        _NUMBA_NJIT = numba.njit
        hooks, _HOOKS[:] = list(_HOOKS), []
        for hook in hooks:
            hook()
        lazies, _LAZY[:] = list(_LAZY), []
        for lazy in lazies:
            lazy.dispatcher()
        _swap_module_globals()


def _swap_module_globals() -> None:
    """Every module-level name bound to a :class:`LazyJit` in the package's loaded modules (the
    defining module and those that imported the name) now names the dispatcher itself."""
    prefix = __name__.rsplit(".", 1)[0]
    for name, mod in list(sys.modules.items()):
        if mod is None or not (name == prefix or name.startswith(prefix + ".")):
            continue
        space = getattr(mod, "__dict__", None)
        if not isinstance(space, dict):
            continue
        for key, value in list(space.items()):
            if isinstance(value, LazyJit):
                space[key] = value.dispatcher()


def _install_locator() -> None:
    """Define the package's cache locator (a numba class) and put it first in numba's list."""
    from numba.core import caching as _caching

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
    impl = getattr(_caching, "CacheImpl", None) or _caching._CacheImpl  # type: ignore[attr-defined]
    if _HashedCacheLocator not in impl._locator_classes:  # this copy's own (an FMU's bundled copy has its own)
        impl._locator_classes.insert(0, _HashedCacheLocator)
