"""Transient records: the window of every record on which a candidate is fitted cheaply, to rule out
a candidate that cannot explain the data before its full fit.

The window is each record's first WINDOW_SHARE (its simulation runs over that share of the grid),
cut into SEGMENTS segments of its own: parameters are fitted on the even ones, the odd ones are
held out (as on the whole record, :mod:`.transient`). Why a window fit may only rule out: a
candidate that explains the whole record to the noise at some parameters explains its window at
those parameters too (held-out z of a window of noise: about N(0, 1)), and the window's own fit
only lowers the training chi-square further. A window z above PRUNE_Z therefore means the
candidate cannot explain the data at any parameters the fit can reach; below it, nothing is
concluded and the candidate is fitted on everything (from the window's parameters, a warm start).
The window is not used (nothing is ruled out) when the nominal already explains it to PRUNE_Z, or
when it holds fewer than WINDOW_PERIODS periods of the nominal's slowest mode or WINDOW_MIN fit
samples.
"""

from __future__ import annotations

import dataclasses
import math
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from numpy import ndarray

    from .transient_sim import TView

WINDOW_SHARE = 0.25  #: the window: this share of each record, from its start
WINDOW_MARGIN = 0.25  #: the window's force runs this share of the window beyond it
#: the window's last this many fit samples are left out of its fit and its held-out chi-square: the
#: chains' non-causal parts (the hold and block-mean corrections at the fit rate) see the window's end
#: there (measured: 0.11-0.2 noise std at the last sample, 2e-3 at the fifth, 3e-4 at the twentieth)
WINDOW_GUARD = 16
WINDOW_PERIODS = 5.0  #: the window must hold this many periods of the nominal's slowest mode
WINDOW_MIN = 400  #: ... and this many fit samples (every record)
#: a window held-out z above this rules the candidate out. Measured: the true candidates' window z
#: -1.9 to -0.3 (bench viscous, friction; seed 5252 tr026, tr050, tr003, tr055), the ruled-out ones'
#: 142 to 9.6e6 (docs/diagnose-method.md, "Transient records")
PRUNE_Z = 100.0


def window_views(views: list[TView], share: float = WINDOW_SHARE) -> list[TView]:
    """Each view cut to its first ``share`` of fit samples: a copy with its own caches and start state;
    its force runs WINDOW_MARGIN of the window further (the force chain's inverse, :func:`.true_force`,
    then sees no artificial end inside the window; a grid force costs its force's length)."""
    out = []
    for v in views:
        n = max(1, int(v.n_out * share))
        nf = min(v.force.size, int(n * v.q * (1 + WINDOW_MARGIN)))
        out.append(
            dataclasses.replace(
                v,
                t=v.t[:n],
                meas=v.meas[:n],
                force=v.force[:nf],
                n_out=n,
                z0=v.z0.copy(),
                phi=None if v.phi is None else v.phi[:n],
                fcache={},
                gcache={},
            )
        )
    return out


def guarded(masks: list[ndarray]) -> list[ndarray]:
    """Window masks without the window's last WINDOW_GUARD fit samples."""
    out = []
    for m in masks:
        m = m.copy()
        m[-WINDOW_GUARD:] = False
        out.append(m)
    return out


def slowest_period(p: ndarray) -> float:
    """The longest period [s] of the linear model p's modes (2 pi / the smallest |eigenvalue|)."""
    from ...physics.params import P_I
    from .transient_sim import modal_eigenvalues

    slow = float(np.min(np.abs(modal_eigenvalues(p, float(p[P_I])))))
    return 2 * math.pi / slow if slow > 0 else math.inf


def window_unusable(views: list[TView], p_nom: ndarray) -> str | None:
    """Why the windows of these views cannot rule anything out (too short), or None."""
    period = slowest_period(p_nom)
    for v in views:
        n = int(v.n_out * WINDOW_SHARE) - v.skip
        if n < WINDOW_MIN:
            return f"{v.name}: its window holds {n} fit samples (< {WINDOW_MIN})"
        if n / v.fs < WINDOW_PERIODS * period:
            return f"{v.name}: its window holds {n / v.fs:.3g} s (< {WINDOW_PERIODS:g} periods of {period:.3g} s)"
    return None
