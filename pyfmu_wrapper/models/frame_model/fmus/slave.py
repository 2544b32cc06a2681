"""The Python co-simulation slave of the ShearFrame FMU (its variables: :mod:`.variables`).

The physics is the frame model's (:mod:`pyfmu_wrapper.models.frame_model`): the parameters go
through its packing (:class:`FrameParams` checks them, :func:`frame_pack` packs them), the outputs
and the step are the compiled functions of :mod:`.step` (the storey accelerations of
:func:`~pyfmu_wrapper.models.frame_model.equations.storey_rates`; the exact step of the linear frame
alone, driven by the TMD's two forces), the same functions the native step (:mod:`.native`) calls, so
both step paths are bit-identical. The state has the frame model's layout (the TMD's slots at rest),
for 20 storeys; the first 2 n + 4 entries are used.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.slave import FloatArray, FmuStepError, Slave
from ....physics.params import TMDParams
from ..equations import storey_index
from ..packing import frame_pack
from ..params import FrameParams
from .step import FRAME_U_SIZE, NP_FRAME, NS_MAX, advance_frame, frame_outputs
from .variables import SHEAR_FRAME


class ShearFrameSlave(Slave):
    """A shear frame of ``storeys`` storeys; inputs f_link, f_inerter (the TMD's forces)."""

    spec = SHEAR_FRAME
    n_state = NS_MAX

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.p = np.zeros(NP_FRAME)
        # the input polynomials, then the exact step's cache (.step)
        self._u = np.zeros(FRAME_U_SIZE)

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
        self.z[:] = 0.0
        for i in range(1, n + 1):
            ix = storey_index(i, n)
            self.z[ix], self.z[ix + 1] = self.val(f"x0_{i}"), self.val(f"xd0_{i}")

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        frame_outputs(self.z, self.t, inputs[0], inputs[1], self.p, out)
        return list(out)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The exact step (:func:`.step.advance_frame`), as the native step takes it."""
        if advance_frame(self.z, t, h, self.p, u, self.stats) != 0:
            raise FmuStepError(
                f"doStep of {h:g} s from t = {t:.16g} s: the frame's state is not finite at its end (from "
                f"x_top = {self.z[0]!r} m, xd_top = {self.z[1]!r} m/s; f_link = {u[1]!r} N, f_inerter = {u[4]!r} N)"
            )

    def _native_step(self) -> Any:
        from .native import frame_step

        return frame_step()
