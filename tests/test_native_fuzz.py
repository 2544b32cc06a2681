"""Fuzz of the native FMUs: the C harness of tests/test_fmu_fuzz.py (FMI 2.0: random call
sequences with wrong states, bad value references, NaN/Inf, bad steps, FMU states across instances,
garbage and corrupt states) and tests/fmi3_fuzz.py (FMI 3.0), on the native FMUs instead of the
Python-hosted ones: no crash, no hang, every invalid call refused and logged, no non-finite value
answered OK, restored states bit-identical. A short run by default; the slow test runs 5,000 FMI 2.0
and 1,000 FMI 3.0 sequences (directional derivatives, states and serialisation included).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from _fmu_support import compile_fuzz, extract, guid
from test_fmu_fuzz import check, check3

from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.catalog import PROJECT_FMUS, pick


def _dirs(root: Path, fmi_version: int) -> list[str]:
    fmus = {
        p.stem: p
        for p in build_native_fmus(pick(PROJECT_FMUS), out_dir=root / f"fmus{fmi_version}", fmi_version=fmi_version)
    }
    args = []
    for n in ("BaseOscillator", "TMDInerter"):
        d = extract(fmus[n], root / f"x{fmi_version}")
        args += [str(d), guid(d)]
    return args


def _parse(r: subprocess.CompletedProcess) -> dict:
    assert r.returncode == 0, r.stderr[-3000:]
    out = {k: int(v) for k, v in (line.split() for line in r.stdout.splitlines() if line.strip())}
    out["stderr"] = r.stderr
    return out


def fuzz2(root: Path, sequences: int, calls: int, seed: int) -> dict:
    args, exe = _dirs(root, 2), compile_fuzz(root)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "LD_PRELOAD", "VIRTUAL_ENV"))}
    cmd = [str(exe), str(seed), str(sequences), str(calls), *args]
    return _parse(subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=7200))


def fuzz3(root: Path, sequences: int, calls: int, seed: int) -> dict:
    script = Path(__file__).parent / "fmi3_fuzz.py"
    cmd = [sys.executable, str(script), str(seed), str(sequences), str(calls), *_dirs(root, 3)]
    return _parse(subprocess.run(cmd, capture_output=True, text=True, timeout=7200))


def test_native_fuzz_small(tmp_path):
    check(fuzz2(tmp_path, 40, 150, seed=31), 40)
    check3(fuzz3(tmp_path, 12, 150, seed=32), 12)


@pytest.mark.slow
@pytest.mark.timeout(7200)
def test_native_fuzz_5000_fmi2_and_1000_fmi3_sequences(tmp_path):
    r2 = fuzz2(tmp_path, 5000, 160, seed=3030)
    print({k: v for k, v in r2.items() if k != "stderr"})
    check(r2, 5000)
    r3 = fuzz3(tmp_path, 1000, 150, seed=3031)
    print({k: v for k, v in r3.items() if k != "stderr"})
    check3(r3, 1000)
