"""Build native FMUs: the model's compiled functions linked into the stub, no Python on the target.

``build-fmus --native`` / :func:`build_native_fmus`. The stub's core (``fmu/src/*.c`` but
``py_embed.c`` and ``py_config.c``) is compiled with ``fmu/src/native/native_embed.c`` in their
place, which serves the core's calls into its slave with the compiled functions, and
``fmu/src/native/native_rt.c``, the run time those need; the functions themselves are object code
emitted from the numba source (:mod:`.native_obj`: the step, configure, outputs, derivative and sensitivity whose
factories each FMU's declaration holds). The builders take those declarations
(:class:`~pyfmu_wrapper.fmi.fmumodel.FmuModel`) as arguments. The model's table (sizes, value references, start values,
the messages of its checks) is generated here from the FMU's declaration into
``pyfmu_native_model.h``. The archive holds what a Python-hosted FMU holds but the bundled Python
code: ``modelDescription.xml``, ``documentation/``, ``resources/pyfmu.cfg`` and
``resources/variables.tsv``, and the binaries of three platforms (:data:`PLATFORM_DIR`):

- Linux x86-64 (``linux64`` / ``x86_64-linux``) and Linux aarch64 (``aarch64-linux``, FMI 2.0.4's use of the
  FMI 3.0 tuple), linked with zig's C compiler (the ``ziglang`` package) against glibc 2.17's symbols
  (:data:`ZIG_TARGET`): they load on any glibc >= 2.17 and need only libc, libm and libdl;
- Windows x86-64 (``win64`` / ``x86_64-windows``), cross-compiled with mingw-w64 when it is installed,
  linking only KERNEL32 and msvcrt.

Each binary exports the functions of its own FMI version only. A shipped FMU carries no test hook: the
variables of :data:`TEST_HOOKS` (``debug_raise``) are left out of its model description and variable table,
so a host can neither see nor set them; ``test_hooks=True`` builds the test variant that keeps them.
"""

from __future__ import annotations

import dataclasses
import hashlib
import importlib.util
import os
import subprocess
import sys
import tempfile
import zipfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from ..fmi.contract import MAX_INTEGRATOR_STEPS, c_header
from ..fmi.fmumodel import FmuModel, NativeFmu
from ..fmi.native_model import FIELD_CODE, KAPPA_CODE, ME_FUNCTIONS
from ..fmi.varspec import FmuSpec
from ..safeio.files import replace_checked
from .build import DEFAULT_OUT, STUB_DIR, check_output, fmi_headers_dir, fmi_out_dir, fmu_source_hash, source_hash
from .buildinfo import BuildError
from .documentation import documentation_html
from .model_description import guid_of, model_description_xml, variable_table_tsv
from .model_description3 import model_description3_xml
from .native_obj import ENTRIES, PLATFORM3, RUNTIME_C, mingw_gcc, write_objects

NATIVE_DIR = STUB_DIR / "native"
#: where the native FMUs go, below the build folder (FMI 3.0 ones in its fmi3/)
NATIVE_SUBDIR = "native"
#: the core's sources a native binary is compiled from (py_embed.c and py_config.c are replaced)
CORE = ("fmi_api.c", "fmi3_api.c", "fmi_state.c", "log.c", "resources.c")
#: the binary folder of each platform, per FMI version (FMI 2.0 names, FMI 3.0 platform tuples), and the suffix
PLATFORM_DIR = {(2, p): f"binaries/{p}" for p in PLATFORM3} | {(3, p): f"binaries/{t}" for p, t in PLATFORM3.items()}
SUFFIX = {"linux64": ".so", "win64": ".dll", "aarch64-linux": ".so"}
#: zig's target of each Linux platform: glibc 2.17 (manylinux2014's baseline), so no symbol of a newer
#: glibc is referenced and the binary loads on any glibc >= 2.17
ZIG_TARGET = {"linux64": "x86_64-linux-gnu.2.17", "aarch64-linux": "aarch64-linux-gnu.2.17"}
#: the newest glibc symbol version a Linux binary may reference (tests/test_native_platforms.py reads them)
GLIBC_FLOOR = (2, 17)
#: variables that exist for tests only (a shipped native FMU leaves them out; ``test_hooks=True`` keeps them)
TEST_HOOKS = ("debug_raise",)


