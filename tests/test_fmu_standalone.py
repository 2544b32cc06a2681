"""Standalone FMUs (``build-fmus --standalone``): they bundle a Python runtime with numpy, numba and
llvmlite and run in a pure C host on a machine with no Python reachable.

The slow part builds both standalone FMUs into a temporary folder, copies them elsewhere in /tmp,
and runs them from the C host ``tests/c_host/fmu_pair.c`` under ``env -i`` (PATH=/usr/bin:/bin,
HOME a fresh temporary folder, no PYTHON* variable, run from a folder outside the checkout). The
process's memory map then shows where libpython and the extension modules were loaded from: all
inside the extracted FMU, none from the build interpreter, its venv or the checkout. Numbers:
BaseOscillator alone against the exact forced response of the damped oscillator; the coupled pair
against the monolithic steady state (Case 1), converging at first order in the step.
"""

from __future__ import annotations

import math
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from _fmu_support import damped_forced_response, guid

from pyfmu_wrapper.fmubuild.build import REPO_ROOT, build_fmus, fmi_headers_dir
from pyfmu_wrapper.fmubuild.elfpath import run_paths
from pyfmu_wrapper.fmubuild.standalone import runtime_config, runtime_files
from pyfmu_wrapper.models.catalog import pick

PAIR_SOURCE = Path(__file__).parent / "c_host" / "fmu_pair.c"
BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=18.0, x0=0.01, xd0=0.0)


def test_runtime_holds_libpython_stdlib_and_packages(tmp_path):
    """What a standalone FMU bundles: the build's libpython and stdlib (no tests, GUI, installers),
    lib-dynload, and numpy, numba, llvmlite with their metadata, in a site-packages of the runtime."""
    files = {arc: src for src, arc in runtime_files(tmp_path)}
    ver = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    cfg = runtime_config()
    assert cfg["runtime_libpython"] in files and cfg["runtime_version"] == sys.version.split()[0]
    std = f"python/lib/{ver}/"
    assert f"{std}os.py" in files and f"{std}site.py" in files
    assert any(a.startswith(f"{std}lib-dynload/math.") for a in files)
    for bad in ("test/", "idlelib/", "tkinter/", "ensurepip/", "lib2to3/"):
        assert not any(a.startswith(std + bad) for a in files), bad
    site = f"{std}site-packages/"
    for pkg in ("numpy", "numba", "llvmlite"):
        assert f"{site}{pkg}/__init__.py" in files
        assert any(a.startswith(f"{site}{pkg}-") and a.endswith(".dist-info/METADATA") for a in files), pkg
    assert any(a.endswith("/libllvmlite.so") for a in files)
    # byte code compiled at build time for every bundled module
    assert f"{std}__pycache__/os.{sys.implementation.cache_tag}.pyc" in files
    # no path of the build machine in any bundled ELF: run paths only relative to the file ($ORIGIN)
    elf = [(a, src) for a, src in files.items() if ".so" in a.rsplit("/", 1)[-1]]
    assert len(elf) > 50
    for arc, src in elf:
        d = subprocess.run(["readelf", "-d", str(src)], capture_output=True, text=True).stdout
        for line in d.splitlines():
            if "RUNPATH" in line or "RPATH" in line:
                for part in line.split("[", 1)[1].rstrip("]").split(":"):
                    assert part.startswith("$ORIGIN") or not part, (arc, line)
    lib = Path(files[cfg["runtime_libpython"]])
    assert "/root/" not in " ".join(run_paths(lib)) and sys.base_prefix not in " ".join(run_paths(lib))


