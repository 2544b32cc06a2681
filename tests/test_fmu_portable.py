"""The FMUs are self-contained: they run from a copy in another folder, in a fresh virtual
environment with only numpy, numba and fmpy (not this project), with the build checkout out of
reach (cwd elsewhere, no PYTHONPATH), in a Python host and in a pure C host; and when no Python
fits, instantiation fails with a message naming what was tried and what to install.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from _fmu_support import built_fmus, compile_c_host, damped_forced_response, extract, guid

REPO = Path(__file__).resolve().parents[1]
BASE = dict(M=100.0, K=4.0e4, C=100.0, F=200.0, w=15.0, x0=0.01, xd0=-0.05)
TMD = dict(m=9.0, I=1.0, k=4.0e3, c=10.0, y0=0.01)


def clean_env(**extra) -> dict:
    """The environment without anything pointing at this checkout or its venv."""
    env = {
        k: v
        for k, v in os.environ.items()
        if not k.startswith(("PYTHON", "VIRTUAL_ENV", "LD_PRELOAD", "PYFMU_")) and k != "PATH"
    }
    env["PATH"] = "/usr/bin:/bin"
    env.update(extra)
    return env


def make_venv(venv: Path, cwd: Path) -> Path:
    """A virtual environment with only numpy, numba and fmpy (and their dependencies)."""
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, capture_output=True, cwd=cwd, env=clean_env())
    py = venv / "bin" / "python"
    r = subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "numpy", "numba", "fmpy"],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=clean_env(),
        timeout=1800,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    return py


def cached_venv(cwd: Path) -> Path:
    """The numpy/numba/fmpy venv, made once per machine outside the checkout (creating one takes a
    minute or more on a busy machine: the slow test below makes a brand-new one every time)."""
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "pyfmu-tests" / "portable-venv"
    py = root / "bin" / "python"
    ok = (
        py.is_file()
        and subprocess.run(
            [str(py), "-c", "import numpy, numba, fmpy"], capture_output=True, env=clean_env(), cwd=cwd
        ).returncode
        == 0
    )
    if not ok:
        shutil.rmtree(root, ignore_errors=True)  # missing or broken (an interrupted build): make it anew
        root.parent.mkdir(parents=True, exist_ok=True)
        make_venv(root, cwd)
    return py


@pytest.fixture(scope="module")
def fresh(tmp_path_factory):
    """FMUs copied to a temporary folder, and a venv elsewhere with only numpy, numba, fmpy."""
    root = tmp_path_factory.mktemp("portable")
    fmus = {n: Path(shutil.copy(p, root / p.name)) for n, p in built_fmus().items()}
    py = cached_venv(root)
    return root, fmus, py.parent.parent, py


SCRIPT = textwrap.dedent("""
    import json, sys
    import fmpy
    try:
        import pyfmu_wrapper
        raise SystemExit("pyfmu_wrapper is importable: " + pyfmu_wrapper.__file__)
    except ImportError:
        pass
    base, tmd, repo = sys.argv[1], sys.argv[2], sys.argv[3]
    b = fmpy.simulate_fmu(base, stop_time=1.0, output_interval=1e-3, start_values=json.loads(sys.argv[4]),
                          output=["x", "xd"])
    t = fmpy.simulate_fmu(tmd, stop_time=1.0, output_interval=1e-3, start_values=json.loads(sys.argv[5]),
                          output=["y"])
    files = sorted({m.__file__ for n, m in sys.modules.items() if n.startswith("_pyfmu_") and m.__file__})
    print(json.dumps({"t": list(b["time"]), "x": list(b["x"]), "xd": list(b["xd"]), "y": list(t["y"]),
                      "files": files, "numpy": __import__("numpy").__version__, "exe": sys.executable}))
