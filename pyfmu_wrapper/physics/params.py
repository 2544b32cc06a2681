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
from dataclasses import asdict, dataclass, field, fields, replace
from enum import IntEnum

import numpy as np


class ParameterError(ValueError):
    """A non-physical or malformed parameter value."""


class InerterModel(IntEnum):
    """How the inerter link between base and TMD is modelled (paper Table 1)."""

    NONE = 0  #: no inerter (I must be 0)
    IDEAL = 1  #: ideal inerter, force I (xdd - ydd)
    PLAY = 2  #: Scheibe-Smith chain: inerter I - mesh spring ki || damper ci - gap +-eps
    # eps = 0 with finite ki is the linear inerter-in-series-with-spring (no clamping); the
    # kernels treat it through the same PLAY chain with a zero gap.


def _check(name: str, value, *, source: str | None, minimum=None, strict=False, integer=False):
    where = f" (from {source})" if source else ""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise ParameterError(f"{name} must be a number, got {value!r}{where}")
    v = float(value)
    if not math.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {value!r}{where}")
    if minimum is not None:
        if strict and not v > minimum:
            raise ParameterError(f"{name} must be > {minimum:g}, got {value!r}{where}")
        if not strict and not v >= minimum:
            raise ParameterError(f"{name} must be >= {minimum:g}, got {value!r}{where}")
    return v


@dataclass(frozen=True)
class BaseParams:
    """Base oscillator: M xdd + C xd + K x = F cos(omega t) - (force of the TMD links).

    mass: M [kg]; stiffness: K [N/m]; damping: C [N s/m]; force_amplitude: F [N].
    The excitation frequency omega [rad/s] is not a parameter of the structure; it is passed to
    the solvers (the paper's "Hz" are rad/s, see the physics notes).
    """

    mass: float = 100.0
    stiffness: float = 4.0e4
    damping: float = 100.0
    force_amplitude: float = 200.0
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        s = self.source
        object.__setattr__(self, "mass", _check("mass (M)", self.mass, source=s, minimum=0, strict=True))
        object.__setattr__(self, "stiffness", _check("stiffness (K)", self.stiffness, source=s, minimum=0))
        object.__setattr__(self, "damping", _check("damping (C)", self.damping, source=s, minimum=0))
        object.__setattr__(self, "force_amplitude", _check("force_amplitude (F)", self.force_amplitude, source=s))

    @property
    def natural_frequency(self) -> float:
        """sqrt(K/M) in rad/s."""
        return math.sqrt(self.stiffness / self.mass)


