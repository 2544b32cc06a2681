"""The Python co-simulation slave of the LinearTMD FMU (its variables: :mod:`.variables`).

``configure`` builds :class:`~pyfmu_wrapper.models.linear_tmd.LinearTMDParams` from the FMU's values (its
checks, one-line errors) and packs it with the unit's packing; a step is RODAS4 on the model's equations
with the input force (:mod:`.step`), in pieces of at most ``CHUNK``, within the integrator's step budget.
Python-hosted only (no native step).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import MAX_INTEGRATOR_STEPS
from ....fmi.slave import CHUNK, FloatArray, FmuStepError, Slave
from ....solvers.rodas import STAT_STEPS, failure_message
from ..equations import L_M, N_PACKED, linear_tmd_rhs
from ..packing import linear_tmd_pack
from ..params import PARAMETERS, LinearTMDParams
from .step import FMU_MODEL, integrate
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
        rates = np.empty(4)
        linear_tmd_rhs(self.t, self.z, self.p, self._u, rates)
        xdd = rates[1] + inputs[0] / self.p[L_M]
        return [self.z[0], self.z[1], xdd, self.z[2], self.z[3]]

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """RODAS4 over [t, t + h] (long steps in pieces of CHUNK, within a budget of integrator steps)."""
        rtol, a = self.val("rtol"), self.val("atol")
        self._atol[:] = a
        n = 1 if h <= CHUNK else int(np.ceil(h / CHUNK))
        start = int(self.stats[STAT_STEPS])
        hn = self.h
        for k in range(n):
            lo, hi = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
            hn, _, status, tf = integrate(
                self.z, lo, hi, self.p, u, rtol, self._atol, hn, hi - lo, self._empty_t, self._empty_s, 1e-6,
                self.stats, MAX_INTEGRATOR_STEPS,
            )  # fmt: skip
            if status != 0:
                raise FmuStepError(
                    f"doStep from t = {t:.16g} s: "
                    + failure_message(status, FMU_MODEL, tf, self.z, self.p, self._atol, 1e-6, MAX_INTEGRATOR_STEPS)
                )
            if self.stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
                raise FmuStepError(
                    f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} "
                    "integrator steps; use shorter communication steps"
                )
        self.h = hn