@pytest.fixture(scope="module")
def standalone(tmp_path_factory):
    """Both standalone FMUs, built in one temporary folder, extracted in another (outside the
    checkout); the pair host compiled there too; an empty HOME."""
    build = tmp_path_factory.mktemp("sa_build")
    fmus = build_fmus(pick(("BaseOscillator", "TMDInerter")), build, standalone=True)
    root = Path(tempfile.mkdtemp(prefix="pyfmu_standalone_"))
    dirs = {}
    for p in fmus:
        d = root / p.stem
        with zipfile.ZipFile(p) as z:
            z.extractall(d)
        dirs[p.stem] = d
    shutil.rmtree(build, ignore_errors=True)  # two ~98 MB zips, no longer needed
    exe = root / "fmu_pair"
    subprocess.run(
        ["gcc", "-O2", "-Wall", f"-I{fmi_headers_dir()}", str(PAIR_SOURCE), "-o", str(exe), "-ldl"],
        check=True,
        capture_output=True,
        text=True,
    )
    home = root / "home"
    home.mkdir()
    yield root, dirs, exe, home
    shutil.rmtree(root, ignore_errors=True)  # ~600 MB extracted


def _vrs(d: Path) -> dict:
    import fmpy

    return {v.name: (v.valueReference, v.type) for v in fmpy.read_model_description(str(d)).modelVariables}


def _run(standalone, stop, h, args, **env):
    root, dirs, exe, home = standalone
    b, t = dirs["BaseOscillator"], dirs["TMDInerter"]
    cmd = [
        "env",
        "-i",
        "PATH=/usr/bin:/bin",
        f"HOME={home}",
        "FMU_HOST_VERBOSE=1",
        *[f"{k}={v}" for k, v in env.items()],
        str(exe),
        repr(stop),
        repr(h),
        str(b),
        guid(b),
        str(t),
        guid(t),
        *args,
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=root, timeout=900)
    assert r.returncode == 0, r.stderr[-4000:]
    rows = np.array([[float(v) for v in line.split()[1:]] for line in r.stdout.splitlines() if line.startswith("row ")])
    maps = {line[4:] for line in r.stdout.splitlines() if line.startswith("map ")}
    locale = next(line[7:] for line in r.stdout.splitlines() if line.startswith("locale "))
    return rows, maps, r.stderr, locale


@pytest.mark.slow
def test_base_alone_exact_with_no_python_reachable(standalone):
    root, dirs, *_ = standalone
    vb = _vrs(dirs["BaseOscillator"])
    args = [f"r1:{vb[k][0]}={v!r}" for k, v in BASE.items()] + [f"o1:{vb['x'][0]}"]
    rows, maps, log, _ = _run(standalone, 0.5, 1e-3, args)
    x, _ = damped_forced_response(rows[:, 0], **BASE)
    assert rows.shape == (501, 2)
    assert np.max(np.abs(rows[:, 1] - x)) < 1e-7 * 0.01
    # libpython, numpy's and llvmlite's shared objects all came from the extracted FMU
    libpy = [m for m in maps if "/libpython3" in m]
    assert libpy and all(
        m.startswith(str(dirs["BaseOscillator"]) + "/resources/python/lib/")
        or m.startswith(str(dirs["TMDInerter"]) + "/resources/python/lib/")
        for m in libpy
    ), libpy
    for part in ("_multiarray_umath", "libllvmlite.so"):
        hits = [m for m in maps if part in m]
        assert hits and all(m.startswith(str(root)) for m in hits), (part, hits)
    outside = [m for m in maps if m.startswith((sys.base_prefix, sys.prefix, str(REPO_ROOT)))]
    assert not outside, outside
    assert "(bundled runtime)" in log and f"from {root}" in log


@pytest.mark.slow
def test_pyfmu_python_still_wins_over_the_bundled_runtime(standalone):
    root, dirs, *_ = standalone
    vb = _vrs(dirs["BaseOscillator"])
    args = [f"r1:{vb[k][0]}={v!r}" for k, v in BASE.items()] + [f"o1:{vb['x'][0]}"]
    rows, maps, log, _ = _run(standalone, 0.05, 1e-3, args, PYFMU_PYTHON=sys.prefix)
    assert any(m.startswith(sys.base_prefix) and "/libpython3" in m for m in maps)
    assert "(bundled runtime)" not in log and f"from {sys.prefix}" in log