@dataclass(frozen=True)
class TMDParams:
    """TMD mass m and its links to the base (paper Table 1).

    Link forces are counted positive when they push the base in -x and the TMD in +y:
    Fs = k (x - y) + c (xd - yd) + df (2/pi) atan(s (xd - yd)), and the inerter force P.

    mass: m [kg]; stiffness: k [N/m]; damping: c [N s/m]; friction_force: df [N];
    friction_slope: s [s/m] (regularisation of sign(); 1e6 in the paper); inertance: I [kg];
    inerter: which inerter model; mesh_stiffness: ki [N/m]; mesh_damping: ci [N s/m];
    play_gap: eps [m] (half the backlash: the gear is free while |r - y| < eps).
    """

    mass: float = 9.0
    stiffness: float = 4.0e3
    damping: float = 0.0
    friction_force: float = 0.0
    friction_slope: float = 1.0e6
    inertance: float = 1.0
    inerter: InerterModel = InerterModel.IDEAL
    mesh_stiffness: float = 2.0e7
    mesh_damping: float = 0.01
    play_gap: float = 0.0
    source: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        s = self.source
        chk = {
            "mass": dict(minimum=0),
            "stiffness": dict(minimum=0),
            "damping": dict(minimum=0),
            "friction_force": dict(minimum=0),
            "friction_slope": dict(minimum=0, strict=True),
            "inertance": dict(minimum=0),
            "mesh_stiffness": dict(minimum=0, strict=True),
            "mesh_damping": dict(minimum=0),
            "play_gap": dict(minimum=0),
        }
        for name, kw in chk.items():
            object.__setattr__(self, name, _check(name, getattr(self, name), source=s, **kw))
        try:
            model = InerterModel[self.inerter.upper()] if isinstance(self.inerter, str) else InerterModel(self.inerter)
        except (KeyError, ValueError):
            where = f" (from {s})" if s else ""
            raise ParameterError(
                f"inerter must be one of {[m.name.lower() for m in InerterModel]}, got {self.inerter!r}{where}"
            ) from None
        object.__setattr__(self, "inerter", model)
        where = f" (from {s})" if s else ""
        if model == InerterModel.NONE and self.inertance != 0.0:
            raise ParameterError(f"inertance must be 0 when inerter is 'none', got {self.inertance!r}{where}")
        if model != InerterModel.NONE and self.inertance <= 0.0:
            raise ParameterError(f"inertance must be > 0 for inerter '{model.name.lower()}', got {self.inertance!r}{where}")
        if self.mass + self.inertance <= 0.0:
            raise ParameterError(f"mass + inertance (m + I) must be > 0, got {self.mass!r} + {self.inertance!r}{where}")
        if self.mass <= 0.0 and model != InerterModel.IDEAL:
            raise ParameterError(
                f"mass (m) must be > 0 unless the inerter is ideal (the TMD node would be massless), got {self.mass!r}{where}"
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
        """True when the coupled system is linear: no friction and no gap."""
        return self.friction_force == 0.0 and (self.inerter != InerterModel.PLAY or self.play_gap == 0.0)


def with_values(obj, source: str | None = None, **changes):
    """A copy of a parameter object with some fields changed (and validated again)."""
    if source is not None:
        changes["source"] = source
    return replace(obj, **changes)


def as_dict(obj) -> dict:
    d = asdict(obj)
    d.pop("source", None)
    if "inerter" in d:
        d["inerter"] = InerterModel(d["inerter"]).name.lower()
    return d


# --- numeric packing for the compiled kernels --------------------------------------------------
# One table: index names used by kernels.py. Keep in sync only here.
P_M, P_K, P_C, P_F, P_W, P_m, P_k, P_c, P_df, P_s, P_I, P_ki, P_ci, P_eps, P_MODEL = range(15)
N_PARAMS = 15


def pack(base: BaseParams, tmd: TMDParams, omega: float = 0.0) -> np.ndarray:
    """Pack parameters and the excitation frequency omega [rad/s] into the kernels' float array."""
    p = np.zeros(N_PARAMS)
    p[P_M], p[P_K], p[P_C], p[P_F] = base.mass, base.stiffness, base.damping, base.force_amplitude
    p[P_W] = omega
    p[P_m], p[P_k], p[P_c] = tmd.mass, tmd.stiffness, tmd.damping
    p[P_df], p[P_s], p[P_I] = tmd.friction_force, tmd.friction_slope, tmd.inertance
    p[P_ki], p[P_ci], p[P_eps] = tmd.mesh_stiffness, tmd.mesh_damping, tmd.play_gap
    p[P_MODEL] = float(int(tmd.inerter))
    return p


# Paper cases (Sect. 3): m + I = 10 kg.
CASES = {1: dict(mass=9.0, inertance=1.0), 2: dict(mass=5.0, inertance=5.0), 3: dict(mass=1.0, inertance=9.0)}


def paper_case(case: int, **overrides) -> TMDParams:
    """TMD parameters of the paper's Case 1, 2 or 3 (ideal inerter, no damping unless overridden)."""
    if case not in CASES:
        raise ParameterError(f"case must be 1, 2 or 3, got {case!r}")
    kw = dict(CASES[case])
    kw.update(overrides)
    return TMDParams(**kw)


def field_names(cls) -> list[str]:
    return [f.name for f in fields(cls) if f.name != "source"]
