"""Physical parameters of the base oscillator and the TMD-inerter subsystem.

All quantities are SI: kg, N/m, N s/m, N, m, rad/s. Parameters are frozen dataclasses validated
at construction; a bad value raises :class:`ParameterError` naming the field, the value and, when
known, where it came from (a scenario file and key path).

The paper's symbols (Brzeski & Perlikowski 2017, Table 1) are given beside each field. The
numeric packing (:func:`pack`) is the single mapping between these objects and the compiled
kernels of :mod:`pyfmu_wrapper.physics.kernels`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np

from .._jit import njit
from ..errors import InputError
from . import registry
from .registry import InerterModel


class ParameterError(InputError):
    """A non-physical or malformed parameter value."""


def _check(
    name: str,
    value: Any,
    *,
    source: str | None,
    minimum: float | None = None,
    strict: bool = False,
    integer: bool = False,
) -> float:
    where = f" (from {source})" if source else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        from ..errors import short

        raise ParameterError(f"{name} must be a number, got {short(value)}{where}")
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {value!r}{where}")
    if minimum is not None:
        if strict and not v > minimum:
            raise ParameterError(f"{name} must be > {minimum:g}, got {value!r}{where}")
        if not strict and not v >= minimum:
            raise ParameterError(f"{name} must be >= {minimum:g}, got {value!r}{where}")
    return v


def _default(subsystem: str, name: str) -> Any:
    """The field's default, as the registry declares it (one source)."""
    par = registry.get(subsystem, name)
    return field(default=InerterModel(int(par.default)) if par.kind == "enum" else float(par.default))


def _source() -> Any:
    return field(default=None, compare=False, repr=False)


@dataclass(frozen=True, kw_only=True)
class BaseParams:
    """Base oscillator: M xdd + C xd + K x = F cos(w t) - (force of the TMD links). The excitation
    frequency w [rad/s] is passed to the solvers, not stored here. The fields, their units, defaults
    and ranges are the registry's (:mod:`pyfmu_wrapper.physics.registry`; tests/test_registry.py holds
    the two equal, name by name and in order)."""

    mass: float = _default("base", "mass")  #: M [kg]
    stiffness: float = _default("base", "stiffness")  #: K [N/m]
    damping: float = _default("base", "damping")  #: C [N.s/m]
    force_amplitude: float = _default("base", "force_amplitude")  #: F [N]
    source: str | None = _source()  #: where the values come from (named in errors)

    def __post_init__(self) -> None:
        _validate_fields(self, "base")

    @property
    def natural_frequency(self) -> float:
        """sqrt(K/M) in rad/s."""
        return math.sqrt(self.stiffness / self.mass)


