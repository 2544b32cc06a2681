"""The Python co-simulation slave of the PendulumTMD FMU (its variables: :mod:`.variables`).

``configure`` builds :class:`~pyfmu_wrapper.models.pendulum_tmd.PendulumTMDParams` from the FMU's values of
the pendulum's rows (its checks, one-line errors; the main mass's rows keep their defaults: the FMU does not
read them) and packs it with the unit's packing; the outputs and the step are the compiled functions of
:mod:`.step`, the same ones the native step (:mod:`.native`) calls, so both step paths are bit-identical.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS
from ....fmi.slave import FloatArray, FmuStepError, Slave
from ....physics.params import ParameterError
from ....solvers.rodas import failure_message
from ..equations import N_PACKED
from ..packing import pendulum_tmd_pack
from ..params import PendulumTMDParams
from .step import BAND, FMU_MODEL, U_KAPPA, U_SIZE, advance_pendulum, fill_atol, pendulum_outputs
from .variables import PENDULUM_TMD_FMU, ROWS


class PendulumTMDSlave(Slave):
    """The pendulum on its pivot: state [x, xd, th, thd] (:mod:`.step`), inputs x, xd, xdd of the body it
    hangs on."""

    spec = PENDULUM_TMD_FMU
    n_state = 4

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.p = np.zeros(N_PACKED)
        self._u = np.zeros(U_SIZE)  # the input polynomials, then the compliance

    def configure(self) -> None:
        values = {p.name: self.val(p.fmu_name) for p in ROWS}
        s = PendulumTMDParams(**values, source=f"FMU {self.instance_name}")
        kappa = self.val("base_compliance")
        if not (math.isfinite(kappa) and kappa >= 0.0):
            raise ParameterError(
                f"FMU {self.instance_name}: base_compliance = {kappa!r} 1/kg: must be finite "
                "and >= 0 (1/M of the body the TMD is mounted on, 0: off)"
            )
        self.p[:] = pendulum_tmd_pack(s, None, 0.0)
        self._u[U_KAPPA] = kappa
        self.z[:] = (self.val("x"), self.val("xd"), self.val("th0"), self.val("thd0"))

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        pendulum_outputs(self.z, inputs[2], self._u[U_KAPPA], self.p, out)
        return list(out)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The step of :func:`.step.advance_pendulum`, as the native step takes it."""
        fill_atol(self.val("atol"), self.p, self._atol)
        code, hn, tf = advance_pendulum(self.z, t, h, self.p, u, self.val("rtol"), self._atol, self.h, self.stats)
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
        from .native import pendulum_step

        return pendulum_step()