def failure_reasons() -> tuple[str, ...]:
    """Why a native step failed, by its code (:data:`~.contract.FAIL_NOT_FINITE` ...), in the words
    of the Python-hosted FMU's messages."""
    from ..solvers.rodas import STEP_CAP, STEP_UNDERFLOW, failure_reason

    return (
        "",
        "the state is not finite at its end",
        failure_reason(STEP_UNDERFLOW, MAX_INTEGRATOR_STEPS),
        failure_reason(STEP_CAP, MAX_INTEGRATOR_STEPS),
        f"it needs more than {MAX_INTEGRATOR_STEPS} integrator steps; use shorter communication steps",
    )


def native_of(fmu: FmuModel) -> NativeFmu:
    """The native functions of a declaration (refused by name if it has none)."""
    if fmu.native is None:
        raise BuildError(f"{fmu.name} has no native variant (its declaration holds no native functions)")
    return fmu.native


def model_table(fmu: FmuModel) -> dict[str, Any]:
    """The sizes and words of one native model, from its declaration (:class:`~pyfmu_wrapper.fmi.fmumodel.NativeFmu`'s
    ``table``): its state length, packed parameters and input array (the slave's ``z``, ``p`` and ``u``), its
    states' names, the messages of its cross-field checks and of its field checks, the variables a failed
    check reports."""
    table: dict[str, Any] = native_of(fmu).table()
    return table


def shipped_spec(spec: FmuSpec, test_hooks: bool = False) -> FmuSpec:
    """The variable table a native FMU declares: ``spec`` without the variables of :data:`TEST_HOOKS`
    (``test_hooks``: with them, the test build)."""
    if test_hooks:
        return spec
    kept = tuple(v for v in spec.variables if v.name not in TEST_HOOKS)
    return dataclasses.replace(spec, variables=kept, vr_top=max(v.vr for v in spec.variables))


def native_variable_table(fmu: FmuModel, test_hooks: bool = False) -> str:
    """``resources/variables.tsv`` of a native FMU: the rows of :func:`shipped_spec`, and, when a test hook
    had the highest value reference, a last line holding that value reference alone. The stub sizes its
    value buffers by the highest value reference of the file (the compiled functions address the
    declaration's, test hooks included) and defines only the full rows, so the hook's value reference
    is refused like any unknown one and keeps its start value."""
    spec = shipped_spec(fmu.spec, test_hooks)
    table = variable_table_tsv(spec)
    top = max(v.vr for v in fmu.spec.variables)
    return table if max(v.vr for v in spec.variables) == top else table + f"{top}\n"


