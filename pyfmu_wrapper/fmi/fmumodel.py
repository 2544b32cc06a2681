"""What a module declaring one FMU gives: its variable table, and its native functions if it has any.

A model unit names its FMUs by the dotted names of their declaring modules
(:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.fmus`); each of those modules defines ``FMU``, a
:class:`FmuModel`. The spec names the Python slave (``spec.slave``, "module:Class"); a native FMU's
compiled functions are named the same way (:class:`NativeFmu`), so the host's build
(:mod:`pyfmu_wrapper.fmubuild`) and :mod:`.catalog` reach a model's code by name, never by an import,
and nothing outside the model's folder lists its FMUs.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from .varspec import FmuSpec


@dataclass(frozen=True)
class NativeFmu:
    """The compiled functions of a native FMU, each as "module:function" (a factory, called with no argument)."""

    #: -> the step cfunc (the signature of :data:`pyfmu_wrapper.fmi.native.SIGNATURE`)
    step: str
    #: -> {"configure", "outputs", "derivative", "sensitivity"}: their cfuncs (:mod:`.native_model`'s signatures)
    functions: str
    #: -> the model's table for ``pyfmu_native_model.h``: nstate, np, nu, states (names), checks (the
    #: messages of the cross-field checks, numbered from 1), fields (the messages of FIELD_CODE + slot),
    #: check_vars (the variables a failed cross-field check reports)
    table: str


@dataclass(frozen=True)
class FmuModel:
    """One FMU: its declaration (variables, slave) and its native functions (None: Python-hosted only)."""

    spec: FmuSpec
    native: NativeFmu | None = None

    @property
    def name(self) -> str:
        return self.spec.model_identifier


def resolve(dotted: str) -> Any:
    """The object a "module:attribute" name (or a module's dotted name) refers to."""
    module, _, attr = dotted.partition(":")
    mod = importlib.import_module(module)
    return getattr(mod, attr) if attr else mod


def declared(module: str) -> FmuModel:
    """The ``FMU`` a declaring module defines (refused by name if it defines none)."""
    fmu = getattr(resolve(module), "FMU", None)
    if not isinstance(fmu, FmuModel):
        raise TypeError(f"{module} declares no FMU (a module-level FMU = FmuModel(...))")
    return fmu
