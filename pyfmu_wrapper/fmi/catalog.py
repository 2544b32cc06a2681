"""The FMUs of the project, gathered from the registered model units (one place, no list of models).

Every unit of :data:`pyfmu_wrapper.models.MODELS` names the modules declaring its FMUs
(:attr:`~pyfmu_wrapper.physics.unit.ModelUnit.fmus`); :data:`FMUS` holds their
:class:`~.fmumodel.FmuModel` declarations in registration order, and the test/support FMU
:data:`~.trivial.TRIVIAL` (the stub's overhead benchmark) last, which belongs to no model.
``modelDescription.xml``, the C stub's variable table, the slaves' value buffers, the native build and
the docs all derive from these declarations.
"""

from __future__ import annotations

from ..models import MODELS
from ..physics.unit import Registry
from . import trivial
from .fmumodel import FmuModel, declared
from .varspec import FmuSpec


def gather(models: Registry) -> dict[str, FmuModel]:
    """Model identifier -> declaration: the FMUs every unit of ``models`` names, in registration order (an
    FMU two units name, e.g. the TMD two structures share, once), then Trivial; two different FMUs of
    one name are refused."""
    out: dict[str, FmuModel] = {}
    for unit in models.units():
        for module in unit.fmus:
            fmu = declared(module)
            if fmu.name in out and out[fmu.name] is not fmu:
                raise ValueError(f"two FMUs named {fmu.name!r} ({module} and another model's)")
            out[fmu.name] = fmu
    out[trivial.FMU.name] = trivial.FMU
    return out


#: model identifier -> its declaration: every registered unit's FMUs, then Trivial
FMUS: dict[str, FmuModel] = gather(MODELS)
#: model identifier -> its variable table
SPECS: dict[str, FmuSpec] = {n: f.spec for n, f in FMUS.items()}
#: the FMUs the library's builders make when no FMU is named: those of the first registered unit with FMUs
#: (the paper's pair, its co-simulation)
PROJECT_FMUS: tuple[str, ...] = next((tuple(declared(m).name for m in u.fmus) for u in MODELS.units() if u.fmus), ())
#: what ``build-fmus`` builds when no FMU is named: every model's FMU (the support FMU only on request)
BUILD_FMUS: tuple[str, ...] = tuple(n for n in FMUS if n != trivial.FMU.name)
#: the FMUs with a native variant (``build-fmus --native``)
NATIVE_FMUS: tuple[str, ...] = tuple(n for n, f in FMUS.items() if f.native is not None)
