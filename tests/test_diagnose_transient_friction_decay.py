"""diagnose on transient records: a free decay with dry friction in the TMD link. The link slips for a
few periods, then sticks at an offset x - y that its stick-slip history sets and that stays for the
rest of the record; the truth is the independent stick-slip integrator of :mod:`.transient_truth`."""

from __future__ import annotations

import numpy as np
import yaml

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 1.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 9.0, "inerter": "ideal"}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01}
DF = 2.5  #: the truth's dry friction [N] (seed 9494's tr000: 2.54 N, sticks for good at 0.7 s)
Z0 = np.array([0.0027, 0.0, 0.0082, 0.0])  #: the decay's start (tr000's): x, xd, y, yd [m, m/s]


def make(path, T=8.0, fs=1000.0, seed=3):
    """One free decay of T s from Z0 under a DF stick-slip truth, sampled at fs, 1 % noise."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, T, 1.0 / (8 * fs))
    sig = Truth(BASE, TMD, T, df=DF).simulate(lambda s: 0.0 * np.asarray(s, float), t, Z0.copy())
    sig.pop("mode")
    sig.pop("force")
    write_record(path / "decay.csv", measure(sig, t, 8, rng, NOISE, {}))
    doc = {
        "level": "system",
        "nominal": {"base": BASE, "tmd": TMD},
        "records": [{"file": "decay.csv", "kind": "decay"}],
        "acquisition": {},
    }
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


def _prepared(tmp_path):
    from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis

    d = TransientDiagnosis(load_dataset(make(tmp_path / "ds"), log=lambda *a, **k: None))
    d.prepare()
    return d


def test_simulator_follows_the_stick_slip_truth_of_a_decay(tmp_path):
    """The project's simulator (regularised law + stick check, RK4 on its grid) at the truth's df and
    the slope's bound, its start state fitted (4 unknowns): chi2 / n of the independent truth's
    record within 0.25 of 1 on x, y, xdd and below 2 on ydd (measured 1.03, 1.14, 1.09, 1.62: ydd's
    excess sits in the fit samples holding a stick-slip event, where ydd jumps; about half of it is
    the record's point sampling of that jump, which the simulation's continuous block mean does not
    model: 1.35 when each sample is its interval's mean). At df 10 % off the best start state leaves
    over 30 times more (the stuck offset the slip history sets: the chi-square is a comb in df)."""
    from scipy.optimize import least_squares

    from pyfmu_wrapper.diagnose.system.transient_effects import BOUNDS, apply
    from pyfmu_wrapper.diagnose.system.transient_sim import simulate

    d = _prepared(tmp_path)
    (v,) = d.views
    assert v.free_decay
    slope = BOUNDS["friction.friction_slope"][1]

    def chi2n(df: float) -> np.ndarray:
        mdl = apply(d.p_nom, ("friction",), np.array([df, slope]))
        assert not isinstance(mdl, str)

        def res(u: np.ndarray) -> np.ndarray:
            z = np.zeros(6)
            z[:4] = Z0 + 1e-3 * u
            return ((v.meas - simulate(v, mdl.p, z)) / v.sigma)[v.skip :].ravel()

        r = least_squares(res, np.zeros(4), diff_step=1e-3, max_nfev=40)
        return np.mean(r.fun.reshape(-1, 4) ** 2, axis=0)

    c = chi2n(DF)
    assert np.all(np.abs(c[:3] - 1.0) < 0.25) and c[3] < 2.0, c
    for off in (0.9, 1.1):
        assert np.sum(chi2n(off * DF)) > 30 * np.sum(c), off


def test_friction_fit_of_a_decay_reaches_the_truth_from_its_default_start(tmp_path):
    """The friction single fitted on the decay alone from its default starts (1 N; slopes 1000 and
    3e4 s/m) and the nominal's start state: df within 0.5 % of the truth and the held-out segments
    explained to the noise (z <= EXPLAINS_Z). Without the decay's ramp (:func:`_decay_ramp`) the fit
    stops in a tooth of the comb (seed 9494's tr000: z 3e4)."""
    from pyfmu_wrapper.diagnose.system.transient import EXPLAINS_Z
    from pyfmu_wrapper.diagnose.system.transient_fit import z_test

    d = _prepared(tmp_path)
    tr, te = d._masks(False), d._masks(True)
    f = d._fit(("friction",), tr, te)
    assert f.ok and abs(f.theta[0] - DF) < 0.005 * DF, f.theta
    assert z_test(f) <= EXPLAINS_Z, z_test(f)
