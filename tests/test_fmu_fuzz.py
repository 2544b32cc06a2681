"""Fuzz test of the FMUs in a pure C host (tests/c_host/fmu_fuzz.c, one forked subprocess per
sequence): random FMI call sequences with wrong states, bad value references, NaN/Inf, zero,
negative and huge steps, state get/set/serialize across instances and FMUs, garbage and freed
state pointers and corrupt serialized bytes. No crash, no hang, every invalid call refused and
logged, finite outputs whenever fmi2OK, restored states bit-identical.

The default run keeps 40 sequences; the slow test runs 2,000 (numbers in benchmarks/README_fmu.md).
The FMI 3.0 variants: tests/fmi3_fuzz.py (6 sequences by default, each child loading the Python-hosted FMUs
anew; 1,000 in the slow test).
"""

from __future__ import annotations

import pytest
from _fmu_support import run_fuzz


def check(r, sequences):
    assert r["sequences"] == sequences
    assert (r["crashes"], r["hangs"], r["lost"]) == (0, 0, 0), r["stderr"][-2000:]
    assert r["invalid"] > 0.3 * r["calls"]  # the sequences do exercise the refusals
    assert r["invalid_ok"] == 0 and r["unlogged"] == 0
    assert r["nonfinite_ok"] == 0
    assert r["roundtrips"] > 0 and r["roundtrip_bad"] == 0
    assert r["serial_roundtrips"] > 0 and r["serial_bad"] == 0


def test_fuzz_small(tmp_path):
    check(run_fuzz(tmp_path, 40, 150, seed=11), 40)


@pytest.mark.slow
def test_fuzz_2000_sequences(tmp_path):
    r = run_fuzz(tmp_path, 2000, 160, seed=2026)
    print({k: v for k, v in r.items() if k != "stderr"})
    check(r, 2000)


# --- the FMI 3.0 variants (tests/fmi3_fuzz.py: ctypes, one forked child per sequence) -------------------
def run_fuzz3(root, sequences: int, calls: int, seed: int) -> dict:
    import subprocess
    import sys
    from pathlib import Path

    from _fmu_support import extract, guid

    from pyfmu_wrapper.fmubuild.build import ensure_fmus
    from pyfmu_wrapper.models.catalog import pick

    fmus = ensure_fmus(pick(("BaseOscillator", "TMDInerter")), fmi_version=3)
    args = []
    for n in ("BaseOscillator", "TMDInerter"):
        d = extract(fmus[n], Path(root))
        args += [str(d), guid(d)]
    r = subprocess.run(
        [sys.executable, str(Path(__file__).parent / "fmi3_fuzz.py"), str(seed), str(sequences), str(calls), *args],
        capture_output=True,
        text=True,
        timeout=7200,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    out = {k: int(v) for k, v in (line.split() for line in r.stdout.splitlines() if line.strip())}
    out["stderr"] = r.stderr  # type: ignore[assignment]
    return out


def check3(r, sequences):
    assert r["sequences"] == sequences
    assert (r["crashes"], r["hangs"], r["lost"]) == (0, 0, 0), r["stderr"][-2000:]
    assert r["invalid"] > 0.3 * r["calls"]
    assert r["invalid_ok"] == 0 and r["unlogged"] == 0 and r["nonfinite_ok"] == 0
    assert r["roundtrips"] > 0 and r["roundtrip_bad"] == 0
    assert r["serial_bad"] == 0


def test_fuzz_fmi3_small(tmp_path):
    check3(run_fuzz3(tmp_path, 6, 150, seed=21), 6)


@pytest.mark.slow
@pytest.mark.timeout(3600)
def test_fuzz_fmi3_1000_sequences(tmp_path):
    r = run_fuzz3(tmp_path, 1000, 160, seed=2027)
    print({k: v for k, v in r.items() if k != "stderr"})
    check3(r, 1000)
    assert r["serial_roundtrips"] > 0
