"""The Python co-simulation slaves of the paper's two FMUs (the machinery they share: :mod:`pyfmu_wrapper.fmi.slave`).

Each slave configures its subsystem from the FMU's parameters, gives its outputs and takes a step;
the physics is not restated here: parameters go through :func:`~pyfmu_wrapper.physics.params.pack`,
the outputs are the compiled functions of :mod:`.outputs` and a step is the subsystem's step of
:mod:`.integrators` (the TMD: RODAS4 on its kernels; the base: exact), the same functions the native
step (:mod:`.native`) calls, so both step paths are bit-identical.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ....fmi.contract import MAX_INTEGRATOR_STEPS
from ....fmi.slave import CHUNK, FloatArray, FmuStepError, Slave
from ....physics import kernels as kn
from ....physics import registry
from ....physics.params import BaseParams, P_s, ParameterError, TMDParams, pack
from ....solvers.rodas import STAT_STEPS, failure_message
from .integrators import BASE_U_SIZE, TMD_MODEL, advance_base, fill_atol, integrate_tmd
from .outputs import base_outputs, tmd_outputs
from .variables import BASE_OSCILLATOR, TMD_INERTER


class BaseOscillatorSlave(Slave):
    """Base oscillator alone: state [x, xd], input f_link (force of the TMD links, in -x)."""

    spec = BASE_OSCILLATOR
    n_state = 2

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._u = np.zeros(BASE_U_SIZE)  # the input polynomial, then the exact step's cache (.integrators)

    def configure(self) -> None:
        base = BaseParams(**self._registry_values("base"), source=f"FMU {self.instance_name}")
        self.p[:] = pack(base, TMDParams(), self.val(registry.get("base", "omega").fmu_name))
        self.z[:] = (self.val("x0"), self.val("xd0"))

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        base_outputs(self.z, self.t, inputs[0], self.p, out)
        return list(out)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """The exact step (.integrators.advance_base), as the native step takes it."""
        x0, xd0 = float(self.z[0]), float(self.z[1])
        if advance_base(self.z, t, h, self.p, u, self.stats) != 0:
            raise FmuStepError(
                f"doStep of {h:g} s from t = {t:.16g} s: the base state is not finite at its end "
                f"(from x = {x0!r} m, xd = {xd0!r} m/s; f_link = {u[1]!r} N, d/dt {u[2]!r} N/s, d2/dt2 {u[3]!r} N/s2)"
            )

    def _native_step(self) -> Any:
        from .native import base_step

        return base_step()


class TMDInerterSlave(Slave):
    """TMD subsystem alone: state [y, yd, d, dd], inputs x, xd, xdd of the base."""

    spec = TMD_INERTER
    n_state = 4

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._u = np.zeros(kn.U_KAPPA + 1)  # the input polynomials, then the mounting compliance

    def configure(self) -> None:
        tmd = TMDParams(**self._registry_values("tmd"), source=f"FMU {self.instance_name}")
        kappa = self.val("base_compliance")
        if not (math.isfinite(kappa) and kappa >= 0.0):
            raise ParameterError(
                f"FMU {self.instance_name}: base_compliance = {kappa!r} 1/kg: must be finite "
                "and >= 0 (1/M of the body the TMD is mounted on, 0: off)"
            )
        self.p[:] = pack(BaseParams(), tmd, 0.0)
        self._u[kn.U_KAPPA] = kappa
        self.z[:] = (self.val("y0"), self.val("yd0"), self.val("d0"), self.val("dd0"))

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        out = np.empty(len(self._outputs), dtype=np.result_type(inputs, np.float64))
        tmd_outputs(self.z, inputs[0], inputs[1], inputs[2], self._u[kn.U_KAPPA], self.p, out)
        return list(out)

    def advance(self, t: float, h: float, u: FloatArray) -> None:
        """RODAS4 over [t, t + h] (long steps in pieces of CHUNK, within a budget of integrator steps)."""
        tol_vr = getattr(self, "_tol_vr", None)
        if tol_vr is None:  # value references of rtol/atol, resolved once
            tol_vr = self._tol_vr = (self.spec.by_name("rtol").vr, self.spec.by_name("atol").vr)
        rtol = float(self.r[tol_vr[0]])
        fill_atol(kn.SYS_TMD, float(self.r[tol_vr[1]]), self.p, self._atol)
        band = 1.0 / self.p[P_s] if self.p[P_s] > 0 else 1e-6
        n = 1 if h <= CHUNK else int(np.ceil(h / CHUNK))  # long steps in pieces, within a budget of steps
        start = int(self.stats[STAT_STEPS])
        hn = self.h
        for k in range(n):
            a, b = (t, t + h) if n == 1 else (t + h * k / n, (t + h if k == n - 1 else t + h * (k + 1) / n))
            hn, _, status, tf = integrate_tmd(
                self.z,
                a,
                b,
                self.p,
                u,
                rtol,
                self._atol,
                hn,
                h if n == 1 else b - a,
                self._empty_t,
                self._empty_s,
                band,
                self.stats,
                MAX_INTEGRATOR_STEPS,
            )
            if status != 0:
                raise FmuStepError(
                    f"doStep from t = {t:.16g} s: "
                    + failure_message(status, TMD_MODEL, tf, self.z, self.p, self._atol, band, MAX_INTEGRATOR_STEPS)
                )
            if self.stats[STAT_STEPS] - start > MAX_INTEGRATOR_STEPS:
                raise FmuStepError(
                    f"doStep of {h:g} s from t = {t:.16g} needs more than {MAX_INTEGRATOR_STEPS} "
                    "integrator steps; use shorter communication steps"
                )
        self.h = hn

    def _native_step(self) -> Any:
        from .native import tmd_step

        return tmd_step()
