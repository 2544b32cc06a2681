"""FrameSystem's Python co-simulation slave (the Python-hosted build): the frame unit's checks and packing
(:class:`~pyfmu_wrapper.models.frame_model.FrameParams`, :func:`~pyfmu_wrapper.models.frame_model.frame_pack`), and
the step and outputs of :mod:`.system`, the functions the native step (:mod:`.system_native`) calls, so both are
bit-identical."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import FAIL_BUDGET, MAX_INTEGRATOR_STEPS
from ....fmi.slave import FloatArray, FmuStepError, Slave
from ....physics import registry
from ....physics.params import P_s, TMDParams
from ....solvers.rodas import failure_message
from ..equations import F_N, storey_index
from ..packing import frame_pack
from ..params import MAX_STOREYS, FrameParams
from ..tolerances import frame_atol
from .step import NP_FRAME, NS_MAX
from .system import (
    FRAME_MODEL,
    FS_ATOL,
    FS_RTOL,
    advance_frame_system,
    frame_system_outputs,
    to_model,
    write_frame_system,
)
from .system_variables import FRAME_SYSTEM, RENAMED


class FrameSystemSlave(Slave):
    """The frame with its TMD-inerter: the FMU's state (the layout for 20 storeys), no inputs."""

    spec = FRAME_SYSTEM
    n_state = NS_MAX

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.p = np.zeros(NP_FRAME)

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
        values: dict[str, Any] = {}
        for par in registry.fields("tmd"):
            values[par.name] = self.val(RENAMED.get(par.fmu_name, par.fmu_name))
        tmd = TMDParams(**values, source=f"FMU {self.instance_name}")
        p = frame_pack(frame, tmd, self.val("w"))
        self.p[:] = 0.0
        self.p[: p.size] = p
        self.z[:] = 0.0
        for i in range(1, n + 1):
            b = storey_index(i, MAX_STOREYS)
            self.z[b], self.z[b + 1] = self.val(f"x0_{i}"), self.val(f"xd0_{i}")
        self.z[2:6] = [self.val(n_) for n_ in ("y0", "yd0", "d0", "dd0")]

    def _model_state(self, z: NDArray[Any]) -> NDArray[Any]:
        n = int(self.p[F_N])
        zm = np.empty(2 * n + 4, dtype=z.dtype)
        to_model(z, n, zm)
        return zm

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        frame_system_outputs(self._model_state(self.z), self.t, self.p, out)
        return list(out)

    def _write_outputs(self, values: Any) -> None:
        super()._write_outputs(values)
        write_frame_system(self.z, self.t, self.p, self.r, self.i)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The frame's integrator over [t, t + h] (:func:`advance_frame_system`), as the native step takes it."""
        start = self.z.copy()
        hn, status, tf = advance_frame_system(
            self.z, t, h, self.p, u, float(self.r[FS_RTOL]), float(self.r[FS_ATOL]), self.h, self.stats
        )
        if status == 0:
            self.h = hn
            return
        where = self._model_state(self.z)
        self.z[:] = start
        if status == FAIL_BUDGET - 1:
            raise FmuStepError(
                f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} integrator steps; "
                "use shorter communication steps"
            )
        atol = np.empty(where.size)
        frame_atol(self.p, float(self.r[FS_ATOL]), atol)
        band = 1.0 / self.p[P_s] if self.p[P_s] > 0 else 1e-6
        raise FmuStepError(
            f"doStep from t = {t:.16g} s: "
            + failure_message(status, FRAME_MODEL, tf, where, self.p, atol, band, MAX_INTEGRATOR_STEPS)
        )

    def _native_step(self) -> Any:
        from .system_native import frame_system_step

        return frame_system_step()
