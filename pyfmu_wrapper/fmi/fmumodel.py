"""What one FMU's declaration holds: its variable table, its Python slave class and its native functions' factories, as objects.

A model unit's ``fmus()`` returns its :class:`FmuModel` declarations
(:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.fmus`); the builders (:mod:`pyfmu_wrapper.fmubuild`) take
them as arguments, and nothing resolves a model's code from a name. Where a name has to cross a boundary
(the Python-hosted FMU's ``resources/model.py`` names the slave class for the loader in the FMU's process;
the native build compiles the factories in a fresh interpreter), it is derived from the object
(:func:`dotted_name`), never written by hand.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .varspec import FmuSpec

if TYPE_CHECKING:
    from .slave import Slave


@dataclass(frozen=True)
class NativeFmu:
    """The compiled functions of a native FMU: their factories (each called with no argument), defined
    at the top level of a module of this package (the native build compiles them in a subprocess)."""

    #: -> the step cfunc (the signature of :data:`pyfmu_wrapper.fmi.native.SIGNATURE`)
    step: Callable[[], Any]
    #: -> {"configure", "outputs", "derivative", "sensitivity"}: their cfuncs (:mod:`.native_model`'s signatures)
    functions: Callable[[], dict[str, Any]]
    #: -> the model's table for ``pyfmu_native_model.h``: nstate, np, nu, states (names), checks (the
    #: messages of the cross-field checks, numbered from 1), fields (the messages of FIELD_CODE + slot),
    #: check_vars (the variables a failed cross-field check reports)
    table: Callable[[], dict[str, Any]]

    def factories(self) -> tuple[Callable[..., Any], ...]:
        return (self.step, self.functions, self.table)


@dataclass(frozen=True, eq=False)
class FmuModel:
    """One FMU: its variable table, the Python slave class that runs it (whose ``spec`` is that table)
    and its native functions (None: Python-hosted only)."""

    spec: FmuSpec
    slave: type[Slave]
    native: NativeFmu | None = None
    #: the whole structure with its absorber in one FMU (a system FMU, e.g. for Model Exchange): not one of the
    #: parts the unit's co-simulation couples
    system: bool = False

    def __post_init__(self) -> None:
        if getattr(self.slave, "spec", None) is not self.spec:
            raise ValueError(f"{self.spec.model_identifier}: the slave {self.slave.__qualname__} runs another spec")

    @property
    def name(self) -> str:
        return self.spec.model_identifier


def resolve(dotted: str) -> Any:
    """The object a "module:qualified.name" (from :func:`dotted_name`) refers to."""
    module, _, attr = dotted.partition(":")
    obj: Any = importlib.import_module(module)
    for part in attr.split(".") if attr else ():
        obj = getattr(obj, part)
    return obj


def dotted_name(obj: Any) -> str:
    """The name "module:qualified.name" of a class or function, for a boundary a Python object cannot cross;
    refused unless it names ``obj`` itself (a function defined inside another has no importable name)."""
    name = f"{obj.__module__}:{obj.__qualname__}"
    if "<" in name or resolve(name) is not obj:
        raise ValueError(f"{name} does not name the object it was taken from: define it at a module's top level")
    return name
