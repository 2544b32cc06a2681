"""The native FMUs' platforms (pyfmu_wrapper/fmubuild/native_build.py): linux64, win64 and aarch64-linux in one
archive, Linux binaries that load on glibc >= 2.17, DLLs that export their own FMI version only, no test hook in
a shipped FMU, and the sizes docs/fmus.md states.

- Every Linux binary's versioned symbol references (read from its ELF ``.gnu.version_r`` here, and by
  ``objdump -T`` where binutils is installed: both must agree) name no glibc newer than 2.17.
- BaseOscillator's aarch64-linux binary, run under ``qemu-aarch64`` by a small C host
  (tests/c_host/fmu_single.c) cross-compiled for aarch64, gives x(30 s) at w = 17 rad/s within 1e-10
  (relative) of its x86_64 binary run by the same host source compiled natively; both are the exact forced
  response of the base (the base steps exactly) to 1e-9 of its amplitude.
- The default run builds BaseOscillator once (FMI 2.0 and 3.0, every platform); the plain
  ``build-fmus --fmi-version both`` of every model is the slow test at the end.
"""

from __future__ import annotations

import math
import re
import shutil
import struct
import subprocess
import zipfile
from pathlib import Path

import fmpy
import pytest
from _fmu_support import damped_forced_response, guid
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave

from pyfmu_wrapper.fmubuild.build import fmi_headers_dir, fmi_out_dir
from pyfmu_wrapper.fmubuild.native_build import GLIBC_FLOOR, PLATFORM_DIR, TEST_HOOKS, build_native_fmus
from pyfmu_wrapper.fmubuild.native_obj import mingw_gcc
from pyfmu_wrapper.generate.docs import FMUS_FILE
from pyfmu_wrapper.generate.fmu_sizes import read_size_table, sizes
from pyfmu_wrapper.models.catalog import NATIVE_FMUS, SPECS, pick

SINGLE = Path(__file__).parent / "c_host" / "fmu_single.c"
#: the most an archive may weigh (issue 40: three platforms in at most 2 MB)
MAX_ARCHIVE = 2_000_000
#: where qemu-aarch64 finds the aarch64 loader and C library (Debian's libc6-arm64-cross)
AARCH64_SYSROOT = Path("/usr/aarch64-linux-gnu")


@pytest.fixture(scope="module")
def base_build(tmp_path_factory) -> dict[int, Path]:
    """BaseOscillator, native, FMI 2.0 and 3.0, every platform this machine builds (as build-fmus does)."""
    root = tmp_path_factory.mktemp("platforms")
    fmu = pick("BaseOscillator")
    return {v: build_native_fmus(fmu, fmi_out_dir(root, v), fmi_version=v)[0] for v in (2, 3)}


# --- the symbol versions of an ELF shared object, read from the file -------------------------------------


def needed_versions(so: bytes) -> set[str]:
    """The version names the object's ``.gnu.version_r`` (SHT_GNU_verneed) requires, e.g. GLIBC_2.17."""
    assert so[:4] == b"\x7fELF" and so[4] == 2 and so[5] == 1, "a 64-bit little-endian ELF"
    (shoff,) = struct.unpack_from("<Q", so, 0x28)
    shentsize, shnum = struct.unpack_from("<HH", so, 0x3A)
    sections = [struct.unpack_from("<IIQQQQIIQQ", so, shoff + k * shentsize) for k in range(shnum)]
    out = set()
    for _name, typ, _flags, _addr, off, _size, link, info, _align, _entsize in sections:
        if typ != 0x6FFFFFFE:  # SHT_GNU_verneed
            continue
        strtab = sections[link][4]
        pos = off
        for _ in range(info):  # Elf64_Verneed entries
            _ver, cnt, _file, aux, nxt = struct.unpack_from("<HHIII", so, pos)
            a = pos + aux
            for _ in range(cnt):  # Elf64_Vernaux
                _hash, _flags2, _other, name, anext = struct.unpack_from("<IHHII", so, a)
                out.add(so[strtab + name : so.index(b"\0", strtab + name)].decode())
                a += anext
            pos += nxt
    return out


