"""FMI 3.0 instances of the master, behind the interface of :class:`~.instance.Instance` (the same
choke point: fmpy's :class:`fmpy.fmi3.FMU3Slave` and the raw ``fmi3SetFloat64`` /
``fmi3GetFloat64`` / ``fmi3DoStep``), and :func:`open_instance`, which opens an FMU of either version.
"""

from __future__ import annotations

import ctypes
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .instance import DBL, UINT, Instance, MasterError, address_of, pointer_to

if TYPE_CHECKING:
    from fmpy.model_description import ModelDescription

_BOOLP = ctypes.POINTER(ctypes.c_bool)
#: FMI 3.0 prototypes of the lean calls
_PROTOTYPES3 = {
    "fmi3SetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, UINT, ctypes.c_size_t, DBL, ctypes.c_size_t),
    "fmi3GetFloat64": ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, UINT, ctypes.c_size_t, DBL, ctypes.c_size_t),
    "fmi3DoStep": ctypes.CFUNCTYPE(
        ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_bool, _BOOLP, _BOOLP, _BOOLP, DBL
    ),
}


def _raw_function3(slave: Any, name: str) -> Any:
    try:
        sym = getattr(slave.dll, name)
    except AttributeError:
        raise MasterError(f"{slave.instanceName}: the FMU does not export {name}") from None
    return _PROTOTYPES3[name](address_of(sym))


def derivative_name(input_name: str, order: int) -> str:
    """Name of the FMI 3.0 input variable carrying the order-th derivative of an input."""
    return f"der({input_name})" if order == 1 else f"der({input_name},{order})"


