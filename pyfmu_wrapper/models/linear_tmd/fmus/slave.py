"""The Python co-simulation slave of the LinearTMD FMU (its variables: :mod:`.variables`).

``configure`` builds :class:`~pyfmu_wrapper.models.linear_tmd.LinearTMDParams` from the FMU's values (its
checks, one-line errors) and packs it with the unit's packing; the outputs and the step (RODAS4 on the
model's equations with the input force, in pieces of at most ``CHUNK``, within the integrator's step
budget) are the compiled functions of :mod:`.step`, the same ones the native step (:mod:`.native`) calls,
so both step paths are bit-identical.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS
from ....fmi.slave import FloatArray, FmuStepError, Slave
from ....solvers.rodas import failure_message
from ..equations import N_PACKED
from ..packing import linear_tmd_pack
from ..params import PARAMETERS, LinearTMDParams
from .step import BAND, FMU_MODEL, advance_linear, linear_outputs
from .variables import LINEAR_TMD_FMU


class LinearTMDSlave(Slave):
    """The main mass and its absorber: state [x, xd, y, yd], input f_ext."""

    spec = LINEAR_TMD_FMU
    n_state = 4

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.p = np.zeros(N_PACKED)

    def configure(self) -> None:
        values = {p.name: self.val(p.fmu_name) for p in PARAMETERS}
        s = LinearTMDParams(**values, source=f"FMU {self.instance_name}")
        self.p[:] = linear_tmd_pack(s, None, self.val("w"))
        self.z[:] = (self.val("x0"), self.val("xd0"), self.val("y0"), self.val("yd0"))

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        linear_outputs(self.z, self.t, inputs[0], self.p, self._u, out)
        return list(out)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The step of :func:`.step.advance_linear`, as the native step takes it."""
        self._atol[:] = self.val("atol")
        code, hn, tf = advance_linear(self.z, t, h, self.p, u, self.val("rtol"), self._atol, self.h, self.stats)
        if code == FAIL_BUDGET:
            raise FmuStepError(
                f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} "
                "integrator steps; use shorter communication steps"
            )
        if code != 0:
            raise FmuStepError(
                f"doStep from t = {t:.16g} s: "
                + failure_message(code - 1, FMU_MODEL, tf, self.z, self.p, self._atol, BAND, MAX_INTEGRATOR_STEPS)
            )
        self.h = hn

    def _native_step(self) -> Any:
        from .native import linear_step

        return linear_step()