#: ELF e_machine of x86-64 and AArch64
EM_X86_64, EM_AARCH64 = 62, 183


def machine(elf: bytes) -> int:
    """The ELF header's e_machine: the architecture the file is built for."""
    assert elf[:4] == b"\x7fELF"
    return int(struct.unpack_from("<H", elf, 0x12)[0])


def glibc_versions(names: set[str]) -> list[tuple[int, ...]]:
    return sorted(tuple(int(x) for x in n[6:].split(".")) for n in names if n.startswith("GLIBC_"))


def linux_binaries(fmu: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(fmu) as z:
        return {n: z.read(n) for n in z.namelist() if n.startswith("binaries/") and n.endswith(".so")}


def check_glibc_floor(fmu: Path, tmp_path: Path) -> None:
    """No Linux binary of ``fmu`` references a glibc symbol version above 2.17; objdump -T agrees."""
    binaries = linux_binaries(fmu)
    assert len(binaries) == 2, sorted(binaries)  # linux64 / x86_64-linux and aarch64-linux
    for name, data in binaries.items():
        versions = needed_versions(data)
        glibc = glibc_versions(versions)
        assert glibc, (name, versions)  # it does bind versioned glibc symbols
        assert max(glibc) <= GLIBC_FLOOR, (fmu.name, name, versions)
        if shutil.which("objdump"):
            (tmp_path / "x.so").write_bytes(data)
            dump = subprocess.run(["objdump", "-T", str(tmp_path / "x.so")], capture_output=True, text=True)
            if dump.returncode == 0:  # binutils of this host may not read the other architecture
                assert set(re.findall(r"\b(GLIBC_[\d.]+)\b", dump.stdout)) == {
                    v for v in versions if v.startswith("GLIBC_")
                }, name


def test_archive_holds_three_platforms_within_2_mb(base_build):
    for v, fmu in base_build.items():
        with zipfile.ZipFile(fmu) as z:
            names = set(z.namelist())
            cfg = z.read("resources/pyfmu.cfg").decode()
        plats = ["linux64", "aarch64-linux"] + (["win64"] if mingw_gcc() else [])
        for p in plats:
            suffix = ".dll" if p == "win64" else ".so"
            assert f"{PLATFORM_DIR[(v, p)]}/BaseOscillator{suffix}" in names, (v, p, sorted(names))
        assert f"platforms={' '.join(sorted(plats, key=['linux64', 'win64', 'aarch64-linux'].index))}" in cfg
        assert not [n for n in names if n.endswith(".py")]
        assert fmu.stat().st_size <= MAX_ARCHIVE
    if mingw_gcc() is None:
        pytest.skip("mingw-w64 is missing (.ci/run installs gcc-mingw-w64-x86-64): no win64 binary to check")


def test_linux_binaries_need_no_glibc_above_2_17(base_build, tmp_path):
    for fmu in base_build.values():
        check_glibc_floor(fmu, tmp_path)


def test_the_elf_reader_sees_a_newer_glibc_where_one_is_bound(tmp_path):
    """The reader above is not blind: a library built here with the host's gcc and linked against the host's
    glibc (>= 2.29 on this machine's Debian) binds pow to a version above 2.17, and the reader says so."""
    src = tmp_path / "p.c"
    src.write_text("#include <math.h>\ndouble f(double x, double y) { return pow(x, y) + exp2(x) + log2(y); }\n")
    so = tmp_path / "p.so"
    subprocess.run(["gcc", "-shared", "-fPIC", "-O2", str(src), "-o", str(so), "-lm"], check=True)
    glibc = glibc_versions(needed_versions(so.read_bytes()))
    import platform

    host = tuple(int(x) for x in platform.libc_ver()[1].split(".")[:2])
    if host < (2, 29):
        pytest.skip(f"this host's glibc {host} binds pow to its old version: nothing above 2.17 to find")
    assert max(glibc) > GLIBC_FLOOR, glibc


def test_win64_dll_exports_its_own_fmi_version_only(base_build, tmp_path):
    if mingw_gcc() is None or shutil.which("x86_64-w64-mingw32-objdump") is None:
        pytest.skip("mingw-w64 is missing (.ci/run installs gcc-mingw-w64-x86-64)")
    for v, fmu in base_build.items():
        with zipfile.ZipFile(fmu) as z:
            (tmp_path / "m.dll").write_bytes(z.read(f"{PLATFORM_DIR[(v, 'win64')]}/BaseOscillator.dll"))
        dump = subprocess.run(
            ["x86_64-w64-mingw32-objdump", "-p", str(tmp_path / "m.dll")], capture_output=True, text=True, check=True
        ).stdout
        table = dump[dump.index("[Ordinal/Name Pointer] Table") :]
        exports = set(re.findall(r"^\s*\[\s*\d+\]\s+(\w+)$", table, re.M))
        header = (fmi_headers_dir() / f"fmi{v}Functions.h").read_text()
        declared = set(re.findall(rf"FMI{v}_Export\s+(fmi{v}\w+)TYPE", header))
        assert declared and exports == declared, (v, sorted(exports ^ declared))


def _run_single(exe: list[str], fmu_dir: Path, binary: str, start: dict[str, float], out: str) -> float:
    vr = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmu_dir)).modelVariables}
    args = [f"r:{vr[k]}={v!r}" for k, v in start.items()] + [f"o:{vr[out]}"]
    cmd = [*exe, str(fmu_dir / binary), str(fmu_dir / "resources"), guid(fmu_dir), "30", "0.001", *args]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=600, env={"PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr[-2000:]
    (line,) = [ln for ln in r.stdout.splitlines() if ln.startswith("out ")]
    return float(line.split()[2])


def test_aarch64_binary_under_qemu_agrees_with_x86_64(base_build, tmp_path):
    qemu, cross = shutil.which("qemu-aarch64"), shutil.which("aarch64-linux-gnu-gcc")
    if qemu is None or cross is None or not (AARCH64_SYSROOT / "lib").is_dir():
        pytest.skip("qemu-user, gcc-aarch64-linux-gnu or libc6-arm64-cross is missing (.ci/run installs them)")
    d = tmp_path / "fmu"
    with zipfile.ZipFile(base_build[2]) as z:
        z.extractall(d)
    inc = f"-I{fmi_headers_dir()}"
    for cc, exe in (("gcc", "host_x86_64"), (cross, "host_aarch64")):
        subprocess.run([cc, "-O2", "-Wall", inc, str(SINGLE), "-o", str(tmp_path / exe), "-ldl"], check=True)
    so = {p: (d / PLATFORM_DIR[(2, p)] / "BaseOscillator.so").read_bytes() for p in ("linux64", "aarch64-linux")}
    assert machine((tmp_path / "host_aarch64").read_bytes()) == machine(so["aarch64-linux"]) == EM_AARCH64
    assert machine((tmp_path / "host_x86_64").read_bytes()) == machine(so["linux64"]) == EM_X86_64
    start = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=17.0, x0=0.01, xd0=0.0)
    x86 = _run_single([str(tmp_path / "host_x86_64")], d, "binaries/linux64/BaseOscillator.so", start, "x")
    arm = _run_single(
        [qemu, "-L", str(AARCH64_SYSROOT), str(tmp_path / "host_aarch64")],
        d,
        "binaries/aarch64-linux/BaseOscillator.so",
        start,
        "x",
    )
    rel = abs(arm - x86) / abs(x86)
    print(f"x(30 s) at w = 17 rad/s: x86_64 {x86!r}, aarch64 {arm!r}, relative difference {rel:.3g}")
    assert rel <= 1e-10
    exact, _ = damped_forced_response(30.0, **start)
    amplitude = 200.0 / math.hypot(4.0e4 - 100.0 * 17.0**2, 100.0 * 17.0)
    assert abs(x86 - exact) <= 1e-9 * amplitude, (x86, exact)