@dataclass(frozen=True, kw_only=True)
class TMDParams:
    """TMD mass m and its links to the base (paper Table 1): spring k + k3 (x-y)^3, damper c, dry
    friction df, inerter I (none / ideal / with play ki, ci, eps). Link forces are counted positive
    when they push the base in -x and the TMD in +y: Fs = k (x - y) + k3 (x - y)^3 + c (xd - yd) +
    df (2/pi) atan(s (xd - yd)), and the inerter force P. Fields as the registry declares them."""

    mass: float = _default("tmd", "mass")  #: m [kg]
    stiffness: float = _default("tmd", "stiffness")  #: k [N/m]
    damping: float = _default("tmd", "damping")  #: c [N.s/m]
    friction_force: float = _default("tmd", "friction_force")  #: df [N]
    friction_slope: float = _default("tmd", "friction_slope")  #: s [s/m]
    inertance: float = _default("tmd", "inertance")  #: I [kg]
    mesh_stiffness: float = _default("tmd", "mesh_stiffness")  #: ki [N/m]
    mesh_damping: float = _default("tmd", "mesh_damping")  #: ci [N.s/m]
    play_gap: float = _default("tmd", "play_gap")  #: eps [m]
    inerter: InerterModel = _default("tmd", "inerter")  #: none / ideal / play
    cubic_stiffness: float = _default("tmd", "cubic_stiffness")  #: k3 [N/m^3]
    source: str | None = _source()  #: where the values come from (named in errors)

    def __post_init__(self) -> None:
        s = self.source
        where = f" (from {s})" if s else ""
        try:
            model = InerterModel[self.inerter.upper()] if isinstance(self.inerter, str) else InerterModel(self.inerter)
        except (KeyError, ValueError, TypeError, AttributeError):
            raise ParameterError(
                f"inerter must be one of {[m.name.lower() for m in InerterModel]}, got {self.inerter!r}{where}"
            ) from None
        object.__setattr__(self, "inerter", model)
        _validate_fields(self, "tmd")
        code = tmd_check.py_func(float(self.mass), float(self.inertance), int(model))  # the same check, in Python
        if code:
            raise ParameterError(
                f"{TMD_CHECKS[code - 1]}, got m = {self.mass!r}, I = {self.inertance!r}, "
                f"inerter = '{model.name.lower()}'{where}"
            )

    @property
    def inertia(self) -> float:
        """m + I [kg], the overall inertia of the TMD."""
        return self.mass + self.inertance

    @property
    def inertance_ratio(self) -> float:
        """Iratio = I / (m + I)."""
        return self.inertance / self.inertia

    @property
    def is_linear(self) -> bool:
        """True when the coupled system is linear: no friction, no gap and no cubic spring term."""
        return (
            self.friction_force == 0.0
            and self.cubic_stiffness == 0.0
            and (self.inerter != InerterModel.PLAY or self.play_gap == 0.0)
        )


def _validate_fields(obj: Any, subsystem: str) -> None:
    s = obj.source
    for par in registry.fields(subsystem):
        if par.kind != "real":
            continue
        value = _check(
            f"{par.name} ({par.symbol})", getattr(obj, par.name), source=s, minimum=par.minimum, strict=par.strict
        )
        object.__setattr__(obj, par.name, value)


def as_dict(obj: Any) -> dict[str, Any]:
    d = asdict(obj)
    d.pop("source", None)
    if "inerter" in d:
        d["inerter"] = InerterModel(d["inerter"]).name.lower()
    return d


# --- numeric packing for the compiled kernels --------------------------------------------------
# The indices come from the registry (its order is the packed order); kernels.py uses these names.
_IX = registry.PACK_INDEX
P_M, P_K, P_C, P_F, P_W = (
    _IX["base.mass"],
    _IX["base.stiffness"],
    _IX["base.damping"],
    _IX["base.force_amplitude"],
    _IX["base.omega"],
)
P_m, P_k, P_c, P_df, P_s = (
    _IX["tmd.mass"],
    _IX["tmd.stiffness"],
    _IX["tmd.damping"],
    _IX["tmd.friction_force"],
    _IX["tmd.friction_slope"],
)
P_I, P_ki, P_ci, P_eps, P_MODEL = (
    _IX["tmd.inertance"],
    _IX["tmd.mesh_stiffness"],
    _IX["tmd.mesh_damping"],
    _IX["tmd.play_gap"],
    _IX["tmd.inerter"],
)
P_k3 = _IX["tmd.cubic_stiffness"]
N_PARAMS = registry.N_PARAMS


def pack(base: BaseParams, tmd: TMDParams, omega: float = 0.0) -> np.ndarray:
    """Pack parameters and the excitation frequency omega [rad/s] into the kernels' float array
    (one entry per registry parameter, in registry order)."""
    p = np.zeros(N_PARAMS)
    for i, par in enumerate(registry.PARAMETERS):
        if par.subsystem == "base":
            p[i] = omega if par.name == "omega" else getattr(base, par.name)
        elif par.subsystem == "tmd":
            p[i] = float(int(getattr(tmd, par.name))) if par.kind == "enum" else getattr(tmd, par.name)
        else:  # pragma: no cover - PARAMETERS holds base and tmd only (others are declared)
            raise ValueError(f"parameter {par.subsystem}.{par.name} is not packed with the paper's array")
    return p