def model_header(fmu: FmuModel, test_hooks: bool = False) -> str:
    """pyfmu_native_model.h: the table native_embed.c needs of one model, from its declaration (the
    buffers span every value reference of the declaration; a test hook is read only in a test build)."""
    spec = fmu.spec
    tab = model_table(fmu)
    nvr = max(v.vr for v in spec.variables) + 1
    nstate = tab["nstate"]
    inputs = [v for v in spec.variables if v.causality == "input"]
    outs = [v for v in spec.variables if v.causality == "output"]
    starts = [v for v in spec.variables if v.start is not None]
    kind = [" "] * nvr
    for v in spec.variables:
        if v.causality == "input":
            kind[v.vr] = "i"
        elif v.causality == "parameter" and v.type == "Real":
            kind[v.vr] = "p"
    names = {v.name: v.vr for v in spec.variables}

    def arr(xs: Iterable[object]) -> str:
        return ", ".join(str(x) for x in xs) or "0"

    start_rows = ", ".join(
        f"{{{v.vr}, '{'R' if v.type == 'Real' else 'I'}', {float(v.start)!r}}}"  # type: ignore[arg-type]
        for v in starts
    )
    check_rows = ", ".join(
        f"{{{names[n]}, '{'R' if spec.by_name(n).type == 'Real' else 'I'}', \"{n}\"}}" for n in tab["check_vars"]
    )
    checks = tab["checks"]
    lines = [
        "/* generated by pyfmu_wrapper/fmubuild/native_build.py from the FMU's declaration: do not edit */",
        "#ifndef PYFMU_NATIVE_MODEL_H",
        "#define PYFMU_NATIVE_MODEL_H",
        f"#define NM_NVR {nvr}",
        f"#define NM_NSTATE {nstate}",
        f"#define NM_NP {tab['np']}",
        f"#define NM_NU {tab['nu']}",
        f"#define NM_NATOL {max(nstate, 1)}",
        f"#define NM_NIN {len(inputs)}",
        f"static const int NM_IN_VR[] = {{{arr(v.vr for v in inputs)}}};",
        f"#define NM_NOUT {len(outs)}",
        f"static const unsigned NM_OUT_VR[] = {{{arr(v.vr for v in outs)}}};",
        f"static const char NM_OUT_REAL[] = {{{arr(int(v.type == 'Real') for v in outs)}}};",
        f"#define NM_NSTART {len(starts)}",
        "static const struct { unsigned vr; char type; double value; } NM_START[] = {" + start_rows + "};",
        f'static const char NM_KIND[] = "{"".join(kind)}";',
        f"#define NM_RTOL_VR {names.get('rtol', -1)}",
        f"#define NM_DEBUG_VR {names.get('debug_raise', -1) if test_hooks else -1}",
        "static const char *const NM_STATE_NAMES[] = {" + ", ".join(f'"{n}"' for n in tab["states"]) + "};",
        "static const char *const NM_FAIL_WHY[] = {" + ", ".join(f'"{w}"' for w in failure_reasons()) + "};",
        f"#define NM_NCHECKS {len(checks)}",
        "static const char *const NM_CHECKS[] = {" + (", ".join(f'"{c}"' for c in checks) or '""') + "};",
        f"#define NM_NCHECKVARS {len(tab['check_vars'])}",
        "static const struct { unsigned vr; char type; const char *name; } NM_CHECKVARS[] = {"
        + (check_rows or "{0, 'R', \"\"}")
        + "};",
        *model_exchange_lines(fmu),
        f"#define NM_FIELD_CODE {FIELD_CODE}",
        f"#define NM_KAPPA_CODE {KAPPA_CODE}",
        f"#define NM_VR_KAPPA {names.get('base_compliance', 0)}",
        "static const char *const NM_FIELD_MSG[] = {" + ", ".join(f'"{m}"' for m in tab["fields"]) + "};",
        "#endif",
        "",
    ]
    return "\n".join(lines)


def has_model_exchange(fmu: FmuModel) -> bool:
    """The native FMU implements Model Exchange: its table declares states (variables with ``derivative_of``);
    its functions then include :data:`~pyfmu_wrapper.fmi.native_model.ME_FUNCTIONS` (checked when its objects
    are written, :func:`check_model_exchange`)."""
    return bool(fmu.spec.derivatives())


def model_exchange_lines(fmu: FmuModel) -> list[str]:
    """pyfmu_native_model.h's Model Exchange table (native/native_me.c): the number of states (0: none) and of
    event indicators, the value references of the states (the first NM_NX entries of z) and of their
    derivatives."""
    spec = fmu.spec
    states, ders = spec.states(), spec.derivatives()
    nstate = model_table(fmu)["nstate"] if states else 0
    if len(states) > nstate:
        raise BuildError(f"{fmu.name}: {len(states)} states declared, but its model's state has {nstate} entries")
    return [
        f"#define NM_NX {len(states)}",
        f"#define NM_NZ {len(spec.event_indicators())}",
        f"static const unsigned NM_X_VR[] = {{{', '.join(str(v.vr) for v in states) or '0'}}};",
        f"static const unsigned NM_DER_VR[] = {{{', '.join(str(v.vr) for v in ders) or '0'}}};",
    ]