def test_shipped_fmu_has_no_test_hook_and_the_test_build_has(base_build, tmp_path):
    """The shipped FMU declares no debug_raise and refuses its value reference; the test build
    (``test_hooks=True``) declares it, and setting it fails the next step with the injected error."""
    vr = SPECS["BaseOscillator"].vr("debug_raise")
    assert TEST_HOOKS == ("debug_raise",)
    test_fmu = build_native_fmus(pick("BaseOscillator"), tmp_path / "t", win64=False, aarch64=False, test_hooks=True)[0]
    for fmu, hooked in ((base_build[2], False), (test_fmu, True)):
        md = fmpy.read_model_description(str(fmu))
        assert ("debug_raise" in {v.name for v in md.modelVariables}) is hooked
        d = fmpy.extract(str(fmu), unzipdir=str(tmp_path / f"x{hooked}"))
        s = FMU2Slave(guid=md.guid, unzipDirectory=d, modelIdentifier="BaseOscillator", instanceName="h")
        s.instantiate()
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        s.exitInitializationMode()
        s.doStep(0.0, 1e-3)
        if hooked:
            s.setInteger([vr], [1])
            with pytest.raises(FMICallException):
                s.doStep(1e-3, 1e-3)
        else:
            with pytest.raises(FMICallException):
                s.setInteger([vr], [1])
            s.doStep(1e-3, 1e-3)  # and the FMU steps on
        s.freeInstance()


