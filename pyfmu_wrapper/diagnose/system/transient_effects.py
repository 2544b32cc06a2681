"""Transient records: the candidate effects as changes of the simulated model.

Every candidate is a change of the model that :mod:`.transient_sim` simulates with the measured
force: the unit's vocabulary (:mod:`.effects`: its mechanisms and every parameter of the nominal
model, M, K, C, m, k, c, I; dry friction df through ``friction``), with the bounds of their fits and the smallest size a second effect must have to mean something physically.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, MutableMapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ...physics.params import P_C, P_I, P_K, P_M, P_MODEL, P_c, P_ci, P_df, P_k, P_ki, P_m, P_s
from ...physics.registry import PACK_INDEX
from .effects import TRANSIENT_EFFECTS, VOCAB
from .transient_sim import fastest_rate

if TYPE_CHECKING:
    from numpy import ndarray

#: the play candidate's gear contact (a nuisance of the model; stiff enough that the contact is short
#: against the motion, soft enough for an explicit step of ~1/1000 of the TMD period)
PLAY_KI, PLAY_CI = 2.0e6, 20.0
#: a nominal's dry friction is regularised as df (2/pi) atan(s v) with s = FRICTION_RATE x (the
#: nominal's fastest modal rate) x m / (df 2/pi); the friction candidate fits its slope s within
#: FRICTION_SLOPE (the link also sticks, :data:`.transient_sim.STICK`: the law's steep part near v = 0 is never
#: stepped, so a Coulomb-like slope of 2e5 s/m costs about what 5000 did; a stick-slip truth fits 2e4-2e5)
FRICTION_RATE = 20.0
FRICTION_SLOPE = (10.0, 2.0e5)
#: parameters of a model's regularisation, not of the physics: reported per record, but they do not vote
#: in the records' agreement test (a stick-slip truth's slope is infinite; each record's fit puts it where
#: its own stick-slip content does: seed 7102 tr002, df 2.7447 +- 0.028 and 2.7473 +- 0.027 N on a sweep
#: and a decay, slope 3.6e4 +- 6e3 and 6.5e4 +- 1e3 s/m, p 5e-6: not named)
REGULARISATION = frozenset({"friction.friction_slope"})
#: effect -> (parameter names, their units), from the unit's vocabulary (:mod:`.effects`)
TEFFECTS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    e: (VOCAB[e].param_names, tuple(p.unit for p in VOCAB[e].params)) for e in TRANSIENT_EFFECTS
}
#: bounds of the fit (SI): the vocabulary's physical ones, the friction slope within what the explicit
#: step resolves
BOUNDS = {**VOCAB.bounds(), "friction.friction_slope": FRICTION_SLOPE}


def scales(p: ndarray, stroke: float, xscale: float) -> dict[str, tuple[float, ...]]:
    """Typical size of each parameter (the fit works in units of these)."""
    return {
        "viscous": (0.1 * p[P_c] + 1.0,),
        "friction": (1.0, 1000.0),
        "play": (1e-4,),
        "mass_split": (0.1,),
        "cubic": (0.1 * p[P_k] / max(stroke, 1e-6) ** 2,),
        "force_error": (0.01,),
        "sensor_offset": (0.01 * xscale, 0.01 * xscale),
        "base_mass": (0.01 * p[P_M],),
        "base_stiffness": (0.01 * p[P_K],),
        "base_damping": (0.1 * p[P_C],),
        "tmd_stiffness": (0.01 * p[P_k],),
        "tmd_mass": (0.01 * p[P_m],),
        "inertance": (0.1,),
    }


class _Packed(MutableMapping[str, float]):
    """The kernels' packed parameter array by the registry's names (``tmd.damping``), for
    :meth:`~pyfmu_wrapper.physics.effects.Vocabulary.change`."""

    def __init__(self, p: ndarray) -> None:
        self.p = p

    def __getitem__(self, key: str) -> float:
        return float(self.p[PACK_INDEX[key]])

    def __setitem__(self, key: str, value: float) -> None:
        self.p[PACK_INDEX[key]] = value

    def __delitem__(self, key: str) -> None:
        raise TypeError("a packed parameter cannot be removed")

    def __iter__(self) -> Iterator[str]:
        return iter(PACK_INDEX)

    def __len__(self) -> int:
        return len(PACK_INDEX)


@dataclass
class Model:
    """A candidate model: the kernels' parameter vector, a force gain and sensor offsets."""

    p: ndarray
    gain: float = 1.0
    offset: tuple[float, float] = (0.0, 0.0)


