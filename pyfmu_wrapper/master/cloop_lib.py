"""The C side of the compiled stepping loop (:mod:`.cloop`): ``cloop.c`` compiled with the system C
compiler (``$CC``, default gcc) at first use into ``__pycache__/cloop-<hash>.so`` beside this file (or
the user's cache directory when that is not writable), the hash covering the source and the flags;
the library loaded with ctypes; and the ctypes mirrors of its structures (``cl_inst``, ``cl_ctx``,
``cl_fmi3``) and return codes.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from .instance import MasterError

if TYPE_CHECKING:
    from ctypes import CDLL

HERE = Path(__file__).resolve().parent
SOURCE = HERE / "cloop.c"
FLAGS = ("-O2", "-std=gnu11", "-fPIC", "-shared", "-ffp-contract=off", "-fno-fast-math", "-Wall")

_i64, _dbl, _vp = ctypes.c_int64, ctypes.c_double, ctypes.c_void_p


class Inst(ctypes.Structure):
    """cl_inst of cloop.c: one FMU instance, its fmi2 function pointers and the master's buffers."""

    _fields_ = [
        ("comp", _vp),
        ("set_real", _vp),
        ("get_real", _vp),
        ("set_der", _vp),
        ("do_step", _vp),
        ("n_in", _i64),
        ("n_out", _i64),
        ("in_vr", _vp),
        ("out_vr", _vp),
        ("der_vr", _vp),
        ("der_order", _vp),
        ("in_val", _vp),
        ("out_val", _vp),
        ("der_val", _vp),
        ("sig_in", _vp),
        ("sig_out", _vp),
        ("n_orders", _i64),
        ("rate_orders", _i64),
        ("n_rate", _i64),
        ("any_int", _i64),
        ("phase", _i64),
        ("rate_pos", _vp),
        ("rate_src", _vp),
        ("rate_int", _vp),
        ("rate_gain", _vp),
        ("rate_prev", _vp),
        ("slope", _vp),
        ("rate_ready", _i64),
        ("time_in", _dbl),
        ("calls", _i64),
        ("get_state", _vp),
        ("set_state", _vp),
        ("free_state", _vp),
        ("fmu_state", _vp),
    ]


class Ctx(ctypes.Structure):
    """cl_ctx of cloop.c: the scheme, the step, the signal buffers and the loop's status."""

    _fields_ = [
        ("n_inst", _i64),
        ("nsig", _i64),
        ("scheme", _i64),
        ("order", _i64),
        ("timing", _i64),
        ("gs_order", _vp),
        ("t", _dbl),
        ("h", _dbl),
        ("h_prev", _dbl),
        ("half_h", _dbl),
        ("hh2", _dbl),
        ("h3", _dbl),
        ("y", _vp),
        ("y0", _vp),
        ("d1", _vp),
        ("d2", _vp),
        ("pred", _vp),
        ("ynew", _vp),
        ("stepped", _vp),
        ("hist_y", _vp),
        ("hist_t", _vp),
        ("hist_n", _i64),
        ("n_w", _i64),
        ("max_w", _i64),
        ("w_key", _vp),
        ("w_val", _vp),
        ("steps", _i64),
        ("steps_done", _i64),
        ("need_k", _i64),
        ("need_x0", _dbl),
        ("need_x1", _dbl),
        ("err_inst", _i64),
        ("err_func", _i64),
        ("err_status", _i64),
        ("loop_time", _dbl),
        ("startup_iters", _i64),
        ("probe", _i64),
        ("ysave", _vp),
        ("yit", _vp),
    ]


class Fmi3(ctypes.Structure):
    """cl_fmi3 of cloop.c: an FMI 3.0 instance behind the loop's fmi2 signatures."""

    _fields_ = [
        ("inst", _vp),
        ("set64", _vp),
        ("get64", _vp),
        ("step", _vp),
        ("n_der", _i64),
        ("der_vr", _vp),
        ("zeros", _vp),
        ("getst", _vp),
        ("setst", _vp),
        ("freest", _vp),
    ]


DONE, NEED_WEIGHTS, FMU_ERROR = 0, 1, 2
SCHEME_CODE = {"jacobi": 0, "rate": 1, "gauss-seidel": 2}
_lib = None


def _cache_dirs() -> Iterator[Path]:
    yield HERE / "__pycache__"
    yield Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "pyfmu_wrapper"


def library_path() -> Path:
    """Path of the compiled loop, building it if missing (keyed by a hash of source and flags)."""
    cc = os.environ.get("CC", "gcc")
    src = SOURCE.read_bytes()
    key = hashlib.sha256(src + " ".join((cc,) + FLAGS).encode()).hexdigest()[:16]
    name = f"cloop-{key}.so"
    for d in _cache_dirs():
        if (d / name).exists():
            return d / name
    if shutil.which(cc) is None:
        raise MasterError(
            f"the compiled stepping loop needs a C compiler: {cc!r} not found (set $CC, or "
            "use Master(..., compiled=False))"
        )
    last = None
    for d in _cache_dirs():
        try:
            d.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(prefix="cloop-", suffix=".so", dir=d)
            os.close(fd)
        except OSError as e:
            last = e
            continue
        r = subprocess.run([cc, *FLAGS, str(SOURCE), "-o", tmp], capture_output=True, text=True)
        if r.returncode != 0:
            os.unlink(tmp)
            raise MasterError(f"compiling {SOURCE} failed:\n{r.stderr}")
        os.replace(tmp, d / name)  # atomic: concurrent builders write the same bytes
        return d / name
    raise MasterError(f"no writable cache directory for the compiled loop ({last})")


def library() -> CDLL:
    """The compiled loop, loaded once per process with its functions' signatures."""
    global _lib
    if _lib is None:
        lib = ctypes.CDLL(str(library_path()))
        lib.cl_run.argtypes = [ctypes.POINTER(Ctx), ctypes.POINTER(Inst), _i64, _vp, _vp]
        lib.cl_run.restype = ctypes.c_int
        lib.cl_plain.argtypes = [ctypes.POINTER(Inst), _i64, _dbl, _dbl, _i64]
        lib.cl_plain.restype = ctypes.c_int
        for name in (
            "cl_f3_set_real",
            "cl_f3_set_der",
            "cl_f3_get_real",
            "cl_f3_do_step",
            "cl_f3_get_state",
            "cl_f3_set_state",
            "cl_f3_free_state",
        ):
            getattr(lib, name).restype = ctypes.c_int
        _lib = lib
    return _lib
