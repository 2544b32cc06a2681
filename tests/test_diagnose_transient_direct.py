"""diagnose on transient records: the force's direct term in the accelerations when the load cell's
delay differs from the accelerometers' and part of the force is aliased. The direct term is the
measured force shifted by the delay difference d; an aliased component gets the shift of the
frequency it is seen at, an error of 2 |sin(pi fs d)| of its amplitude. A 256 Hz hammer record behind
a 76 Hz Butterworth on every channel with a 0.74 ms load-cell delay (field seed 3131 tr005) left
residuals alternating +-40 noise std around each hit at the truth, and the true pair unexplained."""

from __future__ import annotations

import math

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 5.0, "stiffness": 4.0e3, "damping": 10.0, "inertance": 5.0, "inerter": "ideal"}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}
FILT = {"filter": {"type": "butterworth", "order": 5, "cutoff_hz": 70.0}}


def make(path, delay, fs=256.0, T=30.0):
    """A hammer record (4 hits of 300 N) of the nominal (odeint at 16 fs), every channel behind FILT,
    the force delayed by ``delay``, sampled at fs."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(1)
    acq = {"all": FILT, **({"force": {"delay_s": delay}} if delay else {})}
    t = np.arange(0.0, T, 1.0 / (16 * fs))
    F = force_signal("hammer", rng, T, 300.0, n_hits=4)
    write_record(
        path / "r0.csv", measure(Truth(BASE, TMD, T).simulate(F, t, None, max_step=5e-4), t, 16, rng, NOISE, acq)
    )
    doc = {
        "level": "system",
        "nominal": {"base": BASE, "tmd": TMD},
        "records": [{"file": "r0.csv", "kind": "transient"}],
    }
    doc["acquisition"] = acq
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize("delay", [7.4e-4, 0.0], ids=["load-cell-delayed", "same-delay"])
def test_direct_term_error_of_an_aliased_delayed_force_is_predicted_and_the_record_set_aside(tmp_path, delay):
    """At the truth (the nominal), the excess chi2/n of xdd equals the predicted error's power
    (2 sin(pi fs d))^2 x aliased share x (direct term / noise)^2 to within 0.4-1.2 x (the aliased
    share is estimated from the measured spectrum, assuming the true force no weaker at the mirror
    frequencies: it errs high, on the side of setting the record aside), and the record is set aside with that reason when it exceeds
    FOLD_MAX^2; with the same delay on every channel the direct term is exact: the record is used and
    sits at the noise."""
    from pyfmu_wrapper.diagnose.system import transient as tr
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.diagnose.system.transient_fit import residual, start_update

    ds = load_dataset(make(tmp_path, delay))
    d = tr.TransientDiagnosis(ds)
    if delay:
        assert len(d.skipped) == 1 and d.skipped[0].startswith("every record would be set aside (about ")
        assert (
            "direct term in the accelerations is unknown" in d.skipped[0]
            and "treat the verdict with care" in d.skipped[0]
        )
        assert d.views and d.views[0].name == "r0.csv"  # the only record: used all the same, with the warning
    else:
        assert d.skipped == [] and [v.name for v in d.views] == ["r0.csv"]
    v = d.views[0]
    snr, dd = tr._direct_snr(v, d.p_nom)
    d.prepare()
    mdl = apply(d.p_nom, (), np.zeros(0))
    assert not isinstance(mdl, str)
    m = d._masks(None)[0]
    for _ in range(3):
        start_update(v, mdl, m)
    e = residual(v, mdl, m)
    assert e is not None
    chi2n = np.mean(e[m][:, v.has] ** 2, axis=0)
    if delay:
        assert dd == pytest.approx(-delay) and snr > tr.FOLD_MAX
        assert 2 * abs(math.sin(math.pi * 256.0 * delay)) == pytest.approx(1.12, abs=0.01)
        # the rule's noise is the sensor's (raw / sqrt(q)); the chi-square's also holds the force noise's
        # response (v.sigma, known after prepare): the prediction in the chi-square's units
        pred = (snr * v.raw_noise["xdd"] / math.sqrt(v.q) / v.sigma[2]) ** 2
        assert 0.4 * pred < chi2n[2] - 1 < 1.2 * pred  # measured 0.64 x here, 0.92 x on the field record
    else:
        assert snr == 0.0
        assert np.all((chi2n > 0.8) & (chi2n < 1.2)), chi2n
