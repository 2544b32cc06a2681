"""The frame diagnosis: which effect of the frame unit's vocabulary, at which element, explains the
transient records **to the noise** (output error, every record simulated exactly, :mod:`.model`).

1. Views: each record's force (the model's input; zero for a free decay) and response channels, the
   noise std of every channel from its fourth differences
   (:func:`pyfmu_wrapper.diagnose.system.transient_sim.robust_noise`) with the nominal's response to
   the force channel's own noise added, so that chi2 / dof ~ 1 means "explained to the noise". A
   record that does not start at rest (its first samples off the nominal's start from rest) gets its
   start state fitted (linearly: the free responses projected out of its residual).
2. Candidates: every effect of the unit's vocabulary (:data:`pyfmu_wrapper.models.frame_model.effects.
   LINEAR`) at every element: each storey's mass, stiffness and damping, the TMD's mass, stiffness,
   damping (``viscous``) and inertance, the force's gain, each recorded channel's gain.
3. Singles: each candidate scanned on a grid of its size (a mode shifted by more than its bandwidth
   is far outside the linearisation) and one Gauss-Newton step from the grid's best (an effect below
   the grid's step), the best refined by nonlinear least squares, and so are the ones whose linearised
   step removes most of the whole records' chi2 (near the noise the scan ranks by its own scatter)
   (:func:`scipy.optimize.least_squares`). Pairs: the FIRSTS best singles, each with the candidates
   whose linearised gain at that single's solution is largest (scanned and refined likewise).
4. Selection by chi2 against the noise: an effect is named when it lowers chi2 by more than
   SIGNIFICANT times the residual's chi2 per dof (a scale-free test) and its size is > 3 std from 0;
   a second one when it does so again beside the first (the residual whitened by the noise's
   covariance, a spurious second effect gains ~ chi2(1): at most ~20 measured on single-effect sets). Candidates within AMBIGUOUS of the named
   one's chi2 explain the data as well: the verdict lists them. The named set leaving chi2 / dof
   above EXPLAINED: ``unexplained``, with where the residual lives.
5. The work is bounded: the search stops after CPU_BUDGET seconds and the verdict says what was not
   tried.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from .. import progress
from .model import FrameModel, Simulator

if TYPE_CHECKING:
    from numpy import ndarray

    from ..data import Dataset

SIGNIFICANT = 60.0  #: an effect is named when it lowers chi2 by this many times chi2 / dof
SIGNIFICANT_ROOT = 0.5  #: ... or by this many sqrt(dof) times chi2 / dof, if more
AMBIGUOUS = 10.0  #: a candidate within this many chi2 / dof of the named one explains the data as well
EXPLAINED = 1.1  #: chi2 / dof at most this (or within 6 std of its dof): explained to the noise (measured: 0.96-1.04)
BAND_Z = 8.0  #: a band's residual this many std above its dof: unexplained (measured: <= 4 after the right effects, 15 with hammer pulses of 10 samples)
CPU_BUDGET = 100.0  #: CPU seconds of the search
FIRSTS = 3  #: singles each paired with seconds
SECONDS = 5  #: seconds scanned per first
REFINE = 6  #: singles refined after the scan
SUB_HZ = (
    1000.0  #: simulation steps per second at least (2 per sample at least; the force a cubic spline between samples)
)
SCAN_HZ, SCAN_PER_MODE = 200.0, 10.0  #: the scans' sampling: at least this rate and samples per period of the top mode
FRICTION_SLOPES = (1e2, 3e2, 1e3, 3e3, 1e4, 1e5)  #: s/m: the friction law's regularisation slopes tried
REST_Z = 6.0  #: a record whose first samples are this many noise std off the nominal's start from rest is not at rest
#: the scan of each structural candidate's size, relative to its nominal value
GRID = {"default": np.linspace(-0.5, 0.5, 21), "damping": np.array([-0.9, -0.6, -0.3, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0])}


@dataclass(frozen=True)
class Cand:
    """One candidate: an effect of the vocabulary at one element."""

    effect: str
    where: Any  #: storey number, channel column, or None
    element: str
    param: str
    scale: float  #: the unit of the fitted variable (the nominal value, or 1 for a gain)
    kind: str  #: struct | gain | force

    @property
    def key(self) -> str:
        return f"{self.effect}@{self.element}.{self.param}"

    @property
    def label(self) -> str:
        return f"{self.effect} at {self.element}"


@dataclass
class View:
    name: str
    t: ndarray
    u: ndarray  #: the measured force (zero: a free decay)
    meas: ndarray  #: (samples, channels)
    channels: list[str]
    sigma: ndarray  #: noise std per channel
    raw_noise: ndarray
    sim: Simulator
    whiten: Any = None  #: (u, beta) per frequency bin: the whitening of :meth:`FrameDiagnosis._input_noise`
    weight: Any = None  #: (bins,): the real FFT's Parseval weights
    sensor: Any = (
        None  #: (bins, channels): the sensor noise's std per frequency bin (without the force noise's response)
    )
    scan_q: int = 1  #: the scans use every scan_q-th sample
    ssim: Any = None  #: the simulation on that grid
    fsim: Any = None  #: the simulation with friction (twice the sub-steps)
    free_start: bool = False  #: its start state is fitted
    free_decay: bool = False


@dataclass
class Fit:
    cands: tuple[Cand, ...]
    u: ndarray  #: scaled values
    chi2: float
    std: ndarray
    ok: bool = True
    reason: str = ""
    resid: list[ndarray] = field(default_factory=list)

    @property
    def effects(self) -> list[str]:
        return [c.effect for c in self.cands if c.kind != "slope"]

    @property
    def elements(self) -> list[str]:
        return [c.element for c in self.cands if c.kind != "slope"]

    @property
    def label(self) -> str:
        return " + ".join(c.label for c in self.cands if c.kind != "slope") or "nominal"

    def values(self) -> dict[str, tuple[float, float]]:
        return {
            c.key: (float(u * c.scale), float(s * c.scale))
            for c, u, s in zip(self.cands, self.u, self.std, strict=True)
        }


class FrameDiagnosis:
    """The frame diagnosis of a dataset (module doc)."""

    def __init__(self, ds: Dataset, budget: float = CPU_BUDGET) -> None:
        from ...models.frame_model import UNIT
        from ..system.transient_sim import robust_noise

        assert UNIT.effects is not None
        self.vocab = UNIT.effects
        self.ds = ds
        self.model0 = FrameModel.from_nominal(ds.nominal)
        self.budget = budget
        self.cpu0 = time.process_time()
        self.wall0 = time.monotonic()
        self.not_tried: list[str] = []
        self.notes: list[str] = []
        self.views: list[View] = []
        self._cache: dict[tuple[Any, ...], list[ndarray]] = {}  #: the structural changes -> the simulated records
        top = self.model0.modes_hz()[-1]
        for r in ds.records:
            t = np.asarray(r["t"], float)
            h = float(t[-1] - t[0]) / (t.size - 1)
            if np.max(np.abs(np.diff(t) - h)) > 0.01 * h:
                from ..errors import DataError

                raise DataError(
                    f"{ds.path / r.name}, column 't': a transient record must be uniformly sampled (spacing "
                    f"varies by more than 1 % of dt = {h:.6g} s)"
                )
            chans = [c for c in r.columns if c not in ("t", "force")]
            meas = np.column_stack([np.asarray(r[c], float) for c in chans])
            u = np.asarray(r["force"], float) if r.has("force") else np.zeros(t.size)
            raw = np.array([robust_noise(meas[:, k]) for k in range(len(chans))])
            sub = max(2, math.ceil(SUB_HZ * h))  # sub-steps: at least SUB_HZ steps per second
            sim = Simulator(chans, ds.acquisition, h, sub)
            fsim = Simulator(chans, ds.acquisition, h, 2 * sub)
            # the scans compare every q-th sample, simulated on that grid: SCAN_PER_MODE samples per
            # period of the nominal's top mode (at least SCAN_HZ per second)
            q = max(1, int(1.0 / (h * max(SCAN_HZ, SCAN_PER_MODE * top))))
            ssim = Simulator(chans, ds.acquisition, h * q, max(2, math.ceil(SUB_HZ * h * q)))
            self.views.append(
                View(
                    r.name,
                    t,
                    u,
                    meas,
                    chans,
                    raw.copy(),
                    raw,
                    sim,
                    scan_q=q,
                    ssim=ssim,
                    fsim=fsim,
                    free_decay=not r.has("force"),
                )
            )
        self._input_noise()
        self.cands = self._candidates()
        rest = self.residuals((), np.zeros(0), whiten=False)
        assert rest is not None
        for v, r in zip(self.views, rest, strict=True):  # start at rest?
            k0 = max(3, int(0.02 / v.sim.h))
            R = r.reshape(-1, len(v.channels))
            R = R - np.mean(R, axis=0)  # a sensor's offset is not a start off rest
            if v.free_decay or float(np.max(np.abs(R[:k0]))) > REST_Z:
                v.free_start = True
        self.nominal = self._evaluate(())
        self.dof = sum(v.meas.size - len(v.channels) for v in self.views) - sum(
            2 * (self.model0.n + 1) for v in self.views if v.free_start
        )

    # -- the model --------------------------------------------------------------------------------

    def _input_noise(self) -> None:
        """The noise of each record as a spectrum (module doc, step 1): each channel's sensor noise (white,
        its std from the fourth differences of the nominal's residual) and the force channel's
        white noise through the nominal (the measured force drives the model: its noise reaches every
        channel, coherently, resonantly near the modes). Per frequency bin that covariance is
        S = D + a a^H (D the sensors' variances, a the force noise's response); the residual is
        whitened by W = (I - beta u u^H) D^-1/2 with u = D^-1/2 a / |D^-1/2 a|, beta = 1 - 1 / sqrt(1 +
        |D^-1/2 a|^2), so that W^H W = S^-1: its chi2 is chi2(dof) under the noise, and a fit cannot
        pass off the force noise's resonant response as an effect."""
        from ..system.transient_sim import robust_noise

        for v in self.views:
            N = v.u.size
            f = np.fft.rfftfreq(N, v.sim.h)
            sf = 0.0 if v.free_decay else robust_noise(v.u)
            G = v.sim.response(self.model0, 2 * np.pi * f)  # (bins, channels)
            f_lo = max(2.0 * self.model0.modes_hz()[-1], 0.25 * f[-1])  # above the modes: noise
            # the force channel's noise per bin: white, from its fourth differences (robust to impulses;
            # its periodogram cannot tell a broadband force, a hammer's, from noise)
            SF = np.full(f.size, sf**2)
            # the sensor noise from the fourth differences of the nominal's residual (what the measured
            # force explains, e.g. a broadband force's direct term in the accelerations, taken out),
            # less the force noise's share there (it reaches the residual through the model)
            res0 = v.meas - v.sim.run(self.model0, v.u)
            est = np.array([robust_noise(res0[:, k]) for k in range(len(v.channels))])
            w4 = (2 * np.sin(np.pi * f * v.sim.h)) ** 8
            g4 = (SF[:, None] * np.abs(G) ** 2 * w4[:, None]).sum(axis=0) / w4.sum()
            D = np.empty((f.size, len(v.channels)))
            for k, ch in enumerate(v.channels):
                c = v.sim.chains.get(ch)
                if c is None or c.type is None:
                    D[:, k] = max(est[k] ** 2 - g4[k], 0.05 * est[k] ** 2)
                else:  # white after the filter and/or white before it (coloured by it)
                    H2 = np.abs(c.response(2 * np.pi * f)) ** 2
                    # never below the fourth differences' white level (a fit that took the force's
                    # content for noise and subtracted it must not leave a channel without noise)
                    white = max(est[k] ** 2 - g4[k], 0.05 * est[k] ** 2)
                    D[:, k] = np.maximum(noise_psd(res0[:, k], f, H2, SF * np.abs(G[:, k]) ** 2, f_lo), white)
            sensor = np.sqrt(np.mean(D, axis=0))
            v.raw_noise = sensor
            a = (
                np.sqrt(SF)[:, None] * G / np.sqrt(D)
            )  # the force noise's share, in units of each channel's sensor noise
            s2 = np.sum(np.abs(a) ** 2, axis=1)
            v.whiten = (a / np.sqrt(np.maximum(s2, 1e-300))[:, None], 1.0 - 1.0 / np.sqrt(1.0 + s2))
            wt = np.full(f.size, math.sqrt(2.0 / N))
            wt[0] = 0.0  # the mean of every channel is left out: a sensor's offset (bias) is not the model's
            if N % 2 == 0:
                wt[-1] = math.sqrt(1.0 / N)
            v.weight = wt
            v.sigma = np.sqrt(sensor**2 + np.mean(SF[:, None] * np.abs(G) ** 2, axis=0))
            v.sensor = np.sqrt(D)

    def _candidates(self) -> list[Cand]:
        from ...models.frame_model.effects import LINEAR

        m = self.model0
        out = []
        for e in LINEAR:
            eff = self.vocab[e]
            par = eff.params[0].name
            if eff.per == "storey":
                for i in range(1, m.n + 1):
                    sc = m.value(e, i)
                    if e == "storey_damping":
                        sc = max(sc, 0.01 * math.sqrt(m.stiffnesses[i - 1] * m.masses[i - 1]))
                    out.append(Cand(e, i, eff.at(i), par, sc, "struct"))
            elif eff.per == "channel":
                chans = sorted({c for v in self.views for c in v.channels}, key=_channel_order)
                out += [Cand(e, c, eff.at(c), par, 1.0, "gain") for c in chans]
            elif e == "force_error":
                if not all(v.free_decay for v in self.views):
                    out.append(Cand(e, None, eff.element, par, 1.0, "force"))
            else:
                sc = m.value(e)
                if e == "viscous":
                    sc = max(sc, 0.01 * math.sqrt(m.stiffness * max(m.mass, 1e-9)))
                elif e == "inertance":
                    sc = max(sc, 0.1 * m.mass)
                out.append(Cand(e, None, eff.element, par, sc, "struct"))
        return out

    def residuals(
        self, cands: tuple[Cand, ...], u: ndarray, whiten: bool = True, short: bool = False
    ) -> list[ndarray] | None:
        """The whitened residual of every record (measured - model, start states projected out where
        fitted, whitened per frequency bin: :meth:`_input_noise`; ``whiten`` False: in the time domain,
        divided by sigma); None for a non-physical model."""
        deltas: dict[tuple[str, Any], float] = {}
        gains: dict[str, float] = {}
        fg = 0.0
        fric: tuple[float, float] | None = None
        for c, x in zip(cands, u, strict=True):
            if c.kind == "struct":
                deltas[(c.effect, c.where)] = deltas.get((c.effect, c.where), 0.0) + float(x) * c.scale
            elif c.kind == "gain":
                gains[c.where] = gains.get(c.where, 0.0) + float(x)
            elif c.kind == "friction":
                fric = (float(x) * c.scale, float(c.where))
            elif c.kind == "slope":  # log10 of the friction law's slope, fitted beside its force
                if fric is None or not -1.0 < float(x) < 8.0:
                    return None
                fric = (fric[0], 10.0 ** float(x))
            else:
                fg += float(x)
        model = self.model0.changed(deltas) if deltas else self.model0
        if model.physical() or fg <= -0.9 or (fric is not None and fric[0] < 0):
            return None
        key: tuple[Any, ...] = tuple(sorted((e, str(w), round(d, 12)) for (e, w), d in deltas.items() if d != 0.0))
        if fric is not None:
            key += (("friction", fric),)
        if short:  # the scans: every scan_q-th sample, simulated on that grid (less work)
            key += ("short",)
            whiten = False
        ys = self._cache.get(key)
        if ys is None:
            if fric is not None and fric[0] > 0:
                ys = [
                    (v.fsim if not short else v.ssim).run(model, v.u if not short else v.u[:: v.scan_q], fric)
                    for v in self.views
                ]
            elif short:
                ys = [v.ssim.run(model, v.u[:: v.scan_q]) for v in self.views]
            else:
                ys = [v.sim.run(model, v.u) for v in self.views]
            if len(self._cache) > 16:  # bounded memory: a long record's simulation is megabytes
                self._cache.clear()
            self._cache[key] = ys
        out = []
        for v, y in zip(self.views, ys, strict=True):
            g = np.array([1.0 + gains.get(c, 0.0) for c in v.channels]) / (1.0 + fg)
            meas = v.meas[:: v.scan_q] if short else v.meas
            n = meas.shape[0]
            r = (meas - y * g) / v.sigma
            if v.free_start:
                P = (v.ssim if short else v.sim).free(model, n) * (g / v.sigma)[None, :, None]
                nc = len(v.channels)  # with each channel's offset (its mean is left out anyway)
                P = np.concatenate([P, np.broadcast_to(np.eye(nc)[None], (n, nc, nc))], axis=2)
                P = P.reshape(-1, P.shape[2])
                rf = r.reshape(-1)
                sc = np.sqrt(np.einsum("ij,ij->j", P, P)) + 1e-300
                Ps = P / sc
                coef = np.linalg.lstsq(np.einsum("ki,kj->ij", Ps, Ps), np.einsum("ki,k->i", Ps, rf), rcond=1e-12)[0]
                r = (rf - np.einsum("ki,i->k", Ps, coef)).reshape(r.shape)
            if whiten:
                X = np.fft.rfft(r * v.sigma, axis=0) / v.sensor
                U, beta = v.whiten
                E = (X - (beta * np.sum(U.conj() * X, axis=1))[:, None] * U) * v.weight[:, None]
                r = np.stack([E.real, E.imag])
            out.append(r.reshape(-1))
        return out

    def _vec(self, cands: tuple[Cand, ...], u: ndarray) -> ndarray:
        r = self.residuals(cands, u)
        if r is None:
            return np.full(self.n_resid, 1e6)
        return np.concatenate(r)

    @property
    def n_resid(self) -> int:
        return sum(2 * (v.u.size // 2 + 1) * len(v.channels) for v in self.views)

    def _evaluate(self, cands: tuple[Cand, ...], u: ndarray | None = None) -> Fit:
        u = np.zeros(len(cands)) if u is None else np.asarray(u, float)
        r = self.residuals(cands, u)
        if r is None:
            return Fit(cands, u, math.inf, np.full(len(cands), math.inf), False, "not physical")
        return Fit(cands, u, float(sum(float(np.einsum("i,i->", x, x)) for x in r)), np.zeros(len(cands)), resid=r)

    def cpu(self) -> float:
        return time.process_time() - self.cpu0

    def over(self) -> bool:
        return self.cpu() > self.budget

    # -- the fits ---------------------------------------------------------------------------------

    def scan(self, base: Fit, c: Cand) -> float:
        """The best size of ``c`` beside ``base`` (held at its values) on its grid (gains: linear)."""
        grid = GRID["damping"] if c.effect in ("storey_damping", "viscous") else GRID["default"]
        if c.kind != "struct":
            grid = np.linspace(-0.3, 0.3, 13)
        best, arg, r_best = math.inf, 0.0, None
        for g in grid:
            r = self.residuals((*base.cands, c), np.append(base.u, g), short=True)
            chi2 = math.inf if r is None else sum(float(np.einsum("i,i->", x, x)) for x in r)
            if chi2 < best:
                best, arg, r_best = chi2, float(g), r
        # a Gauss-Newton step from the grid's best: an effect smaller than half the grid's step leaves
        # every candidate's best at 0 (the nominal), all tied, and the true one may not be refined
        if r_best is not None:
            d = 1e-3
            r = self.residuals((*base.cands, c), np.append(base.u, arg + d), short=True)
            if r is not None:
                r0 = np.concatenate(r_best)
                J = (np.concatenate(r) - r0) / d
                jj = float(np.einsum("i,i->", J, J))
                if jj > 0.0:
                    step = float(np.clip(-np.einsum("i,i->", J, r0) / jj, -0.5, 0.5))
                    r = self.residuals((*base.cands, c), np.append(base.u, arg + step), short=True)
                    chi2 = math.inf if r is None else sum(float(np.einsum("i,i->", x, x)) for x in r)
                    if chi2 < best:
                        arg = arg + step
        return arg

    def refine(self, cands: tuple[Cand, ...], u0: ndarray) -> Fit:
        """Nonlinear least squares from ``u0``; std from the Jacobian (scaled by chi2/dof when above 1)."""
        from scipy.optimize import least_squares

        try:
            sol = least_squares(
                lambda u: self._vec(cands, u),
                np.asarray(u0, float),
                method="lm",
                x_scale=1.0,
                max_nfev=40 * (len(cands) + 1),
            )
        except (ValueError, np.linalg.LinAlgError) as e:  # pragma: no cover - a model the fit cannot evaluate
            return Fit(cands, np.asarray(u0, float), math.inf, np.full(len(cands), math.inf), False, str(e))
        f = self._evaluate(cands, sol.x)
        if not f.ok:
            return f
        J = sol.jac
        try:
            cov = np.linalg.inv(J.T @ J) * max(1.0, f.chi2 / max(self.dof - len(cands), 1))
            f.std = np.sqrt(np.maximum(np.diag(cov), 0.0))
        except np.linalg.LinAlgError:
            f.std = np.full(len(cands), math.inf)
        progress.candidate(f.label)
        return f

    def linear_gains(self, base: Fit, cands: list[Cand]) -> ndarray:
        """The chi2 each of ``cands`` would remove beside ``base``, linearised: (J r)^2 / (J J) of its
        column J = d residual / d u (forward differences), one column at a time (bounded memory)."""
        r0 = np.concatenate(base.resid)
        out = np.zeros(len(cands))
        for i, c in enumerate(cands):
            d = 1e-4
            r = self.residuals((*base.cands, c), np.append(base.u, d))
            if r is None:
                continue
            J = (np.concatenate(r) - r0) / d
            out[i] = float(np.einsum("i,i->", J, r0)) ** 2 / max(float(np.einsum("i,i->", J, J)), 1e-300)
        return out

    def run(self) -> dict[str, Any]:
        progress.stage("frame: scanning every effect at every element")
        nom = self.nominal
        singles: list[Fit] = []
        scanned: list[tuple[float, Cand, float]] = []
        for c in self.cands:
            if self.over():
                self.not_tried.append(f"the scan of {c.label}")
                continue
            g = self.scan(nom, c)
            f = self._evaluate((c,), np.array([g]))
            scanned.append((f.chi2, c, g))
        scanned.sort(key=lambda x: x[0])
        # near the noise the scan's chi2 (every q-th sample) ranks candidates by little more than its own
        # scatter: the ones whose linearised step removes most of the whole records' chi2 are refined too
        todo = scanned[:REFINE]
        if not self.over():
            gain = self.linear_gains(nom, [c for _, c, _ in scanned])
            todo += [scanned[int(i)] for i in np.argsort(-gain)[:REFINE] if scanned[int(i)] not in todo]
        progress.stage("frame: refining the best singles")
        for _, c, g in todo:
            if self.over():
                self.not_tried.append(f"the refinement of {c.label}")
                continue
            singles.append(self.refine((c,), np.array([g])))
        singles = sorted((f for f in singles if f.ok), key=self._order)
        pairs: list[Fit] = []
        progress.stage("frame: pairs")
        for first in singles[:FIRSTS]:
            if self.over():
                self.not_tried.append(f"pairs with {first.label}")
                continue
            others = [c for c in self.cands if c != first.cands[0]]
            gain = self.linear_gains(first, others)
            for i in np.argsort(-gain)[:SECONDS]:
                c = others[int(i)]
                if self.over():
                    self.not_tried.append(f"the pair {first.label} + {c.label}")
                    continue
                g = self.scan(first, c)
                pairs.append(self.refine((*first.cands, c), np.append(first.u, g)))
        pairs = sorted((f for f in pairs if f.ok), key=self._order)
        best = min([nom, *singles[:1], *pairs[:1]], key=lambda f: f.chi2)
        if not self.explained(best) and not any(v.free_decay for v in self.views):
            fs, fp = self.friction(nom, singles)
            singles = sorted([*singles, *fs], key=self._order)
            pairs = sorted([*pairs, *fp], key=self._order)
        return self.decide(nom, singles, pairs)

    def friction(self, nom: Fit, singles: list[Fit]) -> tuple[list[Fit], list[Fit]]:
        """Dry friction in the TMD link (tried only when no linear candidate explains the data): its force
        scanned and refined at each slope of FRICTION_SLOPES (held, reported in the notes), alone and
        beside the best linear single."""
        progress.stage("frame: dry friction in the TMD link")
        rms = float(np.sqrt(np.mean(np.concatenate([v.u for v in self.views]) ** 2)))
        eff = self.vocab["friction"]
        out: list[Fit] = []
        for slope in FRICTION_SLOPES:
            if self.over():
                self.not_tried.append(f"friction at slope {slope:g} s/m")
                continue
            c = Cand("friction", slope, eff.element, eff.params[0].name, 0.01 * rms, "friction")
            best, arg = math.inf, 0.0
            for g in (0.1, 0.3, 1.0, 3.0, 10.0):
                f = self._evaluate((c,), np.array([g]))
                if f.chi2 < best:
                    best, arg = f.chi2, g
            out.append(self.refine((c,), np.array([arg])))
        out = sorted((f for f in out if f.ok), key=self._order)
        if out and not self.over():  # the slope fitted beside the force, from the best on the grid
            c = out[0].cands[0]
            cs = Cand("friction", None, eff.element, "log10_friction_slope", 1.0, "slope")
            both = self.refine((c, cs), np.array([out[0].u[0], math.log10(float(c.where))]))
            if both.ok and both.chi2 < out[0].chi2:
                out.insert(0, both)
        pairs: list[Fit] = []
        if out and singles and not self.over():
            fr = out[0]
            pairs.append(self.refine((*fr.cands, *singles[0].cands), np.append(fr.u, singles[0].u)))
        for f in out[:1]:
            slope = 10.0 ** float(f.u[1]) if len(f.cands) > 1 else float(f.cands[0].where)
            self.notes.append(
                f"friction law df (2/pi) atan(s v): slope s = {slope:.3g} s/m (fitted from the best of {list(FRICTION_SLOPES)})"
            )
        return out[:1], [p for p in pairs if p.ok]

    def _order(self, f: Fit) -> tuple[float, list[int]]:
        """By chi2; fits equal to 1e-7 (the same model: the TMDI's inerter to the ground adds to the TMD's
        mass exactly) in the vocabulary's order."""
        return (float(f"{f.chi2:.7g}"), [self.cands.index(c) if c in self.cands else len(self.cands) for c in f.cands])

    # -- the verdict ------------------------------------------------------------------------------

    def per_dof(self, f: Fit) -> float:
        return f.chi2 / max(self.dof - len(f.cands), 1)

    def explained(self, f: Fit) -> bool:
        dof = max(self.dof - len(f.cands), 1)
        return f.chi2 <= dof * EXPLAINED or f.chi2 <= dof + 6 * math.sqrt(2 * dof)

    def significant(self, a: Fit, b: Fit, factor: float = 1.0) -> bool:
        """b (more effects) lowers chi2 significantly below a's: by more than SIGNIFICANT (or, on a large
        dataset, SIGNIFICANT_ROOT sqrt(dof): a model error far below the noise per sample still adds up
        over many samples) times chi2 / dof, times ``factor``."""
        level = max(SIGNIFICANT, SIGNIFICANT_ROOT * math.sqrt(self.dof))
        return (a.chi2 - b.chi2) > factor * level * max(1.0, self.per_dof(b))

    def decide(self, nom: Fit, singles: list[Fit], pairs: list[Fit]) -> dict[str, Any]:
        named: Fit | None = None
        s1 = singles[0] if singles else None
        if s1 is not None and self.significant(nom, s1) and _sized(s1):
            named = s1
            seen = set()
            for p in pairs:
                key = frozenset(c.key for c in p.cands)
                if key in seen:
                    continue
                seen.add(key)
                # a second effect: significant beside the first, and needed (the first leaves the data
                # unexplained) unless it is ten times as significant
                if self.significant(s1, p) and _sized(p) and (not self.explained(s1) or self.significant(s1, p, 10.0)):
                    named = p
                    break
        pool = singles if named is None or len(named.cands) == 1 else pairs
        ambiguous: list[Fit] = []
        if named is not None:
            tol = AMBIGUOUS * max(1.0, self.per_dof(named))
            keys = {frozenset(c.key for c in named.cands)}
            for f in pool:
                k = frozenset(c.key for c in f.cands)
                if k not in keys and f.chi2 - named.chi2 < tol and _sized(f):
                    keys.add(k)
                    ambiguous.append(f)
        ref = named or nom
        # unexplained: chi2 above the noise overall, or a frequency band (a mode, between modes) where
        # the residual stands BAND_Z std above its dof (a structure a noise-level error cannot make)
        worst = max(self.bands(ref), key=lambda b: b["z"])
        unexplained = not self.explained(ref) or worst["z"] > BAND_Z
        if self.explained(ref) and unexplained:
            self.notes.append(
                f"chi2 is at the noise overall, but near {worst['band']} the residual is {worst['z']:.1f} std above "
                "its noise: a structure the named model leaves"
            )
        return self.result(nom, named, singles, pairs, ambiguous, unexplained)

    def where(self, f: Fit) -> dict[str, Any]:
        """Where the residual of ``f`` exceeds the noise: per record and channel, chi2 / samples."""
        rows: list[dict[str, Any]] = []
        for v, r in zip(self.views, f.resid, strict=True):
            R = r.reshape(-1, len(v.channels))
            for k, c in enumerate(v.channels):
                rows.append({"record": v.name, "channel": c, "chi2_per_sample": float(np.mean(R[:, k] ** 2))})
        rows.sort(key=lambda d: -d["chi2_per_sample"])
        worst = [d for d in rows if d["chi2_per_sample"] > 1.5][:4]
        text = (
            "; ".join(f"{d['channel']} of {d['record']} (chi2/sample {d['chi2_per_sample']:.3g})" for d in worst)
            or "no channel stands out above the noise"
        )
        bands = self.bands(f)
        top = [b for b in bands if b["share"] >= 0.15 or b["z"] > BAND_Z][:3]
        if top and (worst or any(b["z"] > BAND_Z for b in top)):
            text = "" if not worst else text + "; "
            text += "frequency near " + ", ".join(
                f"{b['band']} ({100 * b['share']:.0f} % of the excess, {b['z']:.0f} std above the noise)" for b in top
            )
        return {"channels": rows, "bands": bands, "text": text}

    def bands(self, f: Fit) -> list[dict[str, Any]]:
        """The whitened residual's chi2 excess over its dof by frequency: around each nominal mode (+-10 %),
        below the lowest, between the modes, above the highest; shares of the positive excess."""
        modes = self.model0.modes_hz()
        edges: list[tuple[str, float, float]] = [("below the modes", 0.0, 0.9 * modes[0])]
        for i, m in enumerate(modes):
            edges.append((f"mode {i + 1} ({m:.3g} Hz)", 0.9 * m, 1.1 * m))
            if i + 1 < len(modes) and 1.1 * m < 0.9 * modes[i + 1]:
                edges.append((f"between modes {i + 1} and {i + 2}", 1.1 * m, 0.9 * modes[i + 1]))
        edges.append(("above the modes", 1.1 * modes[-1], math.inf))
        ex = np.zeros(len(edges))
        nd = np.zeros(len(edges))
        for v, r in zip(self.views, f.resid, strict=True):
            nb = v.u.size // 2 + 1
            E = r.reshape(2, nb, len(v.channels))
            p = np.sum(E**2, axis=(0, 2))
            dof = np.full(nb, 2.0 * len(v.channels))  # the chi2 a bin holds under the noise (Re and Im)
            dof[0] = 0.0  # the mean is left out
            if v.u.size % 2 == 0:
                dof[-1] = len(v.channels)
            fr = np.fft.rfftfreq(v.u.size, v.sim.h)
            for k, (_, lo, hi) in enumerate(edges):
                sel = (fr >= lo) & (fr < hi)
                ex[k] += float(np.sum(p[sel]) - np.sum(dof[sel]))
                nd[k] += float(np.sum(dof[sel]))
        pos = np.maximum(ex, 0.0)
        tot = float(pos.sum())
        out = [
            {
                "band": name,
                "excess": float(e),
                "dof": float(d),
                "z": float(e / math.sqrt(2 * d)) if d > 0 else 0.0,
                "share": float(q / tot) if tot > 0 else 0.0,
            }
            for (name, _, _), e, d, q in zip(edges, ex, nd, pos, strict=True)
        ]
        return sorted(out, key=lambda d: -d["share"])

    def result(
        self, nom: Fit, named: Fit | None, singles: list[Fit], pairs: list[Fit], ambiguous: list[Fit], unexplained: bool
    ) -> dict[str, Any]:
        ref = named or nom
        params = {}
        if named is not None:
            for c, (val, sd) in named.values().items():
                cand = next(x for x in named.cands if x.key == c)
                params[c] = {"value": val, "std": sd, "unit": _unit(self.vocab, cand)}
        text = self.text(nom, named, ambiguous, unexplained, singles)
        cpu = self.cpu()
        if self.not_tried:
            text += f" Stopped at the CPU budget ({self.budget:g} s): not tried: {'; '.join(self.not_tried[:6])}" + (
                f" and {len(self.not_tried) - 6} more." if len(self.not_tried) > 6 else "."
            )
        verdict = {
            "structural": named is not None and any(c.kind == "struct" for c in named.cands),
            "effects": named.effects if named else [],
            "elements": named.elements if named else [],
            "labels": [self.vocab[c.effect].label for c in named.cands] if named else [],
            "parameters": params,
            "ambiguous": [{"effects": f.effects, "elements": f.elements, "chi2": f.chi2} for f in ambiguous],
            "unexplained": unexplained,
            "chi2_before": nom.chi2,
            "chi2_after": ref.chi2,
            "dof": self.dof,
            "not_tried": list(self.not_tried),
            "notes": list(self.notes),
            "text": text,
        }
        return {
            "verdict": verdict,
            "candidates": [
                {
                    "effects": f.effects,
                    "elements": f.elements,
                    "chi2": f.chi2,
                    "chi2_per_dof": self.per_dof(f),
                    "params": {k: {"value": a, "std": b} for k, (a, b) in f.values().items()},
                }
                for f in [*singles, *pairs]
            ],
            "where": self.where(ref),
            "noise": [
                {"record": v.name, "noise_std": dict(zip(v.channels, map(float, v.sigma), strict=True))}
                for v in self.views
            ],
            "records": [
                {
                    "record": v.name,
                    "samples": int(v.t.size),
                    "rate_hz": 1.0 / v.sim.h,
                    "start_fitted": v.free_start,
                    "free_decay": v.free_decay,
                }
                for v in self.views
            ],
            "cpu_s": cpu,
            "wall_s": time.monotonic() - self.wall0,
            "model": {"storeys": self.model0.n, "modes_hz": self.model0.modes_hz()},
        }

    def text(self, nom: Fit, named: Fit | None, ambiguous: list[Fit], unexplained: bool, singles: list[Fit]) -> str:
        pd0 = self.per_dof(nom)
        if named is None:
            if not unexplained:
                return (
                    f"No effect: the nominal frame explains the transient records to the noise (chi2/dof = {pd0:.3g})."
                )
            hint = ""
            if singles:
                hint = f" The closest candidate, {singles[0].label}, leaves chi2/dof = {self.per_dof(singles[0]):.3g}."
            return (
                f"Unexplained: the nominal frame leaves chi2/dof = {pd0:.3g} and no effect of the vocabulary lowers it "
                f"significantly; the residual lives in {self.where(nom)['text']}.{hint}"
            )
        vals = "; ".join(
            f"{c.effect} at {c.element}: {c.param} = {u * c.scale:.4g} +- {s * c.scale:.2g} {_unit(self.vocab, c)}"
            + (f" ({100 * u:+.1f} % of the nominal)" if c.kind == "struct" else "")
            for c, u, s in zip(named.cands, named.u, named.std, strict=True)
        )
        pd1 = self.per_dof(named)
        s = f"Gap attributed to {vals}; chi2/dof {pd0:.3g} -> {pd1:.3g}."
        if any(c.kind == "force" for c in named.cands):
            s += " (A force gain is indistinguishable from one common gain of every response channel.)"
        if ambiguous:
            s += " Equally good (within the noise): " + "; ".join(f.label for f in ambiguous) + "."
        if unexplained:
            s += f" It does not explain the data to the noise: the rest lives in {self.where(named)['text']}."
        return s


def noise_psd(r: ndarray, f: ndarray, H2: ndarray, force: ndarray, f_lo: float) -> ndarray:
    """The sensor noise's variance per frequency bin of a filtered channel: white noise after the filter
    (a) and/or white noise before it, coloured by its |H|^2 (b), fitted (non-negative least squares)
    to the band medians of the nominal's residual periodogram above ``f_lo`` (the structure's misfit
    lies below), less the force noise's response ``force`` there. Unit: the variance of a white
    sequence of that level (its periodogram's mean)."""
    from scipy.optimize import nnls

    from ..system.transient_sim import robust_noise

    w = np.hanning(r.size)  # a window: the misfit's low-frequency residual must not leak up
    P = np.abs(np.fft.rfft(w * (r - np.mean(r)))) ** 2 / float(np.sum(w * w))
    sel = np.nonzero((f > f_lo) & (f < f[-1]))[0]
    if sel.size < 64:
        return np.full(f.size, robust_noise(r) ** 2)
    bands = np.array_split(sel, 16)
    y = np.array([np.median(P[b]) / math.log(2.0) - np.mean(force[b]) for b in bands])
    A = np.column_stack([np.ones(len(bands)), [np.mean(H2[b]) for b in bands]])
    (va, vb), _ = nnls(A, np.maximum(y, 0.0))
    out = va + vb * H2
    floor = 1e-3 * max(float(np.max(out)), 1e-300)
    return np.maximum(out, floor)


def _unit(vocab: Any, c: Cand) -> str:
    return "1" if c.kind == "slope" else str(vocab.units[c.param])


def _sized(f: Fit) -> bool:
    """Every parameter of a fit more than 3 std from 0."""
    return bool(np.all(np.abs(f.u) > 3 * f.std))


def _channel_order(c: str) -> tuple[int, int, str]:
    if c in ("y", "ydd"):
        return (99, c == "ydd", c)
    return (int(c[1:].removesuffix("dd")), c.endswith("dd"), c)