""")


def test_runs_in_numpy_numba_fmpy_venv_from_a_copy(fresh):
    _check_run(*fresh)


@pytest.mark.slow
def test_runs_in_brand_new_venv_from_a_copy(fresh, tmp_path):
    root, fmus, _, _ = fresh
    venv = tmp_path / "venv"
    _check_run(root, fmus, venv, make_venv(venv, tmp_path))


def _check_run(root, fmus, venv, py):
    work = root / "elsewhere"
    work.mkdir(exist_ok=True)
    (work / "run.py").write_text(SCRIPT)
    r = subprocess.run(
        [
            str(py),
            "run.py",
            str(fmus["BaseOscillator"]),
            str(fmus["TMDInerter"]),
            str(REPO),
            json.dumps(BASE),
            json.dumps(TMD),
        ],
        capture_output=True,
        text=True,
        cwd=work,
        env=clean_env(),
        timeout=900,
    )
    assert r.returncode == 0, r.stderr[-4000:]
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert out["exe"].startswith(str(venv))
    # the model code came from the FMU's resources/, never from the checkout
    assert out["files"] and all("/resources/_pyfmu_" in f and not f.startswith(str(REPO)) for f in out["files"])
    assert any(f.endswith("/models/base_tmd/fmus/slaves.py") for f in out["files"])
    # and computes the right numbers: exact forced response, exact free decay
    x, xd = damped_forced_response(np.array(out["t"]), **BASE)
    assert np.max(np.abs(np.array(out["x"]) - x)) < 1e-7 * 0.01
    y, _ = damped_forced_response(np.array(out["t"]), TMD["m"] + TMD["I"], TMD["k"], TMD["c"], 0.0, 1.0, TMD["y0"], 0.0)
    assert np.max(np.abs(np.array(out["y"]) - y)) < 1e-8 * TMD["y0"]


def _c_host_run(exe, d, env, cwd):
    args = [str(exe), "run", "0.2", "0.001", str(d), guid(d), "base"]
    import fmpy

    md = fmpy.read_model_description(str(d))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    args += [f"r:{vr[k]}={v!r}" for k, v in BASE.items()] + [f"o:{vr['x']}"]
    return subprocess.run(args, capture_output=True, text=True, env=env, cwd=cwd, timeout=600)


def test_c_host_finds_the_python_named_by_PYFMU_PYTHON(fresh):
    root, fmus, venv, _ = fresh
    d = extract(fmus["BaseOscillator"], root / "c_ok")
    exe = compile_c_host(root)
    r = _c_host_run(exe, d, clean_env(PYFMU_PYTHON=str(venv), FMU_HOST_VERBOSE="1"), root)
    assert r.returncode == 0, r.stderr[-4000:]
    c = np.loadtxt(r.stdout.splitlines())
    x, _ = damped_forced_response(c[:, 0], **BASE)
    assert np.max(np.abs(c[:, 1] - x)) < 1e-7 * 0.01


def test_no_fitting_python_is_a_clear_error(fresh, tmp_path):
    """PYFMU_PYTHON names a Python without numpy/numba-capable site, the recorded one is gone."""
    root, fmus, venv, _ = fresh
    d = extract(fmus["BaseOscillator"], tmp_path / "c_bad")
    cfg = d / "resources" / "pyfmu.cfg"
    cfg.write_text(
        "\n".join(
            "python=/nonexistent/bin/python3" if line.startswith("python=") else line
            for line in cfg.read_text().splitlines()
        )
        + "\n"
    )
    bare = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(bare)], check=True, env=clean_env())
    exe = compile_c_host(tmp_path)
    r = _c_host_run(exe, d, clean_env(PYFMU_PYTHON=str(bare), FMU_HOST_VERBOSE="1"), tmp_path)
    assert r.returncode == 3  # instantiate returned NULL; no crash
    msg = r.stderr
    assert "no Python that can run this FMU was found" in msg
    assert f"PYFMU_PYTHON = {bare}" in msg and "numpy is not installed" in msg and "numba is not installed" in msg
    # copy-pasteable: quoted (unquoted, a shell reads >= as a redirection); the FMU's own documentation
    assert "/nonexistent/bin/python3" in msg and 'python -m pip install "numpy>=1.26" "numba>=0.59"' in msg
    assert "documentation/index.html in the FMU" in msg and "docs/fmus.md" not in msg


def _other_python() -> str | None:
    for cand in ["python3.12", "python3.13", *sorted(Path("/root/.pyenv/versions").glob("3.1[23]*/bin/python3"))]:
        p = shutil.which(str(cand)) if isinstance(cand, str) else str(cand)
        if (
            p
            and subprocess.run(
                [p, "-c", "import sys; assert sys.version_info[:2] != (3, 11)"], capture_output=True
            ).returncode
            == 0
        ):
            return p
    return None


def test_python_host_of_another_version_gets_a_clear_error(fresh, tmp_path):
    """A Python 3.12 host without numpy/numba (the FMU built in 3.11): fmi2Instantiate fails with
    a message naming that interpreter and what to install, instead of importing a foreign numba."""
    other = _other_python()
    if other is None:
        pytest.skip("no Python other than 3.11 on this machine")
    root, fmus, _, _ = fresh
    d = extract(fmus["BaseOscillator"], tmp_path / "other")
    script = textwrap.dedent(f"""
        import ctypes, sys
        lib = ctypes.CDLL({str(d / "binaries" / "linux64" / "BaseOscillator.so")!r})
        msgs = []
        LOG = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p)
        log = LOG(lambda e, n, s, c, m: msgs.append(m.decode()))
        class CB(ctypes.Structure):
            _fields_ = [("logger", LOG), ("alloc", ctypes.c_void_p), ("free", ctypes.c_void_p),
                        ("step", ctypes.c_void_p), ("env", ctypes.c_void_p)]
        cb = CB(log, None, None, None, None)
        lib.fmi2Instantiate.restype = ctypes.c_void_p
        c = lib.fmi2Instantiate(b"x", 1, {guid(d)!r}.encode(), {("file://" + str(d / "resources")).encode()!r},
                                ctypes.byref(cb), 0, 0)
        print("NULL" if c is None else "INSTANCE")
        print("\\n".join(msgs))
        print("numba_loaded", "numba" in sys.modules)
    """)
    r = subprocess.run(
        [other, "-c", script], capture_output=True, text=True, env=clean_env(), cwd=tmp_path, timeout=300
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.startswith("NULL"), r.stdout
    assert "cannot run its model" in r.stdout and other.split("/")[-1][:6] in r.stdout
    assert "numba is not installed" in r.stdout and '-m pip install "numpy>=1.26" "numba>=0.59"' in r.stdout
    assert "documentation/index.html in the FMU" in r.stdout
    assert "numba_loaded False" in r.stdout