@pytest.mark.slow
def test_bundled_runtime_ignores_pythonhome_and_pythonpath(standalone):
    """The bundled runtime starts isolated: a PYTHONHOME that does not exist (fatal if it were
    used) and a PYTHONPATH to the build venv's site-packages are both ignored."""
    import sysconfig

    root, dirs, *_ = standalone
    vb = _vrs(dirs["BaseOscillator"])
    args = [f"r1:{vb[k][0]}={v!r}" for k, v in BASE.items()] + [f"o1:{vb['x'][0]}"]
    rows, maps, log, _ = _run(
        standalone, 0.05, 1e-3, args, PYTHONHOME="/nonexistent", PYTHONPATH=sysconfig.get_paths()["purelib"]
    )
    x, _ = damped_forced_response(rows[:, 0], **BASE)
    assert np.max(np.abs(rows[:, 1] - x)) < 1e-7 * 0.01
    assert not [m for m in maps if m.startswith((sys.base_prefix, sys.prefix, str(REPO_ROOT)))]
    assert "(bundled runtime)" in log


@pytest.mark.slow
def test_bundled_runtime_leaves_the_host_locale_alone(standalone):
    """The bundled runtime is started with PyConfig's isolated configuration in UTF-8 mode
    (fmu/src/py_config.c): it neither reads nor sets the host's locale. The host never calls
    setlocale; with LANG=C.UTF-8 in its environment its LC_CTYPE must still be "C" after the
    FMU ran (the legacy start-up, Py_InitializeEx, set it to C.UTF-8 from the environment)."""
    root, dirs, *_ = standalone
    vb = _vrs(dirs["BaseOscillator"])
    args = [f"r1:{vb[k][0]}={v!r}" for k, v in BASE.items()] + [f"o1:{vb['x'][0]}"]
    rows, maps, log, loc = _run(standalone, 0.05, 1e-3, args, LANG="C.UTF-8")
    x, _ = damped_forced_response(rows[:, 0], **BASE)
    assert np.max(np.abs(rows[:, 1] - x)) < 1e-7 * 0.01
    assert "(bundled runtime)" in log
    assert loc == "C"


def _pair_amplitude(standalone, omega, h, periods=25, window=3):
    from pyfmu_wrapper.models import solve as mono
    from pyfmu_wrapper.models.base_tmd.cosim import CONNECTIONS, fmu_parameters
    from pyfmu_wrapper.physics.params import BaseParams, TMDParams

    _, dirs, *_ = standalone
    vr = {"base": _vrs(dirs["BaseOscillator"]), "tmd": _vrs(dirs["TMDInerter"])}
    base, tmd = BaseParams(), TMDParams(damping=10.0)
    args = []
    for key, v in fmu_parameters(base, tmd, omega, mono.initial_guess(base, tmd, omega)).items():
        inst, name = key.split(".")
        ref, typ = vr[inst][name]
        k = 1 if inst == "base" else 2
        args.append(f"i{k}:{ref}={int(v)}" if typ == "Integer" else f"r{k}:{ref}={float(v)!r}")
    for c in CONNECTIONS:
        (si, sn), (di, dn) = (s.strip().split(".") for s in c.split("->"))
        tag = "c12" if si == "base" else "c21"
        args.append(f"{tag}:{vr[si][sn][0]}={vr[di][dn][0]}")
    args.append(f"o1:{vr['base']['x'][0]}")
    T = 2 * math.pi / omega
    rows, *_ = _run(standalone, periods * T, h, args)
    x = rows[rows[:, 0] >= (periods - window) * T, 1]
    return float(np.max(np.abs(x))), mono.steady_state(base, tmd, omega).amplitude


