"""The shear frame with its TMD as two co-simulated FMUs: ShearFrame (``frame``) and TMDInerter
(``tmd``), coupled by forces at two storeys (native or Python-hosted FMUs, ``CosimSettings.fmu_build``), and their
steady states.

Connections (:func:`connections`)::

    frame.x -> tmd.x, frame.xd -> tmd.xd            the TMD's storey s (spring, damper, friction)
    frame.xdd -> tmd.xdd                            the inerter's terminal j (absent for the ground)
    tmd.force -> frame.f_link                       the links' total force on the structure
    tmd.inerter_force -> frame.f_inerter            its inerter's share, which acts on storey j

With the ideal inerter on another storey (the TMDI), frame.xdd -> tmd.xdd -> tmd.force -> frame.xdd is
an algebraic loop, which the master's ``loop`` scheme solves. With the inerter on the TMD's own
storey (j = s, the paper's TMD-inerter) the interface Jacobian of the paper's pair is used instead:
``frame.xdd_free -> tmd.xdd`` and ``tmd.base_compliance`` = 1/M_s, so the TMD adds the storey's
instantaneous reaction to its own force within each step (no loop; the play chain's gear mesh meets a
storey that reacts without a step of delay: with frame.xdd it diverged, frame3_full at 62 s), and
with the impulse coupling of the settings (the default) the storey gets the TMD's exact impulse over
each step (:func:`connections`; frame3_full's full TMD: 0.21 % from the monolithic engine where the
force coupling left 1-7 % and irregular windows). The steady state is the definition of both engines
(:class:`~pyfmu_wrapper.solvers.steady.WindowCriterion` on max |x| of the top storey per period),
started from the monolithic engine's start (the exact response of the linear companion, or the play
model's companion orbit); the amplitude is the cubic Hermite maximum of the top storey between the
communication points. Every point's coupling error is estimated by step doubling (the amplitude at N
and at N/2 steps per period; with a gear gap, its linear companion's) and held to the settings'
``coupling_tol``: the steps are doubled while it is above, and a point still above is reported not
converged (:func:`checked_steady_state`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from ...cosim.checked import AMPLITUDE_FLOOR, companion
from ...cosim.periods import CosimSteadyState
from ...cosim.settings import CosimSettings
from ...cosim.system import CosimEngine
from ...master.graph import Connection
from ...master.instance import MasterError
from ...master.master import Master
from ...physics import registry
from ...physics.params import BaseParams, TMDParams, has_gap
from ...physics.unit import ModelUnit
from ...solvers.hermite import hermite_absmax_series
from ...solvers.monolithic import SolverSettings, companion_start
from ...solvers.start import initial_guess, play_atol
from ...solvers.steady import WindowCriterion
from ...solvers.sweep import run_sweep_pieces
from .equations import storey_index
from .params import FrameParams

if TYPE_CHECKING:
    from ...fmi.fmumodel import FmuModel

RECORD = ("frame.x_top", "frame.xd_top")
#: the relative amplitude accuracy asked of a frame's co-simulation unless the settings ask another
#: (3-storey TMDI at 13.75 rad/s: 1e-3 gives 1.0e-4 against the exact response, 1e-4 gives 1.1e-5 in
#: fewer periods: the orbit starts closer to the exact linear start)
FRAME_ACCURACY = 1e-4
ATOL_FLOOR = 1e-14
#: a point's steps per period are doubled at most this many times when its coupling-error estimate
#: is above the tolerance (:func:`checked_steady_state`)
MAX_REFINEMENTS = 3


def connections(frame: FrameParams, tmd: TMDParams | None = None) -> list[Any]:
    """The coupling of the frame and its TMD (module doc): with the inerter on the TMD's storey and
    ``tmd`` given, the momentum (impulse) coupling of the paper's pair: the storey gets the exact
    impulse of the TMD over each step, m (yd(t + h) - yd(t)) / h, with its first moment."""
    if tmd is not None and frame.terminal == frame.tmd_at:
        return [
            "frame.x -> tmd.x",
            "frame.xd -> tmd.xd",
            "frame.xdd_free -> tmd.xdd",
            Connection("tmd.yd", "frame.f_link", "rate", float(tmd.mass), "tmd.force", integral_src="tmd.y"),
        ]
    out = [
        "frame.x -> tmd.x",
        "frame.xd -> tmd.xd",
        "tmd.force -> frame.f_link",
        "tmd.inerter_force -> frame.f_inerter",
    ]
    if frame.terminal == frame.tmd_at:
        out.append("frame.xdd_free -> tmd.xdd")
    elif frame.terminal > 0:
        out.append("frame.xdd -> tmd.xdd")
    return out


def compliance(frame: FrameParams) -> float:
    """tmd.base_compliance: 1/M_s when the inerter's terminal is the TMD's storey s, else 0 (off)."""
    return 1.0 / frame.masses[frame.tmd_at - 1] if frame.terminal == frame.tmd_at else 0.0


def fmu_parameters(frame: FrameParams, tmd: TMDParams, omega: float, z0: ArrayLike, fmu_rtol: float = 1e-8) -> dict:
    """The FMU parameter values ("instance.variable" -> value) of a configuration and start state z0
    (the frame model's layout, :mod:`pyfmu_wrapper.models.frame_model.equations`)."""
    z = np.asarray(z0, dtype=float)
    n = frame.n
    atol = max(1e-8 * abs(frame.force_amplitude) / frame.stiffness, ATOL_FLOOR)
    out: dict[str, float | int] = {
        "frame.storeys": n,
        "frame.F": frame.force_amplitude,
        "frame.w": float(omega),
        "frame.force_storey": frame.loaded_storey,
        "frame.tmd_storey": frame.tmd_at,
        "frame.inerter_to": frame.terminal,
        "frame.rtol": fmu_rtol,
        "frame.atol": atol,
    }
    for i in range(1, n + 1):
        ix = storey_index(i, n)
        out[f"frame.m{i}"] = frame.masses[i - 1]
        out[f"frame.k{i}"] = frame.stiffnesses[i - 1]
        out[f"frame.c{i}"] = frame.dampings[i - 1]
        out[f"frame.x0_{i}"] = z[ix]
        out[f"frame.xd0_{i}"] = z[ix + 1]
    paper = registry.fmu_start_values(BaseParams(), tmd, omega)
    out.update({k: v for k, v in paper.items() if k.startswith("tmd.")})
    first = BaseParams(mass=frame.masses[0], stiffness=frame.stiffness, force_amplitude=frame.force_amplitude)
    out.update(
        {
            "tmd.y0": z[2],
            "tmd.yd0": z[3],
            "tmd.d0": z[4],
            "tmd.dd0": z[5],
            "tmd.rtol": fmu_rtol,
            "tmd.atol": min(atol, play_atol(first, tmd)) if has_gap(tmd) else atol,
            "tmd.base_compliance": compliance(frame),
        }
    )
    return out


def frame_fmus() -> tuple[FmuModel, ...]:
    """The FMUs of the frame's co-simulation: the frame's own (its unit's) and the paper's TMDInerter
    (declared by ``base_tmd``)."""
    from ..base_tmd.fmus.tmd_inerter import FMU as TMD_INERTER
    from .fmus.shear_frame import FMU as SHEAR_FRAME

    return (SHEAR_FRAME, TMD_INERTER)


def make_master(
    frame: FrameParams, tmd: TMDParams | None = None, order: int = 2, fmi_version: int = 2, fmu_build: str = "native"
) -> Master:
    """A master for the frame and its TMD (the FMUs built if missing or stale); ``tmd``: the impulse
    coupling where it applies (:func:`connections`); fmu_build: "native" (the models compiled into the
    FMUs' binaries, no Python) or "python" (the Python-hosted FMUs, the reference: the same bits)."""
    if fmu_build == "native":
        from ...fmubuild.native_build import ensure_native_fmus

        paths = ensure_native_fmus(frame_fmus(), fmi_version=fmi_version)
    else:
        from ...fmubuild.build import ensure_fmus

        paths = ensure_fmus(frame_fmus(), fmi_version=fmi_version)
    fmus: dict[str, str | Path] = {"frame": paths["ShearFrame"], "tmd": paths["TMDInerter"]}
    conns = connections(frame, tmd)
    impulse = any(not isinstance(c, str) for c in conns)
    return Master(fmus, conns, {}, scheme="jacobi" if impulse else "loop", order=order, record=RECORD)


def steady_state(
    unit: ModelUnit, master: Master, frame: FrameParams, tmd: TMDParams, omega: float, settings: CosimSettings, n: int
) -> CosimSteadyState:
    """The co-simulated steady state at omega [rad/s] with n communication steps per period."""
    t0 = time.perf_counter()
    W = settings.window_for(tmd)
    if W > 1 and settings.play_start == "companion":
        z = companion_start(unit, frame, tmd, omega, SolverSettings(rtol=1e-8, atol_scale=1e-8))
    else:
        z = initial_guess(unit, frame, tmd, omega)
    master.initialize(0.0, fmu_parameters(frame, tmd, omega, z, settings.fmu_rtol))
    T = 2.0 * math.pi / omega
    h = T / n
    ix, iv = master.signals.index("frame.x_top"), master.signals.index("frame.xd_top")
    t_rec, rec = np.zeros(n), np.zeros((n + 1, master.nsig))
    crit = WindowCriterion.from_settings(settings, W, frame, omega)
    if W == 1:
        crit.add(abs(master.y[ix]), (master.y[ix], master.y[iv]))
        crit.period_max.clear()
    k = 0
    while k < crit.max_periods:
        k += 1
        rec[0] = master.y
        master.advance(n, h, t_rec, rec[1:])
        amp = hermite_absmax_series(np.ascontiguousarray(rec[:, ix]), np.ascontiguousarray(rec[:, iv]), h)
        if crit.add(amp, (master.y[ix], master.y[iv])):
            break
    amplitude, converged, change = crit.result()
    return CosimSteadyState(
        omega=float(omega),
        amplitude=amplitude,
        state=z,
        periods=k,
        converged=converged,
        change=change,
        steps=k * n,
        wall_time=time.perf_counter() - t0,
        period_max=np.array(crit.period_max),
        irregular=crit.irregular,
        reason="" if converged else f"not settled within {k} periods (last relative change {change:.3g})",
        steps_per_period=n,
    )


def coupling_gap(
    unit: ModelUnit,
    master: Master,
    frame: FrameParams,
    tmd: TMDParams,
    omega: float,
    settings: CosimSettings,
    ss: CosimSteadyState,
) -> float:
    """Step-doubling estimate of the coupling error of ``ss`` (found with N steps per period): the gap
    between the steady-state amplitudes at N and N/2 steps per period, relative to max(|ss.amplitude|,
    :data:`~.checked.AMPLITUDE_FLOOR` |F|/K of the frame). The gap over-estimates the error of the N run
    for any order of the coupling >= 1. With a gear gap (window > 1: the rattle, whose error the play
    model's error model covers, :mod:`.checked`) the gap is that of the linear companion (the same
    spring, damper and inertance with an ideal inerter, no friction, no cubic term: from the exact
    linear start it settles in a few periods, where the friction's companion did not within 240) at
    the same N and N/2. inf when a run does not settle."""
    n = ss.steps_per_period
    smooth = tmd if settings.window_for(tmd) == 1 else replace(companion(tmd), friction_force=0.0, cubic_stiffness=0.0)
    fine = ss if smooth is tmd else steady_state(unit, master, frame, smooth, omega, settings, n)
    coarse = steady_state(unit, master, frame, smooth, omega, settings, max(n // 2, 8))
    if not (fine.converged and coarse.converged):
        return math.inf
    scale = max(abs(ss.amplitude), AMPLITUDE_FLOOR * abs(frame.force_amplitude) / frame.stiffness)
    return abs(fine.amplitude - coarse.amplitude) / scale if scale > 0 else math.inf


def checked_steady_state(
    unit: ModelUnit, master: Master, frame: FrameParams, tmd: TMDParams, omega: float, settings: CosimSettings, n: int
) -> CosimSteadyState:
    """The steady state at omega with n steps per period, its coupling error estimated by step
    doubling (:func:`coupling_gap`) and held to ``settings.coupling_tolerance``: above it the steps are
    doubled (at most :data:`MAX_REFINEMENTS` times, within ``max_steps_per_period``); a point whose
    estimate stays above is reported not converged, with the estimate, never as a converged answer."""
    tol = settings.coupling_tolerance(tmd)
    t0 = time.perf_counter()
    for k in range(MAX_REFINEMENTS + 1):
        ss = steady_state(unit, master, frame, tmd, omega, settings, n)
        if not ss.converged:
            break
        ss.coupling_error = coupling_gap(unit, master, frame, tmd, omega, settings, ss)
        if ss.coupling_error <= tol:
            break
        if k == MAX_REFINEMENTS or 2 * n > settings.max_steps_per_period:
            ss.converged = False
            ss.reason = (
                f"coupling error estimate {ss.coupling_error:.3g} above coupling_tol {tol:g} at {n} steps per "
                "period (step doubling)"
            )
            break
        n *= 2
    ss.wall_time = time.perf_counter() - t0
    return ss


def _impulse_tmd(tmd: TMDParams, settings: CosimSettings) -> TMDParams | None:
    """The TMD for :func:`make_master` when the settings ask for the impulse coupling, else None."""
    return tmd if settings.coupling == "impulse" else None


def _sweep_piece(
    unit: ModelUnit,
    frame: FrameParams,
    tmd: TMDParams,
    seq: Sequence[float],
    direction: str,
    settings: CosimSettings,
    z0: ArrayLike | None,
    queue: Any = None,
) -> tuple[list[dict[str, Any]], None]:
    master = make_master(frame, _impulse_tmd(tmd, settings), settings.order, settings.fmi_version, settings.fmu_build)
    rows = []
    try:
        for w in seq:
            n = max(settings.steps_for(tmd), int(settings.steps_per_period or 0))
            t0 = time.perf_counter()
            try:
                ss = checked_steady_state(unit, master, frame, tmd, float(w), settings, n)
            except MasterError as exc:  # this point is not converged, the sweep goes on with new FMUs
                master.close()
                master = make_master(
                    frame, _impulse_tmd(tmd, settings), settings.order, settings.fmi_version, settings.fmu_build
                )
                why = f"the FMUs failed at {n} steps per period: {str(exc).splitlines()[0][:300]}"
                ss = CosimSteadyState(float(w), math.nan, np.zeros(0), 0, False, math.inf, 0, 0.0, reason=why)
                ss.wall_time = time.perf_counter() - t0
            rows.append(ss.row(direction))
            if queue is not None:
                queue.put(1)
    finally:
        master.close()
    return rows, None


def sweep(
    unit: ModelUnit,
    frame: FrameParams,
    tmd: TMDParams,
    omegas: Sequence[float] | np.ndarray,
    direction: str = "up",
    settings: CosimSettings = CosimSettings(),
    progress: Callable[..., Any] | None = None,
    workers: int = 1,
) -> pd.DataFrame:
    """Co-simulated top-storey amplitudes over omegas (sorted), up, down or both; each frequency
    starts from the monolithic engine's start state (no continuation)."""
    accuracy = FRAME_ACCURACY if settings.accuracy is None else settings.accuracy
    settings = replace(settings, accuracy=accuracy)
    if frame.terminal != frame.tmd_at:  # the TMDI: force coupling, its steps from the force coupling's error model
        settings = replace(settings, coupling="force")
    piece = partial(_sweep_piece, unit)
    rows, _ = run_sweep_pieces(piece, frame, tmd, omegas, direction, settings, progress, None, workers)
    return pd.DataFrame(rows)


def engine(unit: ModelUnit) -> CosimEngine:
    """The frame's co-simulation as ``run-scenario`` calls it, for its unit (the unit's ``cosim`` returns
    ``engine(UNIT)``; this module imports no unit): its sweep (its steps come from the accuracy asked
    for, so nothing is refused up front, and it has no phase portrait)."""
    return CosimEngine(sweep=partial(sweep, unit))