def _doc_table() -> dict:
    return read_size_table(FMUS_FILE.read_text(encoding="utf-8"))


def check_doc_sizes(build: dict[int, list[Path]], rel: float = 0.1) -> None:
    """docs/fmus.md's generated size table against a fresh build: every FMU built is there, each size
    within ``rel`` (the archive's bytes move with any source change: its GUID and hashes are in it)."""
    table = _doc_table()
    for v, fmus in build.items():
        for fmu in fmus:
            total, binaries = sizes(fmu, v)
            kb, bins = table[(fmu.stem, v)]
            assert abs(kb * 1000 - total) <= rel * total, (fmu.stem, v, kb, total)
            for p, n in binaries.items():
                assert abs(bins[p] * 1000 - n) <= rel * n, (fmu.stem, v, p, bins[p], n)


def test_docs_size_table_is_every_native_fmu_within_2_mb_and_holds_against_a_fresh_build(base_build):
    table = _doc_table()
    assert {k for k in table} == {(n, v) for n in NATIVE_FMUS for v in (2, 3)}
    for (name, v), (kb, bins) in table.items():
        assert kb * 1000 <= MAX_ARCHIVE and set(bins) == {"linux64", "win64", "aarch64-linux"}, (name, v)
    check_doc_sizes({v: [p] for v, p in base_build.items()})


@pytest.mark.slow
def test_plain_build_fmus_both_gives_three_platforms_within_2_mb_and_glibc_2_17(tmp_path):
    """The plain ``build-fmus --fmi-version both`` (every model's native FMUs; the command docs/fmus.md gives):
    each archive <= 2 MB with the three platforms, no glibc symbol version above 2.17, the docs' sizes."""
    import sys

    out = tmp_path / "fmus"
    r = subprocess.run(
        [sys.executable, "-m", "pyfmu_wrapper.cli.build_fmus", "--fmi-version", "both", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    build = {v: sorted(fmi_out_dir(out, v).glob("*.fmu")) for v in (2, 3)}
    assert {p.stem for p in build[2]} == {p.stem for p in build[3]} == set(NATIVE_FMUS)
    for v, fmus in build.items():
        for fmu in fmus:
            assert fmu.stat().st_size <= MAX_ARCHIVE, fmu
            _, binaries = sizes(fmu, v)
            assert set(binaries) == {"linux64", "aarch64-linux"} | ({"win64"} if mingw_gcc() else set()), fmu
            check_glibc_floor(fmu, tmp_path)
    check_doc_sizes(build)
