"""diagnose on transient records: pairs of effects named by the rule of the issue (a second effect
only when it closes a stated share of what the first leaves and its size is significant and
physically meaningful), judged in the parameters that mean something."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.run import run_diagnosis
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}
KINDS = [("sweep_lin", {"f0": 1.5, "f1": 5.0}), ("random", {"f_lo": 1.0, "f_hi": 8.0, "amp": 60.0})]


def make(path, changes, offsets=None, fs=256.0, T=30.0, seed=7):
    """A sweep and a random-force record of the truth (odeint at 8 fs), sampled at fs with 1 % noise."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    recs = []
    for i, (kind, kw) in enumerate(KINDS):
        kw = dict(kw)
        t = np.arange(0.0, T, 1.0 / (8 * fs))
        F = force_signal(kind, rng, T, kw.pop("amp", 150.0), **kw)
        m = measure(Truth(BASE, TMD, T, **changes).simulate(F, t, None), t, 8, rng, NOISE, {}, offsets=offsets)
        write_record(path / f"r{i}.csv", m)
        recs.append({"file": f"r{i}.csv", "kind": "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": {}}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.slow
def test_cubic_beside_an_offset_of_one_sensor_is_a_pair(tmp_path):
    """Cubic stiffness and an offset of the x sensor alone (-1.2 mm, as field tr035): the pair closes
    the gap to the noise; the offset is significant in x, and 0 in y. The old rule asked every
    parameter of the second effect to be > 3 std from 0, so y's zero refused the pair (unexplained)."""
    make(tmp_path, {"k3": 9.4e4}, offsets={"x": -1.2e-3})
    v = run_diagnosis(tmp_path, out=None)["verdict"]
    assert sorted(v["effects"]) == ["cubic", "sensor_offset"], v["text"]
    p = v["parameters"]
    assert abs(p["sensor_offset.x_offset"]["value"] + 1.2e-3) < 2e-5
    assert abs(p["cubic.cubic_stiffness"]["value"] - 9.4e4) < 0.05 * 9.4e4


@pytest.mark.slow
def test_a_cause_the_screen_misses_is_found_on_the_windows(tmp_path, monkeypatch):
    """Base mass -7 kg and base stiffness +1500 N/m (as field seed 6363 tr044): the base's resonance
    moves by 5.6 %, twice its half-power bandwidth (C / (2 sqrt(K M)) = 2.5 %). On that field dataset
    the screen's one linear step from the nominal ranked both last (a drop of 1.3 in a chi-square of
    1e8) and every kept single was ruled out on its window, so nothing was named. Here the screen is
    made to miss them the same way (both screened out): the screened-out singles are then fitted on
    the windows, and the pair is named with values within 1 % of the truth."""
    from pyfmu_wrapper.diagnose.system import transient

    real = transient.screen

    def missing(d, cands, train, base=None):
        keep, out = real(d, cands, train, base)
        if base is None:  # the first screen, from the nominal: both causes ranked last
            for e in ("base_mass", "base_stiffness"):
                if e in keep:
                    keep.remove(e)
                    out[e] = 1.3
        return keep, out

    monkeypatch.setattr(transient, "screen", missing)
    make(tmp_path, {"dM": -7.0, "dK": 1500.0}, T=60.0)
    res = run_diagnosis(tmp_path, out=None)
    v = res["verdict"]
    assert sorted(v["effects"]) == ["base_mass", "base_stiffness"], v["text"]
    p = v["parameters"]
    assert abs(p["base_mass.delta_mass"]["value"] + 7.0) < 0.07
    assert abs(p["base_stiffness.delta_stiffness"]["value"] - 1500.0) < 15.0
    notes = [c.get("restart", "") for c in res["transient"]["candidates"] if c["effects"] == ["base_mass"]]
    assert any("screened out, fitted on the windows" in n for n in notes)