def apply(p_nom: ndarray, effects: tuple[str, ...], theta: ndarray) -> Model | str:
    """The model with the effects at parameters theta (in SI, concatenated in effect order), or the
    reason it is not physical (m, M, K, k <= 0, I, c, C, df, gap < 0, 1 + a <= 0)."""
    p = p_nom.copy()
    mdl = Model(p)
    i = 0
    for e in effects:
        th = theta[i : i + len(TEFFECTS[e][0])]
        i += len(th)
        if e == "friction" and th[0] < 0:
            return f"friction force df < 0 ({th[0]:.3g} N)"
        if e == "play":
            if th[0] < 0:
                return f"play gap < 0 ({th[0]:.3g} m)"
            p[P_MODEL], p[P_ki], p[P_ci] = 2.0, PLAY_KI, PLAY_CI
        elif e == "force_error":
            mdl.gain = 1.0 + th[0]
        elif e == "sensor_offset":
            mdl.offset = (float(th[0]), float(th[1]))
    VOCAB.change(_Packed(p), effects, theta)  # the model parameters each effect changes (the unit's table)
    if p[P_df] > 0 and "friction" not in effects:  # a nominal's friction: the slope an explicit step resolves
        p[P_s] = min(p_nom[P_s], FRICTION_RATE * fastest_rate(p_nom) * max(p[P_m], 1e-9) / (p[P_df] * 2 / math.pi))
    for idx, name in ((P_M, "M"), (P_K, "K"), (P_m, "m"), (P_k, "k")):
        if p[idx] <= 0:
            return f"{name} <= 0 ({p[idx]:.3g})"
    for idx, name in ((P_C, "C"), (P_c, "c"), (P_I, "I")):
        if p[idx] < 0:
            return f"{name} < 0 ({p[idx]:.3g})"
    if int(p[P_MODEL]) == 2 and p[P_I] <= 0:
        return "play needs an inertance I > 0"
    if mdl.gain <= 0:
        return f"1 + a <= 0 ({mdl.gain:.3g})"
    return mdl


def meaningless(effect: str, theta: ndarray, p: ndarray, stroke: float) -> str:
    """Why a second effect's parameter is too small to mean anything physically ('' when it is not):
    below MEANINGFUL of the nominal value it changes (a 0.2 % forcing gain or 0.3 % of K beside a
    named effect is calibration scatter, not a cause); a cubic term under 0.5 % of k over the stroke."""
    from ...physics.params import P_C, P_I, P_K, P_M, P_c, P_k, P_m

    ref = {
        "base_mass": p[P_M],
        "base_stiffness": p[P_K],
        "base_damping": p[P_C],
        "tmd_stiffness": p[P_k],
        "tmd_mass": p[P_m],
        "viscous": max(p[P_c], 1.0),
        "force_error": 1.0,
        "mass_split": p[P_m] + p[P_I],
        "inertance": p[P_m] + p[P_I],
    }
    from ..gates import CUBIC_MEANINGFUL, MEANINGFUL  # the steady pipeline's gate: one set of sizes

    if effect in MEANINGFUL and abs(theta[0]) < MEANINGFUL[effect] * ref[effect]:
        return f"|{theta[0]:.3g}| < {MEANINGFUL[effect]:g} x {ref[effect]:.4g}"
    if effect == "cubic" and abs(theta[0]) * stroke**2 < CUBIC_MEANINGFUL * p[P_k]:
        return f"k3 d^2 = {abs(theta[0]) * stroke**2:.3g} N/m < 0.5 % of k"
    return ""
