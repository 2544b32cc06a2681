"""What Reference-FMUs' fmusim v0.0.39 found on the native FMUs (benchmarks/bench_native_external.py), as a
test that needs no external tool: the same calls through fmpy.

``fmusim --output-interval 2`` co-simulates the TMD with communication steps of 2 s. The Python-hosted FMU
takes such a step in pieces of at most 1 s (models/base_tmd/fmus/slaves.py: advance); the native TMD FMU refused it with
an error ("the native FMU takes steps of at most 1 s"), so fmusim stopped with exit status 3 on the
native FMU and ran to the end on the Python-hosted one. A native FMU must compute what the Python-hosted
FMU computes: the same outputs, bit for bit, after each long step. It does now: the compiled step takes
long steps in the Python slave's pieces (models/base_tmd/fmus/native.py tmd_step).
"""

from __future__ import annotations

import numpy as np
import pytest
from _fmu_support import built_fmus
from test_fmu_ranges import Logged

from pyfmu_wrapper.fmubuild.native_build import build_native_fmus
from pyfmu_wrapper.models.catalog import pick

OUTPUTS = ("force", "y", "yd", "inerter_force")


@pytest.fixture(scope="module")
def tmd_pair(tmp_path_factory):
    native = build_native_fmus(pick("TMDInerter"), out_dir=tmp_path_factory.mktemp("native"))[0]
    return {"native": native, "hosted": built_fmus()["TMDInerter"]}


def _run(fmu, tmp_path, tag, steps):
    """Case 1 TMD from y0 = 10 mm with the base at rest, communication steps ``steps``: outputs after each."""
    f = Logged(fmu, tmp_path, tag)
    rows = []
    try:
        f.s.setupExperiment(startTime=0.0)
        f.s.enterInitializationMode()
        f.s.setReal([f.vr[k] for k in ("m", "I", "k", "c", "y0")], [9.0, 1.0, 4.0e3, 10.0, 0.01])
        f.s.exitInitializationMode()
        t = 0.0
        for h in steps:
            f.s.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            t += h
            rows.append(f.s.getReal([f.vr[k] for k in OUTPUTS]))
        f.s.terminate()
    except Exception as e:  # noqa: BLE001 - the FMU's own message is what the test reports
        raise AssertionError(f"{tag}: {e}: {f.text()}") from e
    finally:
        f.s.freeInstance()
    return np.array(rows)


def test_native_tmd_takes_a_2s_step_as_the_python_hosted_fmu(tmd_pair, tmp_path):
    steps = (2.0, 2.0, 1.5)  # 2 s twice (two pieces each), then 1.5 s (two pieces of 0.75 s)
    hosted = _run(tmd_pair["hosted"], tmp_path, "hosted", steps)
    # independent of either FMU: the TMD's free oscillation from 10 mm with the base at rest loses energy
    # (c = 10 N.s/m), (m + I) yd^2 / 2 + k y^2 / 2 <= k y0^2 / 2, so |y| never exceeds 10 mm
    assert np.all(np.isfinite(hosted)) and np.all(np.abs(hosted[:, 1]) <= 0.01)
    native = _run(tmd_pair["native"], tmp_path, "native", steps)
    assert native.tobytes() == hosted.tobytes()  # bit for bit, every output after every step


def test_steps_of_at_most_1s_agree_bit_for_bit(tmd_pair, tmp_path):
    """The same run in steps of 1 s (the longest piece of a step): identical."""
    steps = (1.0,) * 5 + (0.5,)
    hosted = _run(tmd_pair["hosted"], tmp_path, "hosted1", steps)
    native = _run(tmd_pair["native"], tmp_path, "native1", steps)
    assert np.all(np.isfinite(hosted)) and np.ptp(hosted[:, 1]) > 1e-3  # the TMD moves
    assert native.tobytes() == hosted.tobytes()
