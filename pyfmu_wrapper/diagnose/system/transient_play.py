"""Transient records: play in the inerter gear named by the **predictable band** (issue 41).

A gear with play rattles: the inerter's far terminal crosses the gap and hits its stops, a chaotic
sequence of impacts (docs/diagnose-evidence.md, issue 41: the truth's own contact values leave chi2/n
12-380 in the accelerations). No simulation follows the rattle sample by sample, so the held-out
chi-square of :mod:`.transient` leaves every play single ``unexplained``. What a model of play does
predict is the **low band** -- the motion at the structure's modes, where the inerter acts while the
gap is closed and not while it is open (an amplitude-dependent loss of inertance) -- and how much the
rattle spreads it. This module scores candidates there:

* the band: the whitened residual's discrete Fourier transform on each record (the chain's start-up
  skipped), bins 0 < f <= BAND x the nominal's highest modal frequency (the rattle's 60-700 Hz
  contact content is outside; its low-frequency part is the spread below);
* the noise of each bin: the sensor's white share plus the **spread of the candidate's own
  simulations** (:func:`.transient_sim.spread`): the candidate simulated again with its nuisances
  perturbed -- the force by an independent realisation of the load cell's measured noise, and the
  gear contact (ki, ci: unknown, a nuisance of play; the band test's own is CONTACT, the paper's mesh
  stiffness as the truth's) by factors SPREAD_CONTACT -- the difference's periodogram smoothed over
  SMOOTH bins. Residual and spread are both differences of two rattles (truth and model, model and
  model), so their expected power is the same. For a model without play the contact does nothing and
  the spread is the response to the force's noise: the noise model of
  :func:`.transient.TransientDiagnosis.prepare`. One rule for every candidate;
* with play, plus its :func:`floor`: the residual's content above the band that the spread does not
  make and that is flat (the impacts folded by a sampling without an anti-alias filter), carried into
  the band;
* ``chi2 = sum 2 |E_k|^2 / (N s_k)`` over the band's bins (2 dof per bin and channel).

Play's gap is found on a log grid (GAPS, its best bracket sampled REFINE times finer, then a parabola
in log eps through the best three) by the Gaussian likelihood (chi-square plus the log of the noise:
the noise depends on the gap, and a wider gap rattles more); the nominal and every one-parameter single of the vocabulary (the REFIT best
refitted on the band, bounded Brent from its held-out fit) and friction (at its fit) are scored
**under play's noise** (its spread and floor at the fitted gap), so declaring the rattle as noise helps every
candidate alike. Play is named when (all of): the nominal does not explain the band (z > EXPLAINS_Z);
the gap's minimum is inside the grid; at least two records have their own minimum inside it and the
gap is > 3 std from 0 (std: the records' scatter, MAD); play's reduced band chi-square is at most
PLAY_RED; its band excess is at most PLAY_SHARE of the best other candidate's -- or, where other
candidates explain the band as well under play's noise (a small rattle's loss of inertance looks like
a lower inertance there), the content above the band separates them (:func:`_rattle_test`): each
model under its own noise, those without play leave the rattle there and play makes it in its spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ...physics.params import P_MODEL, P_ci, P_ki
from .transient_effects import BOUNDS, TEFFECTS, apply
from .transient_fit import residual, start_update
from .transient_sim import fastest_rate, simulate, spread

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_effects import Model
    from .transient_sim import TView

BAND = 3.0  #: band top: this many times the nominal's highest modal frequency
SMOOTH = 15  #: bins the spread's periodogram is averaged over
#: the play contact's perturbations (ki factor, ci factor): the truth's contact is unknown
SPREAD_CONTACT = ((0.5, 0.3), (2.0, 3.0))
GAPS = tuple(float(g) for g in np.geomspace(2e-5, 3e-3, 9))  #: the gap's grid [m]
#: the band test's gear contact (ki [N/m], ci [N s/m]): the paper's mesh stiffness, as the truth's
CONTACT = (2.0e7, 20.0)
FLOOR_TOP = 0.9  #: the floor (:func:`floor`) is measured from the band's top to this share of the fit's Nyquist
FLOOR_SPLIT = 4  #: in this many sub-bands (the lowest level counts)
PLAY_SHARE = 0.8  #: play's band excess at most this share of the best other candidate's (the shared noise)
PLAY_RED = 60.0  #: play's reduced band chi-square at most this
#: above the band, a candidate without play leaves the rattle when its excess there (z, under its own
#: noise) exceeds this (:func:`_rattle_test`)
RATTLE_Z = 20.0
#: ... and play, to win on the content above the band, explains the band to this reduced chi-square
RATTLE_RED = 2.0
EXPLAINS_Z = 5.0  #: the nominal explains the band when its z is at most this (as :mod:`.transient`)
START_PASSES = 1  #: start-state passes under each scored model (from the nominal's start)
REFINE = 3  #: the gap's bracket around its best grid point sampled this many times finer than GAPS
REFIT = 3  #: one-parameter singles refitted on the band: the best this many at their held-out values


class TransientDiagnosis(Protocol):
    """What the band test reads of :class:`.transient.TransientDiagnosis`."""

    views: list[TView]
    p_nom: ndarray
    sc: dict[str, tuple[float, ...]]
    noise_parts: dict[str, tuple[ndarray, ndarray | None]]

    def candidates(self) -> list[str]: ...


def _band_bins(v: TView, f_top: float) -> tuple[ndarray, int]:
    n = v.n_out - v.skip
    f = np.fft.rfftfreq(n, 1.0 / v.fs)
    return (f > 0) & (f <= f_top), n


@dataclass
class Score:
    """A model's band chi-square: its sum, dof, each record's reduced value, and each record's noise
    per band bin and channel (the variance of the whitened residual's transform / (n/2))."""

    chi2: float
    dof: int
    per: list[float]
    noise: list[ndarray]
    #: the Gaussian -2 log-likelihood's noise term, sum of 2 log s over bins and channels (with the
    #: chi-square: what a noise that depends on the parameters costs; each record's apart)
    logdet: list[float]
    #: with play: each record's floor per channel (:func:`floor`)
    floor: list[ndarray] = field(default_factory=list)
    #: above the band (to FLOOR_TOP x the fit's Nyquist frequency), under the model's own noise: the
    #: chi-square and its dof (0: not computed -- a shared noise, or too few bins)
    hi_chi2: float = 0.0
    hi_dof: int = 0

    @property
    def hi_excess(self) -> float:
        """The chi-square's excess over its dof above the band, in its std (z)."""
        return (self.hi_chi2 - self.hi_dof) / math.sqrt(2 * self.hi_dof) if self.hi_dof else 0.0

    @property
    def nll(self) -> float:
        return self.chi2 + float(sum(self.logdet))

    @property
    def red(self) -> float:
        return self.chi2 / max(self.dof, 1)


def band_chi2(
    td: TransientDiagnosis, mdl: Model, noise: list[ndarray] | None = None, hi_floor: list[ndarray] | None = None
) -> Score | None:
    """Model ``mdl`` on the band: its spread (with play: plus its :func:`floor`) in the noise, or the
    given ``noise`` (another model's: the shared likelihood); None when a simulation blows up. Above the
    band (``Score.hi_chi2``, own noise only): ``hi_floor``, a model with play's floors per record, added
    to a model without play's noise there (the folded flat content one is granted, the other is too)."""
    f_top = BAND * fastest_rate(td.p_nom) / (2 * math.pi)
    chi, dof, per, used, ld, fl = 0.0, 0, [], [], [], []
    hi_chi, hi_dof = 0.0, 0
    for j, v in enumerate(td.views):
        m = np.ones(v.n_out, bool)
        m[: v.skip] = False
        saved = v.z0.copy()
        d = None
        play = int(mdl.p[P_MODEL]) == 2
        try:
            for _ in range(START_PASSES):
                start_update(v, mdl, m)
            y = simulate(v, mdl.p, force_gain=mdl.gain)
            e = None if y is None else residual(v, mdl, m, sim=y)
            if e is not None and noise is None:
                # without play the contact's factors change nothing: one perturbation (the force's noise)
                d = spread(v, mdl.p, mdl.gain, SPREAD_CONTACT if play else SPREAD_CONTACT[:1], base=y)
        finally:
            v.z0 = saved
        if e is None or (noise is None and d is None):
            return None
        k, n = _band_bins(v, f_top)
        u = e[v.skip :][:, v.has]
        F = np.fft.rfft(u - u.mean(axis=0), axis=0)
        E = F[k]
        if noise is None:
            white = td.noise_parts[v.name][0] ** 2
            sp = smooth_power(d, v, n)  # type: ignore[arg-type]
            s = white + sp[k]
            hi = _above_bins(v, f_top, n)
            s_hi = white + sp[hi]
            if play:
                fl.append(floor(F, sp, white, v, f_top, n))
                s = s + fl[-1]
                s_hi = s_hi + fl[-1]
            elif hi_floor:
                s_hi = s_hi + hi_floor[j]
            if hi.sum() >= 16:
                hi_chi += float(np.sum(2 * np.abs(F[hi]) ** 2 / (n * s_hi)))
                hi_dof += 2 * int(hi.sum()) * u.shape[1]
        else:
            s = noise[j]
        c = float(np.sum(2 * np.abs(E) ** 2 / (n * s)))
        chi += c
        dof += 2 * E.size
        per.append(c)
        used.append(s)
        ld.append(float(2 * np.sum(np.log(s))))
    return Score(chi, dof, per, used, ld, fl, hi_chi, hi_dof)


def _above_bins(v: TView, f_top: float, n: int) -> ndarray:
    """The bins above the band up to FLOOR_TOP x the fit's Nyquist frequency (where :func:`floor` looks)."""
    fr = np.fft.rfftfreq(n, 1.0 / v.fs)
    return np.asarray((fr > f_top) & (fr <= FLOOR_TOP * 0.5 * v.fs))


def floor(F: ndarray, sp: ndarray, white: ndarray, v: TView, f_top: float, n: int) -> ndarray:
    """Per recorded channel: the residual's content that the play model's spread does not make and that is
    flat in frequency, carried into the band (variance of a whitened fit sample). What a sampling
    without an anti-alias filter folds of the impacts (60-700 Hz and up; the truth's contact, stiffer
    and shorter than any simulation's, in point samples where the simulation averages) is flat from 0 to
    the fit's Nyquist frequency; the rattle's own content rises with frequency (alternate impacts: their
    momenta cancel at low frequency) and is the spread's; the harmonics of a stick-slip or a stiffening
    spring fall with it, and a resonance above the band (an elastic inerter's) is a hump. So the range
    above the band (to FLOOR_TOP x the fit's Nyquist frequency) is cut into FLOOR_SPLIT equal
    sub-bands (fewer where a sub-band would hold fewer than 16 bins), each one's level the residual's
    median periodogram / ln 2 (the mean of a flat level, blind to a few harmonics) less the white share
    and the spread's median there, and the floor is the lowest level, at least 0 (0 without 16 bins)."""
    fr = np.fft.rfftfreq(n, 1.0 / v.fs)
    top = FLOOR_TOP * 0.5 * v.fs
    above = int(np.sum((fr > f_top) & (fr <= top)))
    m = min(FLOOR_SPLIT, above // 16)
    if m < 1:
        return np.zeros(white.size)
    edges = np.linspace(f_top, top, m + 1)
    levels = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        k = (fr > lo) & (fr <= hi)
        P = np.abs(F[k]) ** 2 / n
        levels.append(np.median(P, axis=0) / math.log(2.0) - white - np.median(sp[k], axis=0))
    return np.asarray(np.maximum(np.min(levels, axis=0), 0.0))


def smooth_power(d: list[ndarray], v: TView, n: int) -> ndarray:
    """The spread's power per rfft bin: the mean periodogram of the perturbed simulations' differences
    (whitened), averaged over SMOOTH bins."""
    from scipy.ndimage import uniform_filter1d

    P = np.mean(
        [np.abs(np.fft.rfft(x[v.skip :][:, v.has] - x[v.skip :][:, v.has].mean(axis=0), axis=0)) ** 2 / n for x in d],
        axis=0,
    )
    return np.asarray(uniform_filter1d(P, SMOOTH, axis=0, mode="nearest"))


def _score(
    td: TransientDiagnosis,
    effects: tuple[str, ...],
    theta: ndarray,
    noise: list[ndarray] | None = None,
    hi_floor: list[ndarray] | None = None,
) -> Score | None:
    mdl = apply(td.p_nom, effects, theta)
    if isinstance(mdl, str):
        return None
    if "play" in effects:
        mdl.p[P_ki], mdl.p[P_ci] = CONTACT
    return band_chi2(td, mdl, noise, hi_floor)


def play_gap(td: TransientDiagnosis) -> dict[str, Any]:
    """Play's gap on the band, its own spread in the noise: the grid GAPS; around its best interior
    point the bracket between its neighbours sampled REFINE times finer, and the gap the minimum of the
    parabola in log eps through the best of these points and its neighbours (the best point itself at
    the bracket's end). Each record's own minimum: the same on its own likelihood (its coarse minimum
    elsewhere: the parabola through that point and its coarse neighbours).
    Its std: the scatter of the records' minima (MAD) / sqrt(records) (the chi-square's curvature at the
    minimum says little); one record: unknown."""
    rows = [(g, _score(td, ("play",), np.array([g]))) for g in GAPS]
    chis = np.array([math.inf if r is None else r.nll for _, r in rows])
    per = np.array([np.add(r.per, r.logdet) if r is not None else [math.inf] * len(td.views) for _, r in rows])
    x = np.log(np.array(GAPS))
    i = int(np.argmin(chis))
    g_best, s_best = rows[i]
    fine: tuple[ndarray, ndarray, ndarray] | None = None
    if 0 < i < len(GAPS) - 1 and np.all(np.isfinite(chis[i - 1 : i + 2])):
        xs = [float(t) for t in np.linspace(x[i - 1], x[i + 1], 2 * REFINE + 1)]
        fx, fc, fp = [], [], []
        for t in xs:
            j = int(np.argmin(np.abs(x - t)))
            r = rows[j][1] if abs(x[j] - t) < 1e-9 else _score(td, ("play",), np.array([math.exp(t)]))
            if r is not None:
                fx.append(t)
                fc.append(r.nll)
                fp.append(np.add(r.per, r.logdet))
                if r.nll < chis[i] and (s_best is None or r.nll < s_best.nll):
                    g_best, s_best = math.exp(t), r
        fine = (np.array(fx), np.array(fc), np.array(fp))
        xm = _parabola_min(fine[0], fine[1])
        if xm is not None:
            s_try = _score(td, ("play",), np.array([math.exp(xm)]))
            if s_try is not None:
                g_best, s_best = math.exp(xm), s_try
    recs: list[float | None] = []
    for j in range(per.shape[1]):
        if fine is not None and int(np.argmin(per[:, j])) == i:
            recs.append(_parabola_min(fine[0], fine[2][:, j]) or float(fine[0][np.argmin(fine[2][:, j])]))
        else:
            recs.append(_parabola_min(x, per[:, j]))
    rec_gaps = [math.exp(r) for r in recs if r is not None]
    # robust to one record whose minimum says little (a hammer record's few impacts): the MAD's std
    std = (
        float(1.4826 * np.median(np.abs(np.subtract(rec_gaps, np.median(rec_gaps)))) / math.sqrt(len(rec_gaps)))
        if len(rec_gaps) > 1
        else math.inf
    )
    return {
        "grid": [[g, c] for g, c in zip(GAPS, chis.tolist())],
        "fine": [] if fine is None else [[math.exp(t), c] for t, c in zip(fine[0].tolist(), fine[1].tolist())],
        "interior": 0 < i < len(GAPS) - 1,
        "per_record_gap": rec_gaps,
        "gap": g_best,
        "std": std,
        "score": s_best,
    }


def _parabola_min(x: ndarray, c: ndarray) -> float | None:
    """The minimum of the parabola through the lowest point of c(x) and its two neighbours (None: the
    lowest point at an end of the grid, or no finite minimum)."""
    i = int(np.argmin(c))
    if not 0 < i < len(x) - 1 or not np.all(np.isfinite(c[i - 1 : i + 2])):
        return None
    a, b, _ = np.polyfit(x[i - 1 : i + 2], c[i - 1 : i + 2], 2)
    return float(np.clip(-b / (2 * a), x[i - 1], x[i + 1])) if a > 0 else None


def refit_single(td: TransientDiagnosis, e: str, th0: float, noise: list[ndarray]) -> tuple[float, Score | None]:
    """A one-parameter single refitted on the band under the shared ``noise`` (bounded Brent around
    its held-out value)."""
    from scipy.optimize import minimize_scalar

    sc = td.sc[e][0]
    lo, hi = BOUNDS.get(f"{e}.{TEFFECTS[e][0][0]}", (-np.inf, np.inf))
    a, b = max(th0 - 20 * sc, lo), min(th0 + 20 * sc, hi)
    cache: dict[float, Score | None] = {}

    def f(x: float) -> float:
        s = cache[x] = _score(td, (e,), np.array([x]), noise)
        return 1e300 if s is None else s.chi2

    r = minimize_scalar(f, bounds=(a, b), method="bounded", options={"xatol": 0.02 * sc, "maxiter": 12})
    x = float(r.x)
    return x, cache[x] if x in cache else _score(td, (e,), np.array([x]), noise)


def _rattle_test(td: TransientDiagnosis, ps: Score, others: dict[str, dict[str, Any]], ex_p: float) -> dict[str, Any]:
    """When the band does not separate play from other candidates (under play's noise they explain it
    as well: a small rattle's loss of inertance is a lower inertance there), the content **above the
    band**, each model under its own noise: what a model without play leaves there (the rattle: the
    truth's impacts) against its own noise (the sensors' and the force noise's response) is an excess a
    model with play makes in its own spread (two rattles differ by about as much as truth and model).
    Play's floor (:func:`floor`: flat content folded by a sampling without an anti-alias filter) is in
    every model's noise there: a friction truth's stick-slip, point-sampled at 256 Hz, folds flat too
    (seed 9494 tr004: without it in the rivals' noise, play's floor alone separated play from the true
    friction). Separates when every other candidate whose band excess play does not undercut by
    PLAY_SHARE leaves an excess above the band (z > RATTLE_Z), play's own there is at most RATTLE_Z
    and PLAY_SHARE of the smallest of theirs, and play explains the band itself to within RATTLE_RED
    of its noise (reduced band chi-square; the true friction of tr004 left play 9.9 there, play truths
    0.6-1.1: play's rattle spread above the band covers a stick-slip's content too)."""
    rivals = [k for k, o in others.items() if (o["chi2"] - o["dof"]) <= 0 or ex_p > PLAY_SHARE * (o["chi2"] - o["dof"])]
    out: dict[str, Any] = {"play_z": ps.hi_excess if ps.hi_dof else None, "rivals": {}, "separates": False}
    if not ps.hi_dof or not rivals:
        return out
    done: dict[bytes, float | None] = {}  # a rival at a value that leaves the nominal (0) is scored once
    for k in rivals:
        eff, th = ((), np.zeros(0)) if k == "nominal" else ((k,), np.atleast_1d(np.asarray(others[k]["value"], float)))
        mdl = apply(td.p_nom, eff, th)
        key = b"" if isinstance(mdl, str) else mdl.p.tobytes() + np.array([mdl.gain, *mdl.offset]).tobytes()
        if key not in done:
            own = _score(td, eff, th, hi_floor=ps.floor)
            done[key] = None if own is None or not own.hi_dof else own.hi_excess
        out["rivals"][k] = done[key]
    zs = list(out["rivals"].values())
    if all(z is not None and z > RATTLE_Z for z in zs) and ps.red <= RATTLE_RED:
        out["separates"] = ps.hi_excess <= min(RATTLE_Z, PLAY_SHARE * min(z for z in zs if z is not None))
    return out


def play_test(td: TransientDiagnosis, fitted: dict[str, ndarray]) -> dict[str, Any]:
    """The band test (module doc): ``fitted`` holds each single's held-out fit or default start
    (effect -> SI values; an effect missing: 0).
    Returns the scores, the gap and whether play is named."""
    nom = _score(td, (), np.zeros(0))
    out: dict[str, Any] = {"band_hz": BAND * fastest_rate(td.p_nom) / (2 * math.pi), "named": False}
    if nom is None:
        out["why"] = "the nominal's simulation failed"
        return out
    out["nominal"] = {"chi2": nom.chi2, "dof": nom.dof}
    z_nom = (nom.chi2 - nom.dof) / math.sqrt(2 * nom.dof)
    if z_nom <= EXPLAINS_Z:
        out["why"] = f"the nominal explains the band (z {z_nom:.3g} <= {EXPLAINS_Z:g})"
        return out
    pg = play_gap(td)
    out["play"] = {k: pg[k] for k in ("gap", "std", "interior", "grid", "fine", "per_record_gap")}
    ps: Score | None = pg["score"]
    if ps is None:
        out["why"] = "play's simulations failed"
        return out
    out["play"].update(chi2=ps.chi2, dof=ps.dof, red=ps.red, per_record=ps.per, floor=[f.tolist() for f in ps.floor])
    out["play"]["interior_records"] = len(pg["per_record_gap"])
    # the shared likelihood: every other candidate under play's noise (its spread at its gap), so the
    # rattle declared as noise helps every candidate alike
    shared = ps.noise
    n2 = _score(td, (), np.zeros(0), shared)
    others: dict[str, dict[str, Any]] = {}
    if n2 is not None:
        others["nominal"] = {"chi2": n2.chi2, "dof": n2.dof}
    at: dict[str, float] = {}  # each one-parameter single at its held-out value (else its default start)
    for e in td.candidates():
        if e == "play" or len(TEFFECTS[e][0]) != 1:
            continue
        th0 = float(fitted[e][0]) if e in fitted else 0.0
        s0 = _score(td, (e,), np.array([th0]), shared)
        if s0 is not None:
            at[e] = th0
            others[e] = {"value": th0, "chi2": s0.chi2, "dof": s0.dof}
    for e in sorted(at, key=lambda k: others[k]["chi2"])[:REFIT]:  # the best refitted on the band
        x, s = refit_single(td, e, at[e], shared)
        if s is not None and s.chi2 < others[e]["chi2"]:
            others[e] = {"value": x, "chi2": s.chi2, "dof": s.dof, "refitted": True}
    if "friction" in fitted:
        s = _score(td, ("friction",), fitted["friction"], shared)
        if s is not None:
            others["friction"] = {"value": fitted["friction"].tolist(), "chi2": s.chi2, "dof": s.dof}
    out["others"] = others
    if not others:
        out["why"] = "no other candidate could be scored"
        return out
    best = min(others, key=lambda k: others[k]["chi2"])
    ex_o = others[best]["chi2"] - others[best]["dof"]
    ex_p = ps.chi2 - ps.dof
    out["best_other"] = best
    out["share"] = ex_p / ex_o if ex_o > 0 else math.inf
    why = []
    if not pg["interior"]:
        why.append("the gap's band minimum is at the end of its grid")
    if ex_o <= 0 or ex_p > PLAY_SHARE * ex_o:
        rattle = _rattle_test(td, ps, others, ex_p)
        out["above_band"] = rattle
        if not rattle["separates"]:
            why.append(f"play leaves {out['share']:.3g} of the band excess of {best} (> {PLAY_SHARE:g})")
    if ps.red > PLAY_RED:
        why.append(f"play's reduced band chi-square {ps.red:.3g} > {PLAY_RED:g}")
    if len(pg["per_record_gap"]) < 2:
        why.append("fewer than two records have their own band minimum inside the gap's grid")
    elif not (pg["gap"] > 3 * pg["std"]):
        why.append("the records' own gaps scatter: the gap is not > 3 std from 0")
    out["named"] = not why
    out["why"] = "; ".join(why)
    return out