class Instance3(Instance):
    """One FMI 3.0 co-simulation instance behind the same interface as :class:`Instance`.

    The compiled loop (:mod:`.cloop`) calls it through its fmi3 adapters (:attr:`der3_vr`: the
    FMI 3.0 variable of each position of the derivative arrays); both paths agree bit for bit."""

    REAL_TYPE = "Float64"

    fmi_version = 3
    LEAN_CALLS = (
        "fmi3SetFloat64",
        "fmi3SetFloat64",
        "fmi3DoStep",
        "fmi3GetFloat64",
        "fmi3GetFMUState",
        "fmi3SetFMUState",
    )

    def __init__(
        self, name: str, path: Path, md: ModelDescription, unzipdir: str
    ) -> None:  # not super().__init__: that one is FMI 2.0
        from fmpy.fmi3 import FMU3Slave

        self.name = name
        self.path = Path(path)
        self.md = md
        self.unzipdir = unzipdir
        cs = md.coSimulation
        if cs is None:
            raise MasterError(f"{name}: {path} is not a co-simulation FMU")
        self.vars = {v.name: v for v in md.modelVariables}
        self.can_state = bool(cs.canGetAndSetFMUstate)
        self.can_dd = _fmi3_provides_dd(unzipdir)
        # input derivatives: der(u), der(u,2) for every continuous Float64 input
        ins = [
            v
            for v in md.modelVariables
            if v.causality == "input"
            and v.type == "Float64"
            and v.variability == "continuous"
            and not v.name.startswith("der(")
        ]
        self.can_interpolate = bool(ins) and all(derivative_name(v.name, k) in self.vars for v in ins for k in (1, 2))
        self.slave = FMU3Slave(
            guid=md.guid, unzipDirectory=unzipdir, modelIdentifier=cs.modelIdentifier, instanceName=name
        )
        self.last_error = ""
        self.slave.instantiate(logMessage=self._log3())
        self._c = self.slave.component
        self._set_real = _raw_function3(self.slave, "fmi3SetFloat64")
        self._get_real = _raw_function3(self.slave, "fmi3GetFloat64")
        self._do_step = _raw_function3(self.slave, "fmi3DoStep")
        self._set_der = None
        self._flags = (ctypes.c_bool * 3)()
        self._last_t = ctypes.c_double()
        self._flag_ptrs = [ctypes.cast(ctypes.byref(self._flags, i), _BOOLP) for i in range(3)]
        self.initialized = False
        self.inputs = []
        self.outputs = []
        self.order = 0
        self.n_orders = 0
        self.rate_orders = 0

    def _log3(self) -> Any:
        from fmpy.fmi3 import printLogMessage

        def logger(env: Any, status: int, category: bytes, message: bytes) -> None:
            if status > 1:
                self.last_error = (message or b"").decode(errors="replace")
            printLogMessage(env, status, category, message)

        self._log_keep = logger
        return logger

    def finalize_ports(self) -> None:
        super().finalize_ports()
        ni = self.n_in
        #: the FMI 3.0 variable of each position of der_vr / der_order / der_val (empty: none)
        self.der3_vr = np.array(
            [self.vars[derivative_name(n, k)].valueReference for k in (1, 2) for n in self.inputs]
            if self.can_interpolate
            else [],
            dtype=np.uint32,
        )
        if self.can_interpolate:
            self.der_vr = self.der3_vr
        # an input set resets its derivatives (FMI 2.0's rule, which the Python path and the
        # numbers rely on): inputs and zero derivatives go in one fmi3SetFloat64
        self.set_vr = np.concatenate([self.in_vr, self.der_vr if self.can_interpolate else []]).astype(np.uint32)
        self.set_val = np.zeros(len(self.set_vr))
        self.n_set = len(self.set_vr)
        self.p_set_vr, self.p_set_val = pointer_to(self.set_vr, UINT), pointer_to(self.set_val, DBL)
        self.p_der_vr = pointer_to(self.der_vr, UINT)
        self.n_in = ni

    def raw_address(self, name: str) -> int:
        raise MasterError(f"{self.name}: an FMI 3.0 instance has no {name} (the compiled loop uses raw3_address)")

    STATE_CALLS = ("fmi3GetFMUState", "fmi3SetFMUState", "fmi3FreeFMUState")

    def raw3_address(self, name: str) -> int:
        """Address of the raw fmi3 function ``name``, for the compiled loop's adapters."""
        return address_of(
            {"fmi3SetFloat64": self._set_real, "fmi3GetFloat64": self._get_real, "fmi3DoStep": self._do_step}[name]
        )

    def set_inputs(self) -> None:
        if self.n_in:
            self.set_val[: self.n_in] = self.in_val
            if self._set_real(self._c, self.p_set_vr, self.n_set, self.p_set_val, self.n_set) > 1:
                raise self.failure("fmi3SetFloat64")

    def set_derivatives(self, n_orders: int) -> None:
        if self.n_in and n_orders and self.can_interpolate:
            n = self.n_in * n_orders
            if self._set_real(self._c, self.p_der_vr, n, self.p_der_val, n) > 1:
                raise self.failure("fmi3SetFloat64")

    def get_outputs(self) -> None:
        if self.n_out and self._get_real(self._c, self.p_out_vr, self.n_out, self.p_out_val, self.n_out) > 1:
            raise self.failure("fmi3GetFloat64")

    def do_step(self, t: float, h: float) -> None:
        f = self._flag_ptrs
        st = self._do_step(self._c, t, h, False, f[0], f[1], f[2], ctypes.byref(self._last_t))
        if st > 1:
            raise self.failure("fmi3DoStep", st, t, h)

    def enter_initialization(self, tol: float | None, t0: float) -> None:
        self.slave.enterInitializationMode(tolerance=tol, startTime=t0)

    def get_state(self) -> Any:
        return self.slave.getFMUState()

    def set_state(self, state: Any) -> None:
        self.slave.setFMUState(state)

    def free_state(self, state: Any) -> None:
        self.slave.freeFMUState(state)

    def set_value(self, name: str, value: float | int | bool) -> None:
        v = self.vars.get(name)
        if v is None:
            raise MasterError(f"{self.name} has no variable {name!r}")
        if v.type in ("Float64", "Float32"):
            getattr(self.slave, f"set{v.type}")([v.valueReference], [float(value)])
        elif v.type == "Boolean":
            self.slave.setBoolean([v.valueReference], [bool(value)])
        elif v.type == "String":
            self.slave.setString([v.valueReference], [str(value)])
        else:  # Int8 ... UInt64, Enumeration (Int64)
            setter = "setInt64" if v.type == "Enumeration" else f"set{v.type}"
            getattr(self.slave, setter)([v.valueReference], [int(value)])

    def _get_reals(self, vrs: list[int]) -> list[float]:
        return self.slave.getFloat64(vrs)

    def _set_reals(self, vrs: list[int], values: list[float]) -> None:
        self.slave.setFloat64(vrs, values)


def _fmi3_provides_dd(unzipdir: str) -> bool:
    """providesDirectionalDerivatives of an FMI 3.0 FMU (fmpy 0.3 reads only FMI 2.0's spelling)."""
    import xml.etree.ElementTree as ET

    cs = ET.parse(Path(unzipdir) / "modelDescription.xml").getroot().find("CoSimulation")
    return cs is not None and cs.get("providesDirectionalDerivatives") in ("true", "1")


def open_instance(name: str, path: Path, md: ModelDescription, unzipdir: str) -> Instance:
    """The instance of an FMU of either FMI version (its model description says which)."""
    if str(md.fmiVersion).startswith("3"):
        return Instance3(name, path, md, unzipdir)
    if not str(md.fmiVersion).startswith("2"):
        raise MasterError(f"{name}: {path} is an FMI {md.fmiVersion} FMU; the master runs FMI 2.0 and 3.0")
    return Instance(name, path, md, unzipdir)
