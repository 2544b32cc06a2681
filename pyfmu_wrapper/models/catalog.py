"""The FMUs of the project, gathered from the registered model units (one place, no list of models).

Every unit of :data:`pyfmu_wrapper.models.MODELS` gives its :class:`~pyfmu_wrapper.fmi.fmumodel.FmuModel`
declarations (:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.fmus`); :data:`FMUS` holds them in registration
order, and the test/support FMU :data:`~pyfmu_wrapper.fmi.trivial.FMU` (the stub's overhead benchmark) last,
which belongs to no model. The builders (:mod:`pyfmu_wrapper.fmubuild`) take declarations as arguments and
never read this list: ``build-fmus``, the docs generator, the tests and the benchmarks pass them from here.
``modelDescription.xml``, the C stub's variable table, the slaves' value buffers, the native build and the
docs all derive from these declarations.
"""

from __future__ import annotations

from collections.abc import Iterable

from ..fmi import trivial
from ..fmi.fmumodel import FmuModel
from ..fmi.varspec import FmuSpec
from ..physics.unit import Registry
from . import MODELS


def gather(models: Registry) -> dict[str, FmuModel]:
    """Model identifier -> declaration: the FMUs every unit of ``models`` gives, in registration order (an
    FMU two units give, e.g. the TMD two structures share, once), then Trivial; two different FMUs of
    one name are refused."""
    out: dict[str, FmuModel] = {}
    for unit in models.units():
        for fmu in unit.fmus():
            if not isinstance(fmu, FmuModel):
                raise TypeError(f"model {unit.name!r}: fmus() gave {fmu!r}, not an FmuModel")
            if fmu.name in out and out[fmu.name] is not fmu:
                raise ValueError(f"two FMUs named {fmu.name!r} (model {unit.name!r} and another model's)")
            out[fmu.name] = fmu
    out[trivial.FMU.name] = trivial.FMU
    return out


#: model identifier -> its declaration: every registered unit's FMUs, then Trivial
FMUS: dict[str, FmuModel] = gather(MODELS)
#: model identifier -> its variable table
SPECS: dict[str, FmuSpec] = {n: f.spec for n, f in FMUS.items()}
#: the FMUs of the first registered unit with FMUs that its co-simulation couples (the paper's pair; its system
#: FMU, TMDSystem, left out): what the tests and benchmarks of the pair build
PROJECT_FMUS: tuple[str, ...] = next(
    (tuple(f.name for f in u.fmus() if not f.system) for u in MODELS.units() if u.fmus()), ()
)
#: what ``build-fmus`` builds when no FMU is named: every model's FMU (the support FMU only on request)
BUILD_FMUS: tuple[str, ...] = tuple(n for n in FMUS if n != trivial.FMU.name)
#: the FMUs with a native variant (``build-fmus --native``)
NATIVE_FMUS: tuple[str, ...] = tuple(n for n, f in FMUS.items() if f.native is not None)


def pick(names: str | Iterable[str]) -> tuple[FmuModel, ...]:
    """The declarations of the FMUs named (one name or several), in the order given; an unknown name is
    refused with the known ones."""
    names = (names,) if isinstance(names, str) else tuple(names)
    unknown = [n for n in names if n not in FMUS]
    if unknown:
        raise ValueError(f"unknown FMU(s) {unknown}; choose from {sorted(FMUS)}")
    return tuple(FMUS[n] for n in names)
