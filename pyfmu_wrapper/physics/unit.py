"""A model as one unit, and the registry of the units.

A :class:`ModelUnit` gathers everything the engines need of one model: its equations as an
:class:`~pyfmu_wrapper.physics.models.OdeModel` (right-hand side, Jacobian, switching functions),
the parameter class of its primary structure (the unit is found by the structure's type), its
declared parameters (:class:`~pyfmu_wrapper.physics.registry.Parameter` rows: names, units, ranges,
docs), the packing of its parameters for the compiled functions, its state layout (length, names,
the states the shooting iterates), its absolute tolerances and the inerter force at a state (the
start of a windowed solve). The registry (:data:`pyfmu_wrapper.models.MODELS`) holds the
units, one registration line each; the monolithic solver and ``run-scenario`` take the unit of a
structure from there and know no model by name.

Conventions every unit keeps (the solvers rely on them): the reported amplitude is max |z[0]| (the
displacement the unit's curves show: the base, the top storey), the TMD's states are z[2:6] =
[y, yd, d, dd] (d: the play chain), the packed array holds the TMD's parameters and the
excitation F cos(w t) at the indices of :mod:`pyfmu_wrapper.physics.params` (``P_*``), so the
TMD equations of :mod:`.kernels` run unchanged on it.
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..errors import InputError
from .effects import Vocabulary
from .modelica_source import ModelicaSource
from .models import OdeModel
from .params import P_F, P_W, TMDParams
from .registry import Parameter
from .tmd import tmd_companion


def tmd_is_linear(structure: Any, tmd: TMDParams) -> bool:
    """A linear structure with the paper's TMD: linear when the TMD is (no friction, play or cubic
    spring): the default of :attr:`ModelUnit.is_linear`."""
    return tmd.is_linear


@dataclass(frozen=True)
class LinearCompanion:
    """Periodic solutions start from the exact steady state of a linear configuration near the model's:
    ``companion(structure, tmd) -> (structure, tmd)`` of that configuration (the solvers take its exact
    frequency response, :func:`~pyfmu_wrapper.solvers.frequency_response.exact_state`)."""

    companion: Callable[[Any, TMDParams], tuple[Any, TMDParams]]


@dataclass(frozen=True)
class SmallForcing:
    """Periodic solutions start from the linearisation about rest (the small-amplitude limit, exact to
    rounding there) and are continued in the force amplitude: the steady state is solved at each
    ``fractions`` of the structure's ``force_amplitude`` in turn, each from the last, the full force last.
    For a model nonlinear in its own way (a pendulum) that has no linear configuration nearby."""

    fractions: tuple[float, ...] = (0.05, 0.2, 0.5)


def same_configuration(structure: Any, tmd: TMDParams) -> tuple[Any, TMDParams]:
    """The companion of a linear model: itself."""
    return structure, tmd


#: the start of a model that takes the paper's TMD: the TMD without friction, gap and cubic spring
PAPER_START = LinearCompanion(tmd_companion)


def no_fmus() -> tuple[Any, ...]:
    """A unit without FMUs: the default of :attr:`ModelUnit.fmus`."""
    return ()


class ModelError(InputError):
    """A structure no registered model takes, or a state that does not fit its model."""


@dataclass(frozen=True)
class ModelUnit:
    """One model (module doc). Every function takes the structure's parameters first."""

    name: str  #: unique, a Python identifier
    ode: OdeModel  #: equations, Jacobian, switching functions, for the integrator
    structure: type  #: the parameter class of the primary structure (BaseParams, FrameParams, ...)
    parameters: tuple[Parameter, ...]  #: the structure's declared parameters
    #: pack(structure, tmd, omega) -> the float array of the compiled functions
    pack: Callable[[Any, TMDParams, float], NDArray[np.float64]]
    #: n_state(structure) -> the length of the state
    n_state: Callable[[Any], int]
    #: atol(structure, tmd, omega, atol_scale) -> absolute tolerance per state
    atol: Callable[[Any, TMDParams, float, float], NDArray[np.float64]]
    #: active(structure, tmd) -> the states the period map's Newton iteration moves
    active: Callable[[Any, TMDParams], list[int]]
    #: inerter_force(z, p) -> the inerter link's force P [N] at state z (packed parameters p)
    inerter_force: Callable[[NDArray[np.float64], NDArray[np.float64]], float]
    description: str = ""
    #: example() -> a structure of this model (the tests run every registered model on it)
    example: Callable[[], Any] | None = None
    #: cosim() -> the unit's co-simulation (a :class:`pyfmu_wrapper.cosim.system.CosimEngine`: its
    #: ``sweep(structure, tmd, omegas, direction=, settings=, progress=, workers=)`` and the rest), a
    #: function of the model's folder that imports it when asked (the FMUs and the master load only
    #: for a co-simulation); None: the model has no co-simulation
    cosim: Callable[[], Any] | None = None
    #: fmus() -> the unit's FMU declarations (``pyfmu_wrapper.fmi.fmumodel.FmuModel``: variable table,
    #: slave class, native functions), a function of the model's folder that imports its FMU code on the
    #: first call (importing a unit stays cheap; physics imports no FMU runtime); default: no FMU
    fmus: Callable[[], tuple[Any, ...]] = no_fmus
    #: the model takes the paper's TMD (``TMDParams``, a scenario's ``tmd:`` block); False: the
    #: structure carries its own absorber, scenario files give no ``tmd:`` block and the engines pass
    #: a detached TMD that the unit does not read
    takes_tmd: bool = True
    #: its classes and cases in the Modelica package (None: it has no Modelica source)
    modelica: ModelicaSource | None = None
    #: the key of the structure's block in a scenario file ("": the unit's name, e.g. ``linear_tmd:``)
    scenario_block: str = ""
    #: a reader of its own for that block, ``reader(rd, node, line) -> structure`` (an
    #: :class:`~pyfmu_wrapper.inputs.reader.Reader` with located errors, the block, its line); None: the
    #: block's keys are the unit's declared parameters (:mod:`pyfmu_wrapper.scenario.structspec`)
    scenario_reader: Callable[[Any, Any, int | None], Any] | None = None
    #: is_linear(structure, tmd) -> the equations are linear in the state (the exact frequency
    #: response applies); default: the structure is linear and the TMD decides (:func:`tmd_is_linear`)
    is_linear: Callable[[Any, TMDParams], bool] = tmd_is_linear
    #: how the solvers start a periodic solution (:class:`LinearCompanion` or :class:`SmallForcing`);
    #: default: the paper's TMD without friction, gap and cubic spring
    start: LinearCompanion | SmallForcing = PAPER_START
    #: the module that defines the unit as its ``UNIT`` (its ``__name__``): a unit is pickled by that
    #: reference, as Python pickles a function (a sweep's worker processes get the unit that way)
    home: str = ""
    #: the effects ``diagnose`` can name on this model (:mod:`pyfmu_wrapper.physics.effects`), declared
    #: once by the unit; None: the model has no diagnosis
    effects: Vocabulary | None = None

    def __reduce__(self) -> tuple[Any, ...]:
        if not self.home:
            raise TypeError(f"model unit {self.name!r} cannot be pickled: it names no home module (home=__name__)")
        return (load_unit, (self.home,))

    def check_state(self, structure: Any, z: NDArray[Any], what: str = "start state") -> NDArray[np.float64]:
        """z as a float array, refused with a one-line :class:`ModelError` unless it has the
        model's length and finite entries."""
        arr = np.asarray(z, dtype=float)
        n = self.n_state(structure)
        if arr.ndim != 1 or arr.shape[0] != n:
            raise ModelError(
                f"{what} of model {self.name!r} must have {n} entries ({', '.join(self.names(structure))}), "
                f"got shape {arr.shape}"
            )
        if not np.all(np.isfinite(arr)):
            raise ModelError(f"{what} of model {self.name!r} must be finite, got {arr.tolist()}")
        return arr

    def names(self, structure: Any) -> tuple[str, ...]:
        """The state's names (the ode's when their number fits, else z0, z1, ...)."""
        n = self.n_state(structure)
        names = tuple(self.ode.state_names)
        return names if len(names) == n else tuple(f"z{i}" for i in range(n))

    def linear_system(
        self, structure: Any, tmd: TMDParams, linearise: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(A, b): dz/dt = A z + b f for the excitation's force f [N], read off the unit's right-hand
        side (exact to rounding for a linear configuration: the rhs is affine in z and in F;
        ``linearise``: A is the complex-step Jacobian at rest, the small-amplitude limit). Kept for the last
        configurations asked (a sweep asks for the same one at every frequency: its start states, the shooting's
        monodromy); the arrays returned are the caller's own."""
        try:
            A, b = _linear_system(self, structure, tmd, bool(linearise))
        except TypeError:  # a structure that is not hashable: computed afresh
            A, b = self._linear_system(structure, tmd, bool(linearise))
        return A.copy(), b.copy()

    def _linear_system(
        self, structure: Any, tmd: TMDParams, linearise: bool
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        n = self.n_state(structure)
        p = self.pack(structure, tmd, 0.0)
        p[P_W] = 0.0
        u = np.zeros(1)
        A = np.empty((n, n))
        if linearise:
            zc, oc = np.zeros(n, dtype=complex), np.empty(n, dtype=complex)
            for j in range(n):
                zc[:] = 0.0
                zc[j] = 1e-30j
                self.ode.rhs(0.0, zc, p, u, oc)
                A[:, j] = oc.imag / 1e-30
        else:
            p[P_F] = 0.0
            fp, fm = np.empty(n), np.empty(n)
            for j in range(n):
                e = np.zeros(n)
                e[j] = 1.0
                self.ode.rhs(0.0, e, p, u, fp)
                self.ode.rhs(0.0, -e, p, u, fm)
                A[:, j] = 0.5 * (fp - fm)
        p[P_F] = 1.0
        b = np.empty(n)
        self.ode.rhs(0.0, np.zeros(n), p, u, b)
        return A, b


@functools.lru_cache(maxsize=32)
def _linear_system(
    unit: ModelUnit, structure: Any, tmd: TMDParams, linearise: bool
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """:meth:`ModelUnit.linear_system`, kept per configuration (the parameters are frozen and hashable)."""
    return unit._linear_system(structure, tmd, linearise)


def load_unit(home: str) -> ModelUnit:
    """The unit a module defines as ``UNIT`` (the other end of :meth:`ModelUnit.__reduce__`)."""
    unit = getattr(importlib.import_module(home), "UNIT", None)
    if not isinstance(unit, ModelUnit):
        raise TypeError(f"{home} defines no model unit UNIT")
    return unit


class Registry:
    """The registered model units, by name and by structure class."""

    def __init__(self) -> None:
        self._units: dict[str, ModelUnit] = {}

    def register(self, unit: ModelUnit) -> ModelUnit:
        if not unit.name.isidentifier():
            raise ValueError(f"a model's name must be a Python identifier, got {unit.name!r}")
        if unit.name in self._units:
            raise ValueError(f"a model named {unit.name!r} is registered already")
        if any(u.structure is unit.structure for u in self._units.values()):
            raise ValueError(f"the structure {unit.structure.__name__} has a model already")
        self._units[unit.name] = unit
        return unit

    def names(self) -> tuple[str, ...]:
        return tuple(self._units)

    def units(self) -> tuple[ModelUnit, ...]:
        return tuple(self._units.values())

    def get(self, name: str) -> ModelUnit:
        try:
            return self._units[name]
        except KeyError:
            raise ModelError(f"no model named {name!r}; registered: {', '.join(self._units)}") from None

    def of(self, structure: Any) -> ModelUnit:
        """The unit whose structure class ``structure`` is an instance of."""
        for unit in self._units.values():
            if isinstance(structure, unit.structure):
                return unit
        known = ", ".join(u.structure.__name__ for u in self._units.values())
        raise ModelError(f"no registered model takes a {type(structure).__name__} (models take: {known})")