#: the cross-field checks of a TMD, in the order :func:`tmd_check` numbers them (1, 2, ...): the
#: words of TMDParams' errors and of the native FMU's configure (fmi/native_model.py calls tmd_check)
TMD_CHECKS = (
    "inertance must be 0 when inerter is 'none'",
    "inertance must be > 0 for an inerter (ideal or with play)",
    "mass + inertance (m + I) must be > 0",
    "mass (m) must be > 0 unless the inerter is ideal (the TMD node would be massless)",
)


@njit(cache=True)
def tmd_check(mass: float, inertance: float, model: int) -> int:
    """0 when a TMD's mass m, inertance I and inerter model (0 none, 1 ideal, 2 play) go together, else
    the number of the first check of :data:`TMD_CHECKS` they fail."""
    if model == 0 and inertance != 0.0:
        return 1
    if model != 0 and inertance <= 0.0:
        return 2
    if mass + inertance <= 0.0:
        return 3
    if mass <= 0.0 and model != 1:
        return 4
    return 0


# Paper cases (Sect. 3): m + I = 10 kg.
CASES = {1: dict(mass=9.0, inertance=1.0), 2: dict(mass=5.0, inertance=5.0), 3: dict(mass=1.0, inertance=9.0)}
#: the paper's optimised viscous damping c [N s/m] per case (Sect. 4, Fig. 3)
PAPER_C_OPT = {1: 56.38, 2: 31.73, 3: 6.45}
#: the paper's optimised dry friction df [N] per case (Sect. 5, Fig. 4)
PAPER_DF_OPT = {1: 45.78, 2: 37.65, 3: 15.44}
#: the paper's standardised play gap eps [m] (Sect. 6)
PAPER_GAP = 1e-4
#: the paper's full model (Sect. 7, line "5" of Fig. 6): (c [N s/m], df [N]) per case; Case 3 half
PAPER_FULL_C_DF = {1: (10.0, 10.0), 2: (10.0, 10.0), 3: (5.0, 5.0)}


def has_gap(tmd: TMDParams) -> bool:
    """The inerter has play with a gap (eps > 0): the rattling configurations, never exactly periodic."""
    return tmd.inerter == InerterModel.PLAY and tmd.play_gap > 0.0


def is_detached(tmd: TMDParams) -> bool:
    """No link joins the TMD to the structure (no spring, damper, friction or inerter: a curve "without the
    TMD"): its mass moves freely, untouched by the structure, so its states are no part of the response."""
    no_inerter = tmd.inerter == InerterModel.NONE or tmd.inertance == 0.0
    links = (tmd.stiffness, tmd.cubic_stiffness, tmd.damping, tmd.friction_force)
    return no_inerter and all(v == 0.0 for v in links)


def paper_case(case: int, **overrides: Any) -> TMDParams:
    """TMD parameters of the paper's Case 1, 2 or 3 (ideal inerter, no damping unless overridden)."""
    if case not in CASES:
        raise ParameterError(f"case must be 1, 2 or 3, got {case!r}")
    kw: dict[str, Any] = dict(CASES[case])
    kw.update(overrides)
    return TMDParams(**kw)


def field_names(cls: Any) -> list[str]:
    return [f.name for f in fields(cls) if f.name != "source"]


def check_structure(obj: Any, parameters: tuple[registry.Parameter, ...], source: str | None) -> None:
    """Validate a frozen structure dataclass against its declared rows, in its ``__post_init__``: every field a
    finite number within its bound (refused with one :class:`ParameterError`
    line naming the field, its value, its unit and ``source``), stored as a float."""
    where = f" (from {source})" if source else ""
    for p in parameters:
        v = getattr(obj, p.name)
        ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
        if ok and p.minimum is not None:
            ok = v > p.minimum if p.strict else v >= p.minimum
        if not ok:
            bound = "" if p.minimum is None else (f" > {p.minimum:g}" if p.strict else f" >= {p.minimum:g}")
            raise ParameterError(f"{p.label} must be a finite number{bound} [{p.unit}], got {v!r}{where}")
        object.__setattr__(obj, p.name, float(v))