def check_model_exchange(fmu: FmuModel, objects: list[Path]) -> None:
    """A native FMU with states must bring every Model Exchange function (refused by name otherwise)."""
    if not has_model_exchange(fmu):
        return
    have = {p.name.split(".")[1] for p in objects}
    missing = [ENTRIES[k] for k in ME_FUNCTIONS if ENTRIES[k] not in have]
    if missing:
        raise BuildError(
            f"{fmu.name} declares states (Model Exchange) but its native functions lack {', '.join(missing)}: "
            f"add {', '.join(k for k in ME_FUNCTIONS if ENTRIES[k] in missing)} to its functions dict"
        )


def native_sources() -> list[Path]:
    """Every source of a native binary: the core, its headers, the native folder."""
    return [STUB_DIR / n for n in CORE] + sorted(STUB_DIR.glob("*.h")) + sorted(NATIVE_DIR.glob("*.[ch]"))


def native_hash(fmu: FmuModel, test_hooks: bool = False) -> str:
    """Hash of what one native FMU is built from (its Python-hosted variant's hash, the native sources and
    the modules of its declared native functions; and whether it is the test build): one FMU's, so the FMUs
    built with it never make it stale."""
    h = hashlib.sha256(source_hash([fmu]).encode() + (b"test_hooks" if test_hooks else b""))
    pkg = Path(__file__).resolve().parents[1]
    writers = [
        pkg / n for n in ("fmubuild/native_build.py", "fmubuild/native_obj.py", "fmi/native.py", "fmi/native_model.py")
    ]
    declared = sorted({Path(sys.modules[f.__module__].__file__ or "") for f in native_of(fmu).factories()})
    for f in native_sources() + writers + declared:
        h.update(f.name.encode() + f.read_bytes())
    return h.hexdigest()[:24]


def zig_cc() -> list[str]:
    """The command of zig's C compiler (the ``ziglang`` package, a dependency of this project)."""
    if importlib.util.find_spec("ziglang") is None:
        raise BuildError(
            "the Linux binaries of a native FMU are linked with zig's C compiler against glibc 2.17: "
            f"install the ziglang package into {sys.executable} (pip install ziglang)"
        )
    return [sys.executable, "-m", "ziglang", "cc"]


def compile_native(
    fmu: FmuModel,
    objects: list[Path],
    out_so: Path,
    fmi_version: int,
    platform: str = "linux64",
    test_hooks: bool = False,
) -> None:
    """Link the core, native_embed.c, native_rt.c and the model's objects into one shared library for a
    Linux ``platform`` (a key of :data:`ZIG_TARGET`) that exports the fmi{2,3}* functions of ``fmi_version``
    only, with zig's C compiler against glibc 2.17 (floating-point contraction off: the C computes what
    it says on every architecture)."""
    if platform not in ZIG_TARGET:
        raise BuildError(f"platform {platform!r}: the Linux binaries are built for {sorted(ZIG_TARGET)}")
    cc = zig_cc()
    out_so.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".native-gen-", dir=out_so.parent) as gen_name:
        gen = Path(gen_name)
        (gen / "pyfmu_contract.h").write_text(c_header())
        (gen / "pyfmu_native_model.h").write_text(model_header(fmu, test_hooks))
        script = gen / "fmi.map"
        script.write_text(f"{{ global: fmi{fmi_version}*; local: *; }};\n")
        cmd = [
            *cc, "-target", ZIG_TARGET[platform], "-shared", "-fPIC", "-O2", "-std=gnu11", "-ffp-contract=off",
            "-fno-sanitize=all", "-Wall", "-Wno-unused-parameter", "-fvisibility=hidden", f"-I{gen}", f"-I{STUB_DIR}",
            f"-I{fmi_headers_dir()}", *[str(STUB_DIR / n) for n in CORE], str(NATIVE_DIR / "native_embed.c"),
            str(RUNTIME_C), *[str(o) for o in objects], "-o", str(out_so), "-s", "-Wl,-z,noexecstack", "-ldl",
            "-lpthread", "-lm", f"-Wl,--version-script={script}",
        ]  # fmt: skip
        env = dict(os.environ, ZIG_LOCAL_CACHE_DIR=str(gen / "zig-cache"))
        r = subprocess.run(cmd, capture_output=True, text=True, env=env)
    if r.returncode != 0:
        raise BuildError(f"linking the native FMU for {platform} failed:\n{' '.join(cmd)}\n{r.stderr}")


