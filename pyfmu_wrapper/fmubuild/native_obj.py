"""Object code of the compiled model functions, per target (the native FMUs).

The numba source of truth (each FMU's declared :class:`~pyfmu_wrapper.fmi.fmumodel.NativeFmu`, given by the
builder: the step cfuncs, which call the same compiled integrators and outputs as the Python slaves) is compiled by numba to LLVM IR; llvmlite turns that IR into an
object file for each target triple (:data:`TRIPLES`: x86_64 Linux, x86_64 Windows and aarch64 Linux, the FMI
platforms linux64 / win64 / aarch64-linux and x86_64-linux / x86_64-windows / aarch64-linux). The object is linked with C: what numba's
generated code calls outside itself is either the C library's maths (:data:`LIBM`) or the small run
time of ``fmu/src/native/native_rt.c`` (:data:`RUNTIME_SYMBOLS`: NRT allocation, and the exception
path of a cfunc wrapper, which does nothing without Python). No model code is written in C.

numba's on-disk cache holds machine code without its IR, so the IR is produced in a fresh interpreter
with the cache neither read nor written (:func:`model_ir`). The code is generated for a generic
x86-64 CPU (no host-specific instructions: the binary runs on any x86-64) and a generic ARMv8-A one.
numba optimises the IR for the build host (x86-64): its target triple and data layout are replaced by each
target's, and the one x86 intrinsic its reference counting leaves in the IR (``llvm.x86.atomic.*.cc``, an
atomic update whose result is a flag) is rewritten for another target as the plain ``atomicrmw`` it stands
for (:func:`portable_ir`); any other target-specific intrinsic is refused. numba emits no contracted
(fused) floating-point operations, so the object computes the bits the JIT-compiled function computes,
as long as the maths functions of the C library agree (glibc on Linux: the same library the JIT calls).
"""

from __future__ import annotations

import functools
import json
import os
import re
import subprocess
import sys
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from ..fmi.fmumodel import dotted_name
from .buildinfo import BuildError

if TYPE_CHECKING:
    from ..fmi.fmumodel import FmuModel

#: FMI 2.0 platform folder -> LLVM target triple (FMI 2.0.4: platforms it does not name use FMI 3.0's tuple)
TRIPLES = {
    "linux64": "x86_64-unknown-linux-gnu",
    "win64": "x86_64-w64-windows-gnu",
    "aarch64-linux": "aarch64-unknown-linux-gnu",
}
#: FMI 3.0 platform tuple of each FMI 2.0 platform folder
PLATFORM3 = {"linux64": "x86_64-linux", "win64": "x86_64-windows", "aarch64-linux": "aarch64-linux"}
#: the CPU the code of each platform is generated for: the baseline of its architecture
CPU = {"linux64": "x86-64", "win64": "x86-64", "aarch64-linux": "generic"}
#: the name the step has in the object file (the C side calls it by this name)
STEP_SYMBOL = "pyfmu_model_step"
#: the C names of a model's other functions (:mod:`pyfmu_wrapper.fmi.native_model`)
ENTRIES = {
    "configure": "pyfmu_model_configure",
    "outputs": "pyfmu_model_outputs",
    "derivative": "pyfmu_model_derivative",
    "sensitivity": "pyfmu_model_sensitivity",
    # Model Exchange (a model that declares states; fmi/native_model.py's ME_FUNCTIONS, fmu/src/native/native_me.c)
    "me_derivatives": "pyfmu_model_me_derivatives",
    "me_indicators": "pyfmu_model_me_indicators",
    "me_nominals": "pyfmu_model_me_nominals",
    "me_jacobian": "pyfmu_model_me_jacobian",
}
#: symbols defined by fmu/src/native/native_rt.c
RUNTIME_SYMBOLS = frozenset(
    {
        "NRT_Free",
        "NRT_MemInfo_alloc_aligned",
        "NRT_MemInfo_call_dtor",
        "PyBytes_FromStringAndSize",
        "PyErr_Clear",
        "PyErr_SetNone",
        "PyErr_SetString",
        "PyErr_WriteUnraisable",
        "PyUnicode_FromString",
        "Py_DecRef",
        "numba_do_raise",
        "numba_gil_ensure",
        "numba_gil_release",
        "numba_runtime_build_excinfo_struct",
        "numba_unpickle",
        "PyExc_RuntimeError",
        "PyExc_StopIteration",
        "PyExc_SystemError",
    }
)
#: maths functions of the C library the code may call (libm on Linux, the C run time on Windows): the
#: double-precision functions of C99's <math.h> that both glibc and mingw-w64 provide (each linked and called
#: on both by tests/test_native_objects.py), not the ones some model happened to need: numba's code calls
#: whichever its numpy and math functions lower to (the complex sine and cosine of a model's complex-step
#: Jacobian: cosh and sinh)
LIBM = frozenset(
    {
        *("acos", "asin", "atan", "atan2", "cos", "sin", "tan", "cosh", "sinh", "tanh", "acosh", "asinh", "atanh"),
        *("exp", "exp2", "expm1", "log", "log10", "log1p", "log2", "pow", "sqrt", "cbrt", "hypot"),
        *("ceil", "floor", "fabs", "fmod", "round", "trunc", "copysign", "fmin", "fmax"),
        *("erf", "erfc", "lgamma", "tgamma"),
    }
)
RUNTIME_C = Path(__file__).resolve().parents[2] / "fmu" / "src" / "native" / "native_rt.c"

