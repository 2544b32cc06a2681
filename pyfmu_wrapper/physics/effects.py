"""The effect vocabulary of a model unit: what ``diagnose`` can name as the cause of a misfit.

An :class:`Effect` is a mechanism or a parameter change at one element of the model (dry friction in
the TMD link, play in the inerter gear, a storey's stiffness off the nominal, a gain error of the force
channel), with its parameters (name, SI unit, whether it enters the equations linearly, the bounds of
its physical range) and the levels at which it can occur (``system``: the whole rig's records;
``link``: the TMD link on a test machine). A model unit declares its vocabulary once
(:attr:`pyfmu_wrapper.physics.unit.ModelUnit.effects`); the steady, FRC, transient and link fits, the
benchmark generators and the reports read it from there and choose their subsets by name.

A parameter that is one of the unit's declared parameters takes its unit from the registry
(:func:`registry_param`), so a change of a registry row reaches the diagnosis.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable, Mapping, MutableMapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from . import registry

SYSTEM, LINK = "system", "link"


@dataclass(frozen=True)
class EffectParam:
    """One parameter of an effect: the name it is reported under (``friction_force``, ``delta_mass``),
    its SI unit as the reports write it, whether the model is linear in it (fitted by least squares in
    the equation-error fits; a nonlinear one is searched), its physical bounds, and what it does to the
    model's declared parameters: ``targets`` as (``subsystem.name``, coefficient), each changed by
    coefficient x the value, or (``replaces``) set to the value (a friction force replaces the
    nominal's). A measurement effect (a gain, an offset) has no target."""

    name: str
    unit: str
    linear: bool = True
    bounds: tuple[float, float] = (-math.inf, math.inf)
    targets: tuple[tuple[str, float], ...] = ()
    replaces: bool = False


@dataclass(frozen=True)
class Effect:
    """One effect of the vocabulary (module doc). ``element``: where it acts, as the verdict names it;
    ``signed``: it can be of either sign (a parameter off its nominal, a gain error), else it is a
    positive amount (a friction force, a gap); ``size``: the parameter a benchmark scores the effect by
    (default: the first); ``per``: the effect is declared once and instantiated at every element of
    that kind (``storey``: at each storey of a frame, ``channel``: at each recorded channel), its
    ``element`` then a template with ``{}`` for the storey number or the channel's column
    (``storey {}``, ``channel {}``): :meth:`elements`."""

    name: str
    label: str
    element: str
    params: tuple[EffectParam, ...]
    signed: bool = False
    levels: tuple[str, ...] = (SYSTEM,)
    size: str = ""
    per: str = ""

    def at(self, where: int | str) -> str:
        """The element string of this effect at storey / channel ``where`` (its ``element`` when it is
        not a per-element effect)."""
        return self.element.format(where) if self.per else self.element

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params)

    @property
    def linear_params(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.params if p.linear)

    def param(self, name: str) -> EffectParam:
        """The parameter ``name`` (KeyError naming the effect's parameters otherwise)."""
        for p in self.params:
            if p.name == name:
                return p
        raise KeyError(f"effect {self.name!r} has no parameter {name!r}; it has {list(self.param_names)}")

    @property
    def truth_key(self) -> str:
        """``effect.parameter`` of the size the benchmarks score (the diagnosis reports it under this key)."""
        return f"{self.name}.{self.size or self.params[0].name}"


def report_unit(fmi_unit: str) -> str:
    """A registry unit (FMI notation: ``N.s/m``, ``N/m3``) as the reports write it (``N s/m``, ``N/m^3``)."""
    out = fmi_unit.replace(".", " ")
    for n in "23456789":
        out = out.replace(f"m{n}", f"m^{n}")
    return out


def registry_param(
    subsystem: str,
    name: str,
    reported: str = "",
    *,
    linear: bool = True,
    bounds: tuple[float, float] = (-math.inf, math.inf),
    replaces: bool = False,
    also: tuple[tuple[str, float], ...] = (),
) -> EffectParam:
    """An effect parameter that changes the declared parameter ``subsystem.name`` by its value (or,
    ``replaces``, sets it), and the ``also`` ones by a coefficient times it; reported under ``reported``
    (default: the declared name), its unit from the registry."""
    row = registry.get(subsystem, name)
    targets = ((f"{subsystem}.{name}", 1.0), *also)
    return EffectParam(reported or name, report_unit(row.unit), linear, bounds, targets, replaces)