def compile_native_win64(
    fmu: FmuModel, objects: list[Path], out_dll: Path, fmi_version: int, test_hooks: bool = False
) -> None:
    """The same binary for Windows x86-64, cross-compiled with mingw-w64: a DLL that needs only
    KERNEL32 and msvcrt (libgcc and winpthreads linked in). It exports the fmi{2,3}* functions of
    ``fmi_version`` only: a .def file lists them, and the ``-export:`` directives the FMI headers'
    ``__declspec(dllexport)`` leave in each object's ``.drectve`` section (fmpy's fmi2Functions.h marks every
    fmi2 function so, whatever is defined) are removed before linking, else the other version's functions
    would be exported too."""
    cc = mingw_gcc()
    if cc is None:
        raise BuildError("the mingw-w64 cross compiler (Debian: gcc-mingw-w64-x86-64) is needed for win64 binaries")
    nm = cc.replace("-gcc", "-nm").replace("-posix", "").replace("-win32", "")
    objcopy = nm[: -len("-nm")] + "-objcopy"
    out_dll.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=".native-win-", dir=out_dll.parent) as gen_name:
        gen = Path(gen_name)
        (gen / "pyfmu_contract.h").write_text(c_header())
        (gen / "pyfmu_native_model.h").write_text(model_header(fmu, test_hooks))
        srcs = [*[STUB_DIR / n for n in CORE], NATIVE_DIR / "native_embed.c", RUNTIME_C]
        flags = ["-O2", "-std=gnu11", "-w", "-D__USE_MINGW_ANSI_STDIO=1", f"-I{gen}", f"-I{STUB_DIR}"]
        flags.append(f"-I{fmi_headers_dir()}")
        objs = []
        for src in srcs:
            o = gen / (src.stem + ".obj")
            r = subprocess.run([cc, *flags, "-c", str(src), "-o", str(o)], capture_output=True, text=True)
            if r.returncode == 0:  # the .def file alone says what the DLL exports
                r = subprocess.run([objcopy, "--remove-section=.drectve", str(o)], capture_output=True, text=True)
            if r.returncode != 0:
                raise BuildError(f"compiling {src.name} for win64 failed:\n{r.stderr}")
            objs.append(o)
        r = subprocess.run([nm, "-g", "--defined-only", *map(str, objs)], capture_output=True, text=True)
        names = {ln.split()[-1] for ln in r.stdout.splitlines() if ln.strip()}
        exports = sorted(n for n in names if n.startswith(f"fmi{fmi_version}"))
        (gen / "fmi.def").write_text("EXPORTS\n" + "".join(f"    {e}\n" for e in exports))
        cmd = [cc, "-shared", "-s", "-o", str(out_dll), *map(str, objs), *map(str, objects), str(gen / "fmi.def"),
               "-static-libgcc", "-Wl,-Bstatic", "-lpthread", "-Wl,-Bdynamic"]  # fmt: skip
        r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0 or not exports:
        raise BuildError(f"linking the win64 native FMU failed:\n{' '.join(cmd)}\n{r.stderr}")


def native_platforms(win64: bool | None = None, aarch64: bool = True) -> tuple[str, ...]:
    """The platforms of a native build (FMI 2.0 folder names): linux64, then win64 (``win64`` None: when
    mingw-w64 is installed), then aarch64-linux (unless ``aarch64`` is False)."""
    if win64 is None:
        win64 = mingw_gcc() is not None
    return ("linux64",) + (("win64",) if win64 else ()) + (("aarch64-linux",) if aarch64 else ())


