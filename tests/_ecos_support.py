"""Test support, not part of the package: the base + TMD pair in another vendor's master, Ecos (pip ``ecospy``, a C++ co-simulation engine
with a fixed-step, zero-order-hold force coupling): one set-up for the tests
(tests/test_fmu_ecos.py) and the accuracy table (benchmarks/accuracy_table.py)."""

from __future__ import annotations

import ctypes
import sys
from pathlib import Path
from typing import Any

from numpy.typing import ArrayLike

from pyfmu_wrapper.models.base_tmd.cosim import CONNECTIONS, fmu_parameters
from pyfmu_wrapper.physics.params import BaseParams, TMDParams


def load_ecospy() -> Any:
    """The ``ecospy`` module, with the ``tbb`` wheel's libtbb.so.12 (which its binary needs) loaded first."""
    tbb = Path(sys.prefix) / "lib" / "libtbb.so.12"
    if tbb.is_file():
        ctypes.CDLL(str(tbb), mode=ctypes.RTLD_GLOBAL)
    import ecospy

    return ecospy


def ecos_simulation(fmus: dict, base: BaseParams, tmd: TMDParams, omega: float, z0: ArrayLike, h: float) -> Any:
    """An initialised Ecos simulation of the pair (``fmus``: "BaseOscillator", "TMDInerter" -> FMU
    path), wired as this project's force coupling (:data:`~.system.CONNECTIONS`), with the
    parameters and start state of :func:`~.system.fmu_parameters`, at the fixed step ``h`` [s].
    The caller steps it and calls ``terminate()`` and ``free()``."""
    ecospy = load_ecospy()
    ss = ecospy.EcosSimulationStructure()
    ss.add_model("base", str(fmus["BaseOscillator"]))
    ss.add_model("tmd", str(fmus["TMDInerter"]))
    for c in CONNECTIONS:
        src, dst = (s.strip().replace(".", "::") for s in c.split("->"))
        ss.make_real_connection(src, dst)
    ss.add_parameter_set(
        "p",
        {
            k.replace(".", "::"): (v if isinstance(v, int) else float(v))
            for k, v in fmu_parameters(base, tmd, omega, z0).items()
        },
    )
    sim = ecospy.EcosSimulation(structure=ss, step_size=h)
    try:
        sim.init(parameter_set="p")
    except BaseException:
        sim.free()
        raise
    return sim
