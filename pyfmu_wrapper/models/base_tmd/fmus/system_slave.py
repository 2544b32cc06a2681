"""TMDSystem's Python co-simulation slave (the Python-hosted build): the unit's packing, and the step and
outputs of :mod:`.system`, the functions the native step (:mod:`.system_native`) calls, so both are bit-identical."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS
from ....fmi.slave import FloatArray, FmuStepError, Slave
from ....physics.params import BaseParams, P_s, TMDParams, pack
from ....solvers.rodas import failure_message
from .system import NSTATE, S_ATOL, S_RTOL, SYSTEM_MODEL, advance_system, system_locals, system_outputs
from .variables import TMD_SYSTEM


class TMDSystemSlave(Slave):
    """The base with its TMD-inerter: state [x, xd, y, yd, d, dd], no inputs."""

    spec = TMD_SYSTEM
    n_state = NSTATE

    def configure(self) -> None:
        base = BaseParams(**self._registry_values("base"), source=f"FMU {self.instance_name}")
        tmd = TMDParams(**self._registry_values("tmd"), source=f"FMU {self.instance_name}")
        self.p[:] = pack(base, tmd, self.val("w"))
        self.z[:] = [self.val(n) for n in ("x0", "xd0", "y0", "yd0", "d0", "dd0")]

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        system_outputs(self.z, self.t, self.p, out)
        return list(out)

    def _write_outputs(self, values: Any) -> None:
        super()._write_outputs(values)
        system_locals(self.z, self.t, self.p, self.r)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The coupled integrator over [t, t + h] (:func:`advance_system`), as the native step takes it."""
        start = self.z.copy()
        hn, status, tf = advance_system(
            self.z, t, h, self.p, u, float(self.r[S_RTOL]), float(self.r[S_ATOL]), self._atol, self.h, self.stats
        )
        if status == 0:
            self.h = hn
            return
        band = 1.0 / self.p[P_s] if self.p[P_s] > 0 else 1e-6
        where = self.z.copy()
        self.z[:] = start
        if status == FAIL_BUDGET - 1:
            raise FmuStepError(
                f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} integrator steps; "
                "use shorter communication steps"
            )
        raise FmuStepError(
            f"doStep from t = {t:.16g} s: "
            + failure_message(status, SYSTEM_MODEL, tf, where, self.p, self._atol, band, MAX_INTEGRATOR_STEPS)
        )

    def _native_step(self) -> Any:
        from .system_native import system_step

        return system_step()