@pytest.mark.slow
@pytest.mark.parametrize("omega", [17.0, 20.0])
def test_pair_against_monolithic_first_order(standalone, omega):
    """Case 1: Gauss-Seidel coupling with a zero-order hold is first order in h, so the steady
    amplitude comes about 10x closer to the monolithic one at h/10 (measured 0.54 % -> 0.054 % at
    17 rad/s, 0.30 % -> 0.029 % at 20 rad/s); held: ratio 5..20 and within 0.2 % at 0.1 ms."""
    a3, ref = _pair_amplitude(standalone, omega, 1e-3)
    a4, _ = _pair_amplitude(standalone, omega, 1e-4)
    e3, e4 = abs(a3 / ref - 1), abs(a4 / ref - 1)
    assert e4 <= 0.002, (a4, ref)
    assert 5 <= e3 / e4 <= 20, (e3, e4)


def test_missing_bundled_runtime_is_named_in_the_error(tmp_path):
    """An FMU whose pyfmu.cfg names a bundled runtime that is not there (and no other Python):
    fmi2Instantiate fails, no crash, and the message lists the runtime in its place of the order."""
    from _fmu_support import built_fmus, compile_c_host, extract

    d = extract(built_fmus()["BaseOscillator"], tmp_path / "fmu")
    cfg = d / "resources" / "pyfmu.cfg"
    lines = [
        ("python=/nonexistent/bin/python3" if line.startswith("python=") else line)
        for line in cfg.read_text().splitlines()
    ]
    cfg.write_text(
        "\n".join(lines + ["runtime=python", "runtime_libpython=python/lib/libpython3.11.so", "runtime_version=3.11.7"])
        + "\n"
    )
    exe = compile_c_host(tmp_path)
    home = tmp_path / "home"
    home.mkdir()
    r = subprocess.run(
        [
            "env",
            "-i",
            "PATH=/usr/bin:/bin",
            f"HOME={home}",
            "FMU_HOST_VERBOSE=1",
            str(exe),
            "run",
            "0.01",
            "0.001",
            str(d),
            guid(d),
            "base",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert r.returncode == 3, r.stderr[-3000:]  # instantiate returned NULL
    msg = r.stderr
    order = [
        "PYFMU_PYTHON: not set",
        f"the FMU's bundled runtime = python: no file {d}/resources/python/lib/libpython3.11.so",
        "the build's interpreter = /nonexistent/bin/python3",
    ]
    pos = [msg.find(o) for o in order]
    assert all(p >= 0 for p in pos) and pos == sorted(pos), msg[-3000:]


@pytest.mark.slow
def test_missing_system_library_is_named_with_the_interpreter(standalone):
    """A target without libffi (simulated: the runtime's _ctypes module removed, which is what a
    missing libffi.so.8 makes of it): instantiation fails with a message naming the missing system
    library, its package and the bundled interpreter (not an empty name, "(, 3.11.7)")."""
    root, dirs, exe, home = standalone
    moved = []
    try:
        for d in dirs.values():
            for so in (d / "resources" / "python" / "lib").glob("python3*/lib-dynload/_ctypes.*.so"):
                so.rename(so.with_suffix(".off"))
                moved.append(so)
        b, t = dirs["BaseOscillator"], dirs["TMDInerter"]
        cmd = ["env", "-i", "PATH=/usr/bin:/bin", f"HOME={home}", str(exe), "0.01", "0.001"]
        r = subprocess.run(
            [*cmd, str(b), guid(b), str(t), guid(t)], capture_output=True, text=True, cwd=root, timeout=900
        )
    finally:
        for so in moved:
            so.with_suffix(".off").rename(so)
    assert moved and r.returncode != 0
    assert "the system library libffi.so.8 is missing (Debian/Ubuntu package libffi8" in r.stderr, r.stderr[-3000:]
    ver = f"{sys.version_info[0]}.{sys.version_info[1]}"
    assert f"/resources/python/bin/python{ver}, {sys.version.split()[0]})" in r.stderr, r.stderr[-3000:]
    assert "(, " not in r.stderr