# Run in a fresh interpreter: numba's cache off (it keeps no IR), each model's declared factories (argv[2]:
# model -> [step, functions], "module:qualified.name" derived from the factories by dotted_name) compiled,
# their IR and symbols written as JSON to argv[1].
_IR_SCRIPT = """
import json, sys
from numba.core import caching
caching.Cache.load_overload = lambda self, *a, **k: None
caching.Cache.save_overload = lambda self, *a, **k: None
from pyfmu_wrapper.fmi.fmumodel import resolve
entries = json.loads(sys.argv[3])
out = {}
for model, (step, functions) in json.loads(sys.argv[2]).items():
    f = resolve(step)()
    out[model] = {sys.argv[4]: [f.native_name, f._library.get_llvm_str()]}
    for key, fn in resolve(functions)().items():
        out[model][entries[key]] = [fn.native_name, fn._library.get_llvm_str()]
with open(sys.argv[1], "w") as fh:
    json.dump(out, fh)
"""


def native_models(fmus: Iterable[FmuModel]) -> dict[str, tuple[str, str]]:
    """FMU -> the names of its step factory and its functions factory (derived from the factories, for
    the subprocess that compiles them), of the declarations given; one without native functions is refused."""
    out = {}
    for f in fmus:
        if f.native is None:
            raise BuildError(f"no compiled step for {f.name}: its declaration holds no native functions")
        out[f.name] = (dotted_name(f.native.step), dotted_name(f.native.functions))
    return out


def model_ir(fmus: Iterable[FmuModel]) -> dict[str, dict[str, tuple[str, str]]]:
    """model -> {C name: (symbol of the cfunc, the LLVM IR of its library)} of the native FMUs given,
    compiled afresh (once per process and set of factories: the sources do not change under a running build)."""
    return _model_ir(tuple(native_models(fmus).items()))


@functools.cache
def _model_ir(models: tuple[tuple[str, tuple[str, str]], ...]) -> dict[str, dict[str, tuple[str, str]]]:
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ir.json"
        env = dict(os.environ, NUMBA_CACHE_DIR=tmp)
        args = [str(out), json.dumps(dict(models)), json.dumps(ENTRIES), STEP_SYMBOL]
        r = subprocess.run([sys.executable, "-c", _IR_SCRIPT, *args], capture_output=True, text=True, env=env)
        if r.returncode != 0:
            raise BuildError(f"compiling the model functions to LLVM IR failed:\n{r.stderr[-4000:]}")
        data = json.loads(out.read_text())
    return {m: {name: (sym, ir) for name, (sym, ir) in fns.items()} for m, fns in data.items()}


def external_symbols(ir: str) -> set[str]:
    """The functions and globals the IR declares but does not define (LLVM intrinsics left out)."""
    import llvmlite.binding as llvm  # type: ignore[import-untyped]

    m = llvm.parse_assembly(ir)
    names = {f.name for f in m.functions if f.is_declaration and not f.name.startswith("llvm.")}
    return names | {g.name for g in m.global_variables if g.is_declaration}


