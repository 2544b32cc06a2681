"""Link-level view of a dataset and the candidate unmodelled effects.

Everything is reduced to one restoring-force problem: samples of the relative displacement d,
velocity v, acceleration a across the device and the force F through it.

* link records: d, v, a and F are measured directly;
* system time records: F is the force of the TMD links on the base, from the base equation
  F = force - M xdd - C xd - K x, and d = x - y, v = xd - yd, a = xdd - ydd.

The nominal force law and every candidate use the physics kernels' force laws
(:func:`friction_force`, :func:`chain_force`); a candidate is ``F = offset(theta) + Phi(theta) beta``:
linear in beta, with at most two nonlinear parameters theta (fitted by variable projection).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..._jit import njit
from ...models.base_tmd.effects import VOCABULARY as VOCAB
from ...physics.effects import LINK
from ...physics.kernels import chain_force, friction_force
from ...physics.params import N_PARAMS, P_ci, P_eps, P_ki
from ..data import DataError, Dataset

if TYPE_CHECKING:
    from numpy import float64, ndarray

MAX_SAMPLES_PER_RECORD = 4000


@njit(cache=True)
def friction_vec(v: np.ndarray, df: float, s: float) -> np.ndarray:
    out = np.empty(v.shape[0])
    for i in range(v.shape[0]):
        out[i] = friction_force(v[i], df, s)
    return out


@njit(cache=True)
def deadzone_vec(d: np.ndarray, eps: float) -> np.ndarray:
    """Unit-stiffness spring in series with a gap +-eps (the kernels' chain force, ci = 0)."""
    p = np.zeros(N_PARAMS)
    p[P_ki], p[P_ci], p[P_eps] = 1.0, 0.0, eps
    out = np.empty(d.shape[0])
    for i in range(d.shape[0]):
        out[i] = chain_force(d[i], 0.0, p)
    return out


@njit(cache=True)
def jenkins_gap(d: np.ndarray, starts: np.ndarray, eps: float, delta: float, n_pre: np.ndarray) -> np.ndarray:
    """Normalised force of a dry-friction slider in series with a contact spring and a gap +-eps.

    The slider sits at q; the spring engages through the gap (kernels' chain force of d - q) and the
    slider slips when the spring force reaches the friction level, i.e. at an elastic deflection
    delta (= friction level / contact stiffness). Returns F / friction level in [-1, 1]. Each record
    (starting at starts[k]) is pre-rolled over its first n_pre[k] samples so that the hysteresis
    state at its first sample is the periodic one.
    """
    p = np.zeros(N_PARAMS)
    p[P_ki], p[P_ci], p[P_eps] = 1.0 / delta, 0.0, eps
    out = np.empty(d.shape[0])
    nrec = starts.shape[0] - 1
    for k in range(nrec):
        a, b = starts[k], starts[k + 1]
        q = d[a]
        for sweep in range(2):
            lo = a
            hi = a + n_pre[k] if sweep == 0 else b
            if hi > b:
                hi = b
            for i in range(lo, hi):
                f = chain_force(d[i] - q, 0.0, p)
                if f > 1.0:
                    q = d[i] - eps - delta
                    f = 1.0
                elif f < -1.0:
                    q = d[i] + eps + delta
                    f = -1.0
                if sweep == 1:
                    out[i] = f
    return out


@dataclass
class LinkData:
    d: np.ndarray
    v: np.ndarray
    a: np.ndarray
    F: np.ndarray  #: measured link force [N]
    gain_reg: np.ndarray  #: regressor of a force-amplitude / force-gain error
    F_nom: np.ndarray
    phase: np.ndarray  #: phase in the cycle [rad], 0 at max displacement (link) / force peak (system)
    t: np.ndarray
    rec: np.ndarray  #: record index of each sample
    starts: np.ndarray  #: first sample of each record, plus n
    n_pre: np.ndarray  #: samples in one period of each record
    records: list  #: Record objects (link or time)
    noise: float  #: noise floor (std of the measured force noise) [N], median over records
    noise_rec: np.ndarray  #: noise floor of each record [N]
    nominal: dict  #: link-level nominal parameters
    level: str

    def mask(self, rec_ids: list[int]) -> ndarray:
        return np.isin(self.rec, np.asarray(sorted(rec_ids), dtype=int))


def link_nominal(ds: Dataset) -> dict:
    if ds.level == "link":
        return dict(ds.nominal)
    from ...physics.params import TMDParams

    t = TMDParams(**ds.nominal["tmd"])  # the physics' own defaults for missing keys
    return dict(
        stiffness=t.stiffness,
        damping=t.damping,
        friction_force=t.friction_force,
        friction_slope=t.friction_slope,
        inertance=t.inertance,
    )


def nominal_force(nom: dict[str, float], d: ndarray, v: ndarray, a: ndarray) -> ndarray:
    """Nominal link force: the kernels' static link force (spring, damper, friction) at relative
    displacement d and velocity v, plus the ideal inerter I a."""
    from ...physics.params import P_c, P_df, P_k, P_s
    from ..system.model import link_force_grid

    p = np.zeros(N_PARAMS)
    p[P_k], p[P_c], p[P_df], p[P_s] = nom["stiffness"], nom["damping"], nom["friction_force"], nom["friction_slope"]
    z = np.zeros_like(d)
    return (
        link_force_grid(np.ascontiguousarray(d, float), np.ascontiguousarray(v, float), z, z, p) + nom["inertance"] * a
    )


SAVGOL_POINTS = 15  #: Savitzky-Golay window (samples, cubic) for non-periodic records


def _deriv(t: ndarray, x: ndarray, omega: float | None = None, order: int = 1) -> ndarray:
    """Derivative of a measured signal: from its Fourier series over whole periods when the record
    is periodic at omega (exact for the steady state, noise averaged over the periods), else from a
    cubic Savitzky-Golay smoother over SAVGOL_POINTS samples (cut-off ~ fs / SAVGOL_POINTS)."""
    from ...solvers.harmonic import fit_series

    dt_mean = (t[-1] - t[0]) / max(len(t) - 1, 1)
    if omega and 2 * math.pi / omega >= 4 * dt_mean:  # at least 4 samples per period
        try:
            s = fit_series(t, {"s": x}, omega, H=40)
        except np.linalg.LinAlgError:  # a basis the samples cannot resolve: use the smoother
            s = None
        if s is not None and s.periodic and s.r2["s"] >= 0.9:
            return s.eval("s", omega * (t - t[0]), deriv=order)
    from scipy.signal import savgol_filter

    dt = (t[-1] - t[0]) / (len(t) - 1)
    w = min(SAVGOL_POINTS, len(t) - (1 - len(t) % 2))
    return savgol_filter(x, w, 3, deriv=order, delta=dt)


def _noise_floor(r: ndarray) -> float64:
    dr = np.diff(r)
    mad = np.median(np.abs(dr - np.median(dr)))
    return 1.4826 * mad / math.sqrt(2.0)


def build_link_data(ds: Dataset) -> LinkData:
    """The restoring-force view of every time record of the dataset (FRC records are skipped)."""
    nom = link_nominal(ds)
    parts, recs, noises = [], [], []
    for rec in ds.records:
        if rec.kind == "frc":
            continue
        c = rec.columns
        t = c["t"]
        if rec.kind == "link":
            d = c["displacement"]
            v = c["velocity"] if rec.has("velocity") else _deriv(t, d, rec.omega)
            a = (
                c["acceleration"]
                if rec.has("acceleration")
                else (_deriv(t, v, rec.omega) if rec.has("velocity") else _deriv(t, d, rec.omega, 2))
            )
            F = c["force"]
            gain = None
        else:
            if not rec.has("y"):
                raise DataError(
                    f"{rec.name}: column 'y' is needed for the restoring-force diagnosis of a "
                    "system time record (the TMD displacement); add it or give FRC records"
                )
            from ...physics.params import BaseParams

            bp = BaseParams(**ds.nominal["base"])
            b = {"mass": bp.mass, "damping": bp.damping, "stiffness": bp.stiffness}
            x, y = c["x"], c["y"]
            xd = c["xd"] if rec.has("xd") else _deriv(t, x, rec.omega)
            yd = c["yd"] if rec.has("yd") else _deriv(t, y, rec.omega)
            xdd = c["xdd"] if rec.has("xdd") else _deriv(t, x, rec.omega, 2)
            ydd = c["ydd"] if rec.has("ydd") else _deriv(t, y, rec.omega, 2)
            F = c["force"] - b["mass"] * xdd - b["damping"] * xd - b["stiffness"] * x
            d, v, a = x - y, xd - yd, xdd - ydd
            gain = c["force"]
        Fn = nominal_force(nom, d, v, a)
        noises.append(_noise_floor(F - Fn))
        if gain is None:
            gain = Fn
        w = rec.omega
        if not w:
            ph = np.zeros_like(t)
        elif rec.kind == "link":
            A = np.column_stack([np.cos(w * t), np.sin(w * t), np.ones_like(t)])
            cc = np.linalg.lstsq(A, d, rcond=None)[0]
            ph = np.mod(w * t - math.atan2(cc[1], cc[0]), 2 * math.pi)
        else:
            ph = np.mod(w * t, 2 * math.pi)
        step = max(1, int(math.ceil(len(t) / MAX_SAMPLES_PER_RECORD)))
        sl = slice(None, None, step)
        dt = (t[-1] - t[0]) / (len(t) - 1) * step
        n_pre = int(min(len(t[sl]), max(2, round(2 * math.pi / w / dt)))) if w else 2
        parts.append((d[sl], v[sl], a[sl], F[sl], gain[sl], Fn[sl], ph[sl], t[sl], n_pre))
        recs.append(rec)
    if not parts:
        raise DataError(f"{ds.path}: no time records (link-level diagnosis needs at least one)")
    cat = [np.concatenate([p[i] for p in parts]) for i in range(8)]
    sizes = [len(p[0]) for p in parts]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    rid = np.repeat(np.arange(len(parts)), sizes)
    return LinkData(
        d=cat[0],
        v=cat[1],
        a=cat[2],
        F=cat[3],
        gain_reg=cat[4],
        F_nom=cat[5],
        phase=cat[6],
        t=cat[7],
        rec=rid,
        starts=starts,
        n_pre=np.array([p[8] for p in parts], dtype=np.int64),
        records=recs,
        noise=float(np.median(noises)),
        noise_rec=np.array(noises),
        nominal=nom,
        level=ds.level,
    )


# --- candidates ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class Effect:
    name: str
    label: str
    params: tuple  #: names of the reported parameters (linear ones, then nonlinear ones)
    theta0: tuple = ()  #: starting grid of nonlinear parameters (log10 values), one tuple per parameter


def _scales(ld: LinkData) -> tuple[float, float]:
    return float(np.percentile(np.abs(ld.d), 99)) or 1.0, float(np.percentile(np.abs(ld.v), 99)) or 1.0


def _effect(name: str, theta0: tuple = (), params: tuple = ()) -> Effect:
    """A link candidate from the unit's vocabulary: its label, its parameters (``params``: the link
    fit's own, e.g. play's link level beside its gap), ``theta0`` its nonlinear parameters' grid."""
    e = VOCAB[name]
    assert LINK in e.levels, name
    return Effect(name, e.label, params or e.param_names, theta0)


def effect_list(ld: LinkData) -> list:
    dmax, vmax = _scales(ld)
    ld10, lv10 = math.log10(dmax), math.log10(vmax)
    eps_grid = tuple(ld10 + np.linspace(-2.3, -0.4, 9))
    slope_grid = (tuple(-lv10 + np.linspace(0.5, 3.5, 7)),)
    effects = [_effect("friction", slope_grid), _effect("play", (eps_grid,), ("link_level", "play_gap"))]
    effects += [_effect(e) for e in ("viscous", "mass_split", "cubic", "force_error", "bias")]
    if ld.nominal["friction_force"] > 0 and ld.nominal["stiffness"] == 0:
        # play in front of a friction element: slider + contact spring + gap (two nonlinear params)
        effects[1] = _effect(
            "play",
            (eps_grid, tuple(ld10 + np.linspace(-3.0, -1.0, 5))),
            ("friction_force", "play_gap", "elastic_deflection"),
        )
        # the same without the gap: friction with pre-sliding (contact) compliance, the rival explanation
        effects.insert(2, _effect("compliant_friction", (tuple(ld10 + np.linspace(-3.0, -0.5, 7)),)))
    return effects


def basis(effect: Effect, ld: LinkData, theta: ndarray) -> tuple:
    """(offset, Phi) of one effect: its force correction is offset + Phi beta (added to nominal)."""
    nom, n = ld.nominal, ld.F.shape[0]
    z = np.zeros(n)
    name = effect.name
    if name == "friction":
        s = 10.0 ** theta[0]
        return -friction_vec(ld.v, nom["friction_force"], nom["friction_slope"]), friction_vec(ld.v, 1.0, s)[:, None]
    if name == "play":
        eps = 10.0 ** theta[0]
        if len(theta) == 2:
            h = jenkins_gap(ld.d, ld.starts, eps, 10.0 ** theta[1], ld.n_pre)
            return -friction_vec(ld.v, nom["friction_force"], nom["friction_slope"]), h[:, None]
        return -nom["stiffness"] * ld.d, deadzone_vec(ld.d, eps)[:, None]
    if name == "compliant_friction":
        h = jenkins_gap(ld.d, ld.starts, 0.0, 10.0 ** theta[0], ld.n_pre)
        return -friction_vec(ld.v, nom["friction_force"], nom["friction_slope"]), h[:, None]
    if name == "viscous":
        return z, ld.v[:, None]
    if name == "mass_split":
        return z, ld.a[:, None]
    if name == "cubic":
        return z, (ld.d**3)[:, None]
    if name == "force_error":
        return z, ld.gain_reg[:, None]
    if name == "bias":
        return z, np.ones((n, 1))
    raise KeyError(name)


def report_params(effect: Effect, ld: LinkData, beta: ndarray, theta: ndarray) -> dict:
    """Physical parameters of a fitted effect (linear beta, nonlinear theta as log10)."""
    name = effect.name
    if name == "friction":
        return {"friction_force": float(beta[0]), "friction_slope": float(10 ** theta[0])}
    if name == "play":
        out = {"play_gap": float(10 ** theta[0])}
        if len(theta) == 2:
            out.update(friction_force=float(beta[0]), elastic_deflection=float(10 ** theta[1]))
        else:
            out["link_stiffness"] = float(beta[0])
        return out
    if name == "compliant_friction":
        return {"friction_force": float(beta[0]), "elastic_deflection": float(10 ** theta[0])}
    if name == "force_error" and ld.level == "system":
        return {"force_gain_error": float(-beta[0])}
    return {effect.params[0]: float(beta[0])}
