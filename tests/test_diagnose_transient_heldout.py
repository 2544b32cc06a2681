"""diagnose on transient records: the held-out stage (each record alone, each record predicted from
the others) by Gauss-Newton steps from the all-records fit (``transient_heldout``), against the full
trust-region fits it replaces: exact where the parameters enter the residual linearly, within a small
share of the stated std on a viscous truth, and a drift between records still disagrees."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from pyfmu_wrapper.diagnose.data import load_dataset
from pyfmu_wrapper.diagnose.records import write_record
from pyfmu_wrapper.diagnose.system.transient import TransientDiagnosis
from pyfmu_wrapper.diagnose.system.transient_fit import fit, warm_start
from pyfmu_wrapper.diagnose.system.transient_heldout import AGREE_P, HeldOut
from pyfmu_wrapper.diagnose.system.transient_truth import Truth, force_signal, measure

BASE = {"mass": 100.0, "stiffness": 4.0e4, "damping": 100.0, "force_amplitude": 200.0}
TMD = {"mass": 9.0, "stiffness": 4.0e3, "damping": 15.0, "inertance": 1.0, "inerter": "ideal"}
NOISE = {"x": 0.01, "y": 0.01, "xdd": 0.01, "ydd": 0.01, "force": 0.005}
RANDOM = ("random", {"f_lo": 1.0, "f_hi": 8.0})
SWEEP = ("sweep_lin", {"f0": 1.5, "f1": 5.0})
DECAY = ("decay", {})


def make(path, kinds, changes=None, offsets=None, gains=None, fs=256.0, T=30.0, seed=11):
    """One record per kind (the truth simulated at 8 fs, sampled at fs); per record an x / y sensor
    offset (m) added to the measured displacements and a load-cell gain error g (the measured force is
    the true one / (1 + g))."""
    path.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    recs = []
    for i, (kind, kw) in enumerate(kinds):
        t = np.arange(0.0, T, 1.0 / (8 * fs))
        F = force_signal(kind, rng, T, 60.0 if kind == "random" else 150.0, **kw)
        z0 = np.array([0.005, 0.0, 0.01, 0.0]) if kind == "decay" else None
        sig = Truth(BASE, TMD, T, **(changes or {})).simulate(F, t, z0)
        if kind == "decay":
            sig.pop("force")
        m = measure(sig, t, 8, rng, NOISE, {})
        if offsets is not None:
            m["x"] = m["x"] + offsets[i][0]
            m["y"] = m["y"] + offsets[i][1]
        if gains is not None and "force" in m:
            m["force"] = m["force"] / (1 + gains[i])
        write_record(path / f"r{i}.csv", m)
        recs.append({"file": f"r{i}.csv", "kind": "decay" if kind == "decay" else "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": {}}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))
    return path


def held(path, effects):
    """The diagnosis prepared, and the held-out stage of ``effects`` at their fit on all records."""
    d = TransientDiagnosis(load_dataset(path))
    d.prepare()
    allm = d._masks(None)
    final = d._fit(effects, allm, None)
    assert final.ok
    return d, HeldOut(d.views, d.p_nom, d.sc, effects, allm, final, warm_start(final, d.sc), d.noise_parts)


def full(d, h, S):
    """The full trust-region fit of the records S from the all-records fit (the stage's old way)."""
    return fit([d.views[j] for j in S], d.p_nom, h.effects, [h.masks[j] for j in S], None, d.sc, **h.warm)


@pytest.mark.parametrize(
    ("effects", "kinds", "offsets", "gains"),
    [
        # sensor offsets enter the residual linearly, and so does a free decay's start state (a nuisance)
        (("sensor_offset",), [RANDOM, SWEEP, DECAY], [(1e-4, -2e-4), (3e-4, 0.0), (-1e-4, 1e-4)], None),
        # a load-cell gain error: the response is linear in the force
        (("force_error",), [RANDOM, SWEEP, RANDOM], None, [0.02, 0.03, 0.025]),
    ],
    ids=["sensor_offset_with_decay", "force_error"],
)
def test_one_step_equals_the_full_fits_where_the_parameters_enter_linearly(tmp_path, effects, kinds, offsets, gains):
    """Each record alone and each set of all records but one: one Gauss-Newton step from the
    all-records fit is the least-squares answer itself when the residual is linear in the unknowns; it
    equals the full trust-region fit to 1e-6 of the parameter's scale, and so do the stds (a decay's
    start state fitted with the parameters in both)."""
    d, h = held(make(tmp_path, kinds, offsets=offsets, gains=gains), effects)
    lin = h._linear()
    assert lin is not None
    n = len(d.views)
    for S in [[i] for i in range(n)] + [[j for j in range(n) if j != i] for i in range(n)]:
        got = lin.solve(S)
        f = full(d, h, S)
        assert got is not None and f.ok
        theta, std, _ = got
        np.testing.assert_allclose(theta, f.theta, rtol=0, atol=1e-6 * np.abs(f.theta).max())
        np.testing.assert_allclose(std, f.std, rtol=1e-3)
    if offsets is not None:  # the per-record values are the records' own offsets (within 4 std)
        a = h.agreement()
        for r, o in zip(a["records"], offsets):
            p = r["params"]["sensor_offset.x_offset"]
            assert abs(p["value"] - o[0]) < 4 * p["std"] + 2e-6, (p, o)
        assert not a["agree"]  # different offsets per record: a drift
    assert h.refitted == []


@pytest.mark.parametrize("drift", [False, True], ids=["viscous", "viscous_drifts"])
def test_agreement_and_held_out_records_equal_the_full_fits_on_a_viscous_truth(tmp_path, drift):
    """Viscous damping dc = 10 N s/m (or 6 / 10 / 14 N s/m, a drift between records) in a random
    record, a sweep and a free decay: the linearised per-record values equal the full fits within 0.05
    of their std (1 std under the drift), the agreement's chi-square (to 5 %) and verdict match (the drift still disagrees), and each
    record predicted from the others closes the same share of its gap (to 1e-4; 1e-3 under the drift,
    where the two differ by the start state a full fit refreshes once; a disagreement names nothing, so
    the diagnosis does not predict records then) with the same chi-square before
    (the nominal's, a decay's start state fitted)."""
    from pyfmu_wrapper.diagnose.system.transient_fit import chi2_of

    dcs = (6.0, 10.0, 14.0) if drift else (10.0, 10.0, 10.0)
    path = tmp_path / "ds"
    path.mkdir()
    recs = []
    for i, (kind, dc) in enumerate(zip([RANDOM, SWEEP, DECAY], dcs)):  # one record per damping, merged
        make(tmp_path / f"p{i}", [kind], changes={"dc": dc}, seed=20 + i)
        (path / f"r{i}.csv").write_bytes((tmp_path / f"p{i}" / "r0.csv").read_bytes())
        recs.append({"file": f"r{i}.csv", "kind": "decay" if kind == DECAY else "transient"})
    doc = {"level": "system", "nominal": {"base": BASE, "tmd": TMD}, "records": recs, "acquisition": {}}
    (path / "dataset.yaml").write_text(yaml.safe_dump(doc))

    d, h = held(path, ("viscous",))
    a, b = h.agreement(), h.by_record()
    assert h.refitted == [] and len(a["records"]) == 3 and len(b) == 3
    assert not any(r["full_fit"] for r in a["records"] + b)
    old = HeldOut(d.views, d.p_nom, d.sc, h.effects, h.masks, h.final, h.warm, d.noise_parts)
    old._lin_tried = True  # no linearisation: the full fits, as before
    a0, b0 = old.agreement(), old.by_record()
    assert len(old.refitted) == 6
    for i, (r, r0, dc) in enumerate(zip(a["records"], a0["records"], dcs)):
        p, p0 = r["params"]["viscous.delta_damping"], r0["params"]["viscous.delta_damping"]
        assert abs(p["value"] - p0["value"]) < (1.0 if drift else 0.05) * p0["std"], (p, p0)
        assert abs(p["std"] / p0["std"] - 1) < 0.02, (p, p0)
        assert abs(p["value"] - dc) < 4 * p["std"] + 0.02 * dc, (p, dc)  # and the truth
        # where they differ (a drift: 4 N s/m from the all-records fit), the start state that a full fit
        # refreshes once is the difference: converged under each value (START_PASSES passes), the
        # linearised value fits the record at least as well
        c, c0 = (_converged_chi2(d, h, i, x) for x in (p["value"], p0["value"]))
        assert c <= c0 + 0.5, (c, c0)
    assert a["agree"] is (not drift) and a0["agree"] is (not drift)
    assert (a["p_value"] < AGREE_P) is drift
    assert abs(a["chi2"] - a0["chi2"]) <= 0.05 * a0["chi2"] + 0.2, (a["chi2"], a0["chi2"])
    for r, r0 in zip(b, b0):
        assert abs(r["gap_closed"] - r0["gap_closed"]) < (1e-3 if drift else 1e-4), (r, r0)
        assert abs(r["chi2_after"] / r0["chi2_after"] - 1) < (1e-2 if drift else 1e-3), (r, r0)
    # the nominal's chi-square before, a decay's start state by one checked step: the nominal's full fit
    nom = fit(d.views, d.p_nom, (), h.masks, None, d.sc)
    for r, v, e, m in zip(b, d.views, nom.resid, h.masks):
        c0 = chi2_of([v], [e], [m])[0]
        assert abs(r["chi2_before"] / c0 - 1) < 1e-6, (r["chi2_before"], c0)


def _converged_chi2(d, h, i, value):
    """Record i's chi-square at the parameter ``value``, its start state converged (START_PASSES passes)."""
    from pyfmu_wrapper.diagnose.system.transient import START_PASSES
    from pyfmu_wrapper.diagnose.system.transient_effects import apply
    from pyfmu_wrapper.diagnose.system.transient_fit import residual, start_update

    v, m = d.views[i], h.masks[i]
    mdl = apply(d.p_nom, h.effects, np.array([value]))
    z = v.z0.copy()
    try:
        for _ in range(START_PASSES):
            start_update(v, mdl, m)
        e = residual(v, mdl, m)
    finally:
        v.z0 = z
    return float(np.sum(e[:, v.has][m] ** 2))