class Vocabulary:
    """A unit's effects by name, with the views every path reads."""

    def __init__(self, effects: Iterable[Effect]) -> None:
        self.effects: dict[str, Effect] = {}
        units: dict[str, str] = {}
        for e in effects:
            if e.name in self.effects:
                raise ValueError(f"effect {e.name!r} is declared twice")
            for p in e.params:
                if units.setdefault(p.name, p.unit) != p.unit:
                    raise ValueError(f"parameter {p.name!r} has two units: {units[p.name]!r} and {p.unit!r}")
            self.effects[e.name] = e
        self.units = units

    def apply(self, values: MutableMapping[str, float], params: Mapping[str, float]) -> None:
        """Apply effect parameters ``params`` (``effect.parameter`` -> value) to ``values``
        (``subsystem.name`` -> value of the model's declared parameters): each parameter's targets
        (:class:`EffectParam`), in the order of ``params``. Measurement effects change nothing here."""
        for k, v in params.items():
            e, name = k.split(".", 1)
            par = self.effects[e].param(name)
            for key, coef in par.targets:
                values[key] = float(v) if par.replaces else values[key] + coef * float(v)

    def change(
        self, values: MutableMapping[str, float], effects: Iterable[str], theta: Sequence[float] | NDArray[np.float64]
    ) -> None:
        """:meth:`apply` of ``effects`` at parameters ``theta`` (concatenated in effect order)."""
        names = [f"{e}.{p.name}" for e in effects for p in self.effects[e].params]
        self.apply(values, dict(zip(names, theta, strict=True)))

    def changed(self, nominal: Mapping[str, Any], params: Mapping[str, float]) -> dict[str, Any]:
        """The parameter objects ``nominal`` (subsystem -> dataclass, e.g. ``{"base": BaseParams, "tmd":
        TMDParams}``) changed by ``params`` (:meth:`apply`), every changed parameter kept within its
        registry bound (a strict minimum m: m + 1e-6 of the nominal), so the model can be evaluated."""
        keys = {key for k in params for key, _ in self.effects[k.split(".", 1)[0]].param(k.split(".", 1)[1]).targets}
        vals = {key: float(getattr(nominal[key.split(".")[0]], key.split(".")[1])) for key in keys}
        self.apply(vals, params)
        kw: dict[str, dict[str, Any]] = {sub: {} for sub in nominal}
        for key, v in vals.items():
            sub, field = key.split(".")
            row = registry.get(sub, field)
            if row.minimum is not None:
                v = max(v, row.minimum + (1e-6 * getattr(nominal[sub], field) if row.strict else 0.0))
            kw[sub][field] = v
        return {sub: dataclasses.replace(obj, **kw[sub]) for sub, obj in nominal.items()}

    def __getitem__(self, name: str) -> Effect:
        return self.effects[name]

    def __contains__(self, name: object) -> bool:
        return name in self.effects

    def names(self, level: str = SYSTEM) -> tuple[str, ...]:
        return tuple(n for n, e in self.effects.items() if level in e.levels)

    def select(self, names: Iterable[str]) -> tuple[str, ...]:
        """``names`` checked against the vocabulary (a path's subset, in its own order)."""
        out = tuple(names)
        unknown = [n for n in out if n not in self.effects]
        if unknown:
            raise KeyError(f"effects {unknown} are not in the vocabulary ({', '.join(self.effects)})")
        return out

    def labels(self) -> dict[str, str]:
        return {n: e.label for n, e in self.effects.items()}

    def bounds(self) -> dict[str, tuple[float, float]]:
        """``effect.parameter`` -> bounds, for the bounded ones."""
        inf = (-math.inf, math.inf)
        return {f"{n}.{p.name}": p.bounds for n, e in self.effects.items() for p in e.params if p.bounds != inf}

    def truth_keys(self, names: Iterable[str]) -> dict[str, str]:
        return {n: self.effects[n].truth_key for n in names}

    def signed(self) -> set[str]:
        return {n for n, e in self.effects.items() if e.signed}