def emit_object(ir: str, symbol: str, platform: str, alias: str = STEP_SYMBOL) -> bytes:
    """The IR as an object file for ``platform`` (a key of :data:`TRIPLES`), its function ``symbol``
    renamed ``alias``; refused if it needs a symbol that is neither the run time's nor libm's."""
    import llvmlite.binding as llvm

    if platform not in TRIPLES:
        raise BuildError(f"platform {platform!r}: native FMUs are built for {sorted(TRIPLES)}")
    missing = external_symbols(ir) - RUNTIME_SYMBOLS - LIBM
    if missing:
        raise BuildError(
            f"the compiled model needs {sorted(missing)}, which neither {RUNTIME_C.name} nor the C library "
            "provides: add them to the run time (or restructure the compiled function)"
        )
    llvm.initialize_all_targets()  # every target llvmlite carries (x86 and AArch64 among them)
    llvm.initialize_all_asmprinters()
    triple = TRIPLES[platform]
    m = llvm.parse_assembly(portable_ir(ir, platform))
    m.triple = triple
    tm = llvm.Target.from_triple(triple).create_target_machine(
        cpu=CPU[platform], features="", opt=3, reloc="pic", codemodel="default"
    )
    m.data_layout = str(tm.target_data)
    for f in m.functions:  # one entry per object: everything else private (several objects link together)
        if not f.is_declaration and f.name != symbol:
            f.linkage = llvm.Linkage.internal
    for g in m.global_variables:
        if not g.is_declaration:
            g.linkage = llvm.Linkage.internal
    fn = m.get_function(symbol)
    fn.name = alias
    m.verify()
    return bytes(tm.emit_object(m))


#: the condition codes of ``llvm.x86.atomic.<op>.cc`` (X86::CondCode) as a comparison of the new value with 0
_X86_CC = {4: "eq", 5: "ne", 8: "slt", 9: "sge", 14: "sle", 15: "sgt"}
_X86_ATOMIC_CC = re.compile(
    r"^(?P<indent>\s*)(?P<res>%[-\w.$]+) = (?:tail )?call i8 @llvm\.x86\.atomic\.(?P<op>add|sub|and|or|xor)\.cc\."
    r"(?P<ty>i\d+)\(ptr (?:\w+ )*(?P<ptr>%[-\w.$]+), (?P=ty) (?P<val>[-\w.$%]+), i32 (?P<cc>\d+)\)\s*$",
    re.M,
)


def portable_ir(ir: str, platform: str) -> str:
    """The IR for ``platform``: unchanged for x86-64; for another architecture every
    ``llvm.x86.atomic.<op>.cc`` call (numba's reference-count decrement, as LLVM's x86 lowering folds it:
    the atomic update and a flag of its result) written as ``atomicrmw`` and a comparison of the new
    value, the declaration dropped. Any other ``llvm.x86.*`` (or call to an intrinsic of no target
    here) is refused by name: the object would not build."""
    if TRIPLES[platform].startswith("x86_64"):
        return ir
    count = 0

    def rewrite(mt: re.Match[str]) -> str:
        nonlocal count
        cc = int(mt["cc"])
        if cc not in _X86_CC:
            raise BuildError(f"llvm.x86.atomic.{mt['op']}.cc with condition code {cc}: no rewrite for {platform}")
        count += 1
        i, ty, tag = mt["indent"], mt["ty"], f"%x86cc.{count}"
        return "\n".join(
            (
                f"{i}{tag}.old = atomicrmw {mt['op']} ptr {mt['ptr']}, {ty} {mt['val']} seq_cst",
                f"{i}{tag}.new = {mt['op']} {ty} {tag}.old, {mt['val']}",
                f"{i}{tag}.flag = icmp {_X86_CC[cc]} {ty} {tag}.new, 0",
                f"{i}{mt['res']} = zext i1 {tag}.flag to i8",
            )
        )

    out = _X86_ATOMIC_CC.sub(rewrite, ir)
    out = re.sub(r"^declare [^\n]*@llvm\.x86\.atomic\.\w+\.cc\.i\d+\([^\n]*$", "", out, flags=re.M)
    left = sorted(set(re.findall(r"@llvm\.x86\.[\w.]+", out)))
    if left:
        raise BuildError(f"the compiled model uses x86 intrinsics {left}: they have no {platform} form")
    return out


def write_objects(
    out_dir: Path, fmus: Iterable[FmuModel], platforms: Iterable[str] = tuple(TRIPLES)
) -> dict[tuple[str, str], list[Path]]:
    """(model, platform) -> the object files of its functions (step first), written into out_dir, for the
    native FMUs given and the platforms given (keys of :data:`TRIPLES`; default all)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: dict[tuple[str, str], list[Path]] = {}
    platforms = tuple(platforms)
    for model, fns in model_ir(fmus).items():
        for platform in platforms:
            for alias, (symbol, ir) in fns.items():
                p = out_dir / f"{model}.{alias}.{platform}.o"
                p.write_bytes(emit_object(ir, symbol, platform, alias))
                paths.setdefault((model, platform), []).append(p)
    return paths


def mingw_gcc() -> str | None:
    """The mingw-w64 cross compiler for win64 (Debian's gcc-mingw-w64-x86-64), if installed."""
    import shutil

    for name in ("x86_64-w64-mingw32-gcc", "x86_64-w64-mingw32-gcc-posix", "x86_64-w64-mingw32-gcc-win32"):
        if shutil.which(name):
            return name
    return None