def build_native_fmus(
    fmus: Iterable[FmuModel],
    out_dir: str | os.PathLike[str] = DEFAULT_OUT / NATIVE_SUBDIR,
    fmi_version: int = 2,
    win64: bool | None = None,
    aarch64: bool = True,
    test_hooks: bool = False,
) -> list[Path]:
    """Build native FMUs of one FMI version into ``out_dir`` (FMI 3.0: pass :func:`.build.fmi_out_dir`'s)
    from their declarations, each of which must hold native functions, with the binaries of
    :func:`native_platforms` in each archive (``win64`` None: when mingw-w64 is installed); ``test_hooks``:
    the test build, which keeps the variables of :data:`TEST_HOOKS`."""
    platforms = native_platforms(win64, aarch64)
    fmus = list(fmus)
    missing = [f.name for f in fmus if f.native is None]
    if missing:
        raise BuildError(f"no native variant of {missing}: their declarations hold no native functions")
    out = Path(out_dir)
    check_output(out, fmus)
    built = []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        objects = write_objects(tmp / "obj", fmus, platforms)
        for fmu in fmus:
            n, spec, nhash = fmu.name, shipped_spec(fmu.spec, test_hooks), native_hash(fmu, test_hooks)
            check_model_exchange(fmu, objects[(n, platforms[0])])
            me = has_model_exchange(fmu)
            binaries = {}
            for plat in platforms:
                binaries[plat] = tmp / plat / f"{n}{SUFFIX[plat]}"
                if plat == "win64":
                    compile_native_win64(fmu, objects[(n, plat)], binaries[plat], fmi_version, test_hooks)
                else:
                    compile_native(fmu, objects[(n, plat)], binaries[plat], fmi_version, plat, test_hooks)
            guid = guid_of(spec, "native" + nhash)
            md = (
                model_description_xml(spec, guid, model_exchange=me)
                if fmi_version == 2
                else model_description3_xml(spec, guid, model_exchange=me)
            )
            cfg = (
                f"guid={guid}\nmodel_identifier={spec.model_identifier}\nvariant=native{'-test' if test_hooks else ''}\n"
                f"platforms={' '.join(binaries)}\nsource_hash={nhash}\n"
            )
            target = out / f"{spec.model_identifier}.fmu"
            part = out / f".{spec.model_identifier}.fmu.{os.getpid()}.{os.urandom(4).hex()}.part"
            try:
                with zipfile.ZipFile(part, "w", zipfile.ZIP_DEFLATED) as z:
                    z.writestr("modelDescription.xml", md)
                    z.writestr("documentation/index.html", documentation_html(spec, guid, (), "none: native code"))
                    for plat, b in binaries.items():
                        z.write(b, f"{PLATFORM_DIR[(fmi_version, plat)]}/{spec.model_identifier}{SUFFIX[plat]}")
                    z.writestr("resources/pyfmu.cfg", cfg)
                    z.writestr("resources/variables.tsv", native_variable_table(fmu, test_hooks))
            except BaseException:
                part.unlink(missing_ok=True)
                raise
            replace_checked(part, target, lambda f: fmu_source_hash(f) is not None, "build-fmus")
            built.append(target)
    return built


def ensure_native_fmus(
    fmus: Iterable[FmuModel],
    out_dir: str | os.PathLike[str] = DEFAULT_OUT / NATIVE_SUBDIR,
    fmi_version: int = 2,
    test_hooks: bool = False,
) -> dict[str, Path]:
    """Paths of the native FMUs (model identifier -> path), building those missing or stale (FMI 3.0 ones
    in ``out_dir/fmi3``; ``test_hooks``: the test build)."""
    fmus = list(fmus)
    d = fmi_out_dir(out_dir, fmi_version)
    paths = {f.name: d / f"{f.spec.model_identifier}.fmu" for f in fmus}
    stale = [f for f in fmus if fmu_source_hash(paths[f.name]) != native_hash(f, test_hooks)]
    if stale:
        build_native_fmus(stale, d, fmi_version, test_hooks=test_hooks)
    return paths
