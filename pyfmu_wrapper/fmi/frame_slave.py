"""The Python co-simulation slave of the ShearFrame FMU (its variables: :mod:`.frame_variables`).

The physics is the frame model's (:mod:`pyfmu_wrapper.physics.frame_model`): the parameters go
through its packing, the outputs are its storey accelerations (:func:`storey_rates`) and a step is
RODAS4 on :func:`storeys_rhs`, the frame alone driven by the TMD's two forces. The state has the
frame model's layout (the TMD's slots at rest), for 20 storeys; the first 2 n + 4 entries are used.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..physics.frame_model import STOREYS, FrameParams, frame_pack, storey_index
from ..physics.frame_model.equations import F_N, F_TMD, F_TO, storey_rates
from ..physics.frame_model.params import MAX_STOREYS
from ..physics.kernels import input_value
from ..physics.params import N_PARAMS, TMDParams
from ..solvers.rodas import STAT_STEPS, failure_message, make_integrator
from .contract import MAX_INTEGRATOR_STEPS
from .frame_variables import SHEAR_FRAME
from .slave import CHUNK, FloatArray, FmuStepError, Slave

_N_MAX = 2 * MAX_STOREYS + 4


class ShearFrameSlave(Slave):
    """A shear frame of ``storeys`` storeys; inputs f_link, f_inerter (the TMD's forces)."""

    spec = SHEAR_FRAME
    n_state = _N_MAX

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.p = np.zeros(N_PARAMS + 4 + 3 * MAX_STOREYS)
        self._n = 1
        self._integrate = make_integrator(STOREYS)

    def configure(self) -> None:
        n = int(self.val("storeys"))
        per = {k: tuple(self.val(f"{k}{i}") for i in range(1, n + 1)) for k in ("m", "k", "c")}
        frame = FrameParams(
            per["m"],
            per["k"],
            per["c"],
            force_amplitude=self.val("F"),
            force_storey=int(self.val("force_storey")),
            tmd_storey=int(self.val("tmd_storey")),
            inerter_to=int(self.val("inerter_to")),
            source=f"FMU {self.instance_name}",
        )
        p = frame_pack(frame, TMDParams(), self.val("w"))
        self.p[:] = 0.0
        self.p[: p.size] = p
        self._n = n
        self.z[:] = 0.0
        for i in range(1, n + 1):
            ix = storey_index(i, n)
            self.z[ix], self.z[ix + 1] = self.val(f"x0_{i}"), self.val(f"xd0_{i}")

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        n = self._n
        m = 2 * n + 4
        rates = np.empty(m, dtype=np.result_type(inputs, np.float64))
        z = self.z[:m].astype(rates.dtype)
        f, P = inputs[0], inputs[1]
        xdd = storey_rates(self.t, z, self.p, f, f - P, 0.0, rates)
        free = storey_rates(self.t, z, self.p, 0.0 * f, 0.0 * f, 0.0, rates)
        sx = storey_index(int(self.p[F_TMD]), n)
        ground = int(self.p[F_TO]) <= 0
        return [z[0], z[1], z[sx], z[sx + 1], 0.0 * xdd if ground else xdd, 0.0 * free if ground else free]

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """RODAS4 over [t, t + h] on the frame alone (long steps in pieces of CHUNK)."""
        m = 2 * int(self.p[F_N]) + 4
        z, atol = self.z[:m], self._atol[:m]
        atol[:] = self.val("atol")
        rtol = self.val("rtol")
        steps = int(np.ceil(h / CHUNK)) if h > CHUNK else 1
        start = int(self.stats[STAT_STEPS])
        hn = self.h
        for k in range(steps):
            a, b = t + h * k / steps, (t + h if k == steps - 1 else t + h * (k + 1) / steps)
            hn, _, status, tf = self._integrate(
                z,
                a,
                b,
                self.p,
                u,
                rtol,
                atol,
                hn,
                b - a,
                self._empty_t,
                self._empty_s[:, :m],
                1e-6,
                self.stats,
                MAX_INTEGRATOR_STEPS,
            )
            if status != 0:
                raise FmuStepError(
                    f"doStep from t = {t:.16g} s: "
                    + failure_message(status, STOREYS, tf, z, self.p, atol, 1e-6, MAX_INTEGRATOR_STEPS)
                )
            if self.stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
                raise FmuStepError(
                    f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} integrator steps"
                )
        self.h = hn

    def inputs_at(self, t: float) -> tuple[float, float]:
        """The input polynomials' values at t (f_link, f_inerter)."""
        return float(input_value(self._u, 0, t)), float(input_value(self._u, 1, t))
