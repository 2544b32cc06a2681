"""How an FMU loads its model code: the bundled copy of this package, checked, imported once per
process and build, with numba's on-disk cache kept outside the (temporary) extraction folder.

This module is bundled into every FMU (``resources/<package>/fmi/fmu_loader.py``) and is loaded by
the FMU's ``resources/model.py`` (a few generated lines naming the bundle) by its file path, before
the package is imported, so it uses the standard library only. The FMU's binary calls
``create(...)`` of ``model.py``, i.e. :meth:`Bundle.create`.

* The bundled package is checked against its recorded SHA-256 before it is imported.
* numba's cache of its compiled functions goes to ``<cache root>/<package>/`` with the bundle hash
  as the source stamp (:func:`pyfmu_wrapper._jit.use_bundle_cache`, the package's one cache
  locator): a cache entry of other code cannot be loaded, and extracting the FMU anew (new folder,
  new file times) does not recompile. Cache root: ``$PYFMU_CACHE_DIR``, else
  ``$XDG_CACHE_HOME/pyfmu-fmus``, else ``~/.cache/pyfmu-fmus``.
* Several FMUs of one build share the imported package; the folder a host deleted is dropped
  from the package's search path (:meth:`Bundle.share_package`).
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import os
import sys
from typing import Any


def cache_root() -> str | None:
    """Where the FMUs' numba caches go ($PYFMU_CACHE_DIR, else $XDG_CACHE_HOME/pyfmu-fmus, else
    ~/.cache/pyfmu-fmus)."""
    for d in (
        os.environ.get("PYFMU_CACHE_DIR"),
        os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "pyfmu-fmus"),
    ):
        if d:
            return d
    return None


def files_hash(folder: str, files: list[str]) -> str:
    """SHA-256 over the package-relative ``files`` under ``folder`` (names and contents): the bundle
    hash (the build computes the same over the source package, :func:`pyfmu_wrapper.fmubuild.bundle.bundle_hash`)."""
    h = hashlib.sha256()
    for rel in files:
        with open(os.path.join(folder, rel), "rb") as f:
            h.update(rel.encode() + b"\0" + hashlib.sha256(f.read()).digest())
    return h.hexdigest()


class Bundle:
    """The bundled package ``package`` beside the FMU's model.py (folder ``here``)."""

    def __init__(self, here: str, package: str, bundle_hash: str, files: list[str], slave: str) -> None:
        self.here, self.package, self.bundle_hash, self.files, self.slave = here, package, bundle_hash, files, slave
        self.folder = os.path.join(here, package)

    def check(self) -> None:
        found = files_hash(self.folder, self.files)
        if found != self.bundle_hash:
            raise RuntimeError(
                f"the model code in {self.folder} was modified after the build "
                f"(SHA-256 {found}, recorded {self.bundle_hash}); rebuild the FMU"
            )

    def share_package(self) -> None:
        """The package is imported already, by another FMU of this build, whose folder the host may
        have deleted since (fmpy deletes an FMU's extraction folder when it is done with it). Put
        this FMU's copy (checked) first on the search path of the package and of each of its
        subpackages, and drop folders that are gone: a submodule no FMU imported yet is then found
        in a folder that exists, whichever FMU of the build was loaded, freed or deleted first."""
        pkgs = [
            (n, m)
            for n, m in list(sys.modules.items())
            if (n == self.package or n.startswith(self.package + "."))
            and isinstance(getattr(m, "__path__", None), list)
        ]
        if all(os.path.join(self.folder, *n.split(".")[1:]) in m.__path__ for n, m in pkgs):
            return
        self.check()
        for n, m in pkgs:
            here = os.path.join(self.folder, *n.split(".")[1:])
            m.__path__[:] = [here] + [p for p in m.__path__ if p != here and os.path.isdir(p)]
        importlib.invalidate_caches()

    def import_package(self) -> None:
        if self.package in sys.modules:
            self.share_package()
            return
        self.check()
        spec = importlib.util.spec_from_file_location(
            self.package, os.path.join(self.folder, "__init__.py"), submodule_search_locations=[self.folder]
        )
        if spec is None or spec.loader is None:
            raise ImportError(f"cannot import the bundled package {self.folder}")
        mod = importlib.util.module_from_spec(spec)
        sys.modules[self.package] = mod
        try:
            spec.loader.exec_module(mod)
            # the package's one numba cache locator, told where this bundle's cache is (before any
            # compiled function of the package is defined)
            jit = importlib.import_module(self.package + "._jit")
            jit.use_bundle_cache(cache_root(), self.bundle_hash)
        except BaseException:
            for name in [n for n in sys.modules if n == self.package or n.startswith(self.package + ".")]:
                del sys.modules[name]
            raise

    def create(
        self,
        reals: memoryview,
        ints: memoryview,
        derivs: memoryview,
        scratch: memoryview,
        instance_name: str,
        resources: str,
    ) -> Any:
        """The slave of this FMU (what the FMU's binary calls, through model.py's ``create``)."""
        self.import_package()
        module, _, cls = self.slave.partition(":")
        slave_class = getattr(importlib.import_module(self.package + "." + module), cls)
        return slave_class(reals, ints, derivs, scratch, instance_name, resources)
