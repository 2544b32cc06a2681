"""The shear frame with its TMD as two co-simulated FMUs: ShearFrame (``frame``) and TMDInerter
(``tmd``), coupled by forces at two storeys (native or Python-hosted FMUs, ``CosimSettings.fmu_build``): the
unit's :class:`~pyfmu_wrapper.cosim.system.CosimSystem` (:class:`FramePairSystem`) and
:class:`~pyfmu_wrapper.cosim.system.CosimEngine` (:func:`engine`).

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
force coupling left 1-7 % and irregular windows).

The steady states, their coupling-error check and the sweeps are the co-simulation engine's
(:mod:`pyfmu_wrapper.cosim.steady`), as for the paper's pair: every storey's x_i, xd_i and the TMD's y, yd
are FMU outputs (ShearFrame's ``x_i``, ``xd_i``; TMDInerter's ``y``, ``yd``), so a configuration without a
gear gap is solved by Newton shooting on the co-simulated period map (a linear one in one Newton step once the
period map's Jacobian is formed) and its coupling error estimated by step doubling from that orbit; the
play model runs period after period from its smooth companion's orbit, its coupling error that of the
companion. The frame's own modes need no resolving by the communication step (ShearFrame steps exactly, by
the matrix exponential): the time scales (:meth:`FramePairSystem.time_scales`) are those of the TMD against its
storey.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from ...cosim import steady as cosim_steady
from ...cosim.settings import CosimSettings, fmu_atol
from ...cosim.system import CosimEngine, Scale
from ...cosim.timescales import parameter_text, ratio_sqrt
from ...master.graph import Connection
from ...master.master import Master
from ...physics import registry
from ...physics.params import BaseParams, InerterModel, TMDParams, has_gap, is_detached
from ...physics.unit import ModelUnit
from ...solvers.start import play_atol
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
    atol = fmu_atol(frame.force_amplitude, frame.stiffness, ATOL_FLOOR)
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
    from ...fmubuild.variants import ensure_variant

    paths = ensure_variant(frame_fmus(), fmu_build, fmi_version)
    fmus: dict[str, str | Path] = {"frame": paths["ShearFrame"], "tmd": paths["TMDInerter"]}
    conns = connections(frame, tmd)
    impulse = any(not isinstance(c, str) for c in conns)
    record = tuple(dict.fromkeys(RECORD + tuple(o for o in state_outputs(frame.n) if o is not None)))
    return Master(fmus, conns, {}, scheme="jacobi" if impulse else "loop", order=order, record=record)


def frame_scales(frame: FrameParams, tmd: TMDParams) -> list[Scale]:
    """The time scales a communication step has to resolve (:mod:`pyfmu_wrapper.cosim.timescales`): those of the
    TMD against the storeys it acts on (ShearFrame steps the frame's own modes exactly): the TMD alone on a
    storey held still, sqrt(k/(m + I)); the storey s it hangs on swinging on the TMD's spring, sqrt(k/M_s); and,
    with an inerter, its terminal j against it, sqrt(k I/((m + I) M_j))."""
    m, k, inert = float(tmd.mass), float(tmd.stiffness), float(tmd.inertance)
    s = frame.tmd_at
    ms = frame.masses[s - 1]
    pars = {
        "m": parameter_text("tmd.mass (m)", m, "kg"),
        "k": parameter_text("tmd.stiffness (k)", k, "N/m"),
        "I": parameter_text("tmd.inertance (I)", inert, "kg"),
        "Ms": parameter_text(f"frame.mass of storey {s} (M_{s})", ms, "kg"),
    }
    out = [
        Scale(ratio_sqrt(k, m + inert), f"the TMD alone, sqrt(k/(m + I)) ({pars['k']}, {pars['m']}, {pars['I']})"),
        Scale(ratio_sqrt(k, ms), f"storey {s} on the TMD's spring, sqrt(k/M_{s}) ({pars['k']}, {pars['Ms']})"),
    ]
    j = frame.terminal
    if inert > 0.0 and tmd.inerter != InerterModel.NONE and j > 0:
        mj = frame.masses[j - 1]
        out.append(
            Scale(
                ratio_sqrt(k * inert, (m + inert) * mj),
                f"the inerter against storey {j}, sqrt(k I/((m + I) M_{j})) ({pars['k']}, {pars['I']}, {pars['m']}, "
                f"{parameter_text(f'frame.mass of storey {j} (M_{j})', mj, 'kg')})",
            )
        )
    return out


def state_outputs(n: int, detached: bool = False) -> tuple[str | None, ...]:
    """The FMU output of each entry of the frame unit's state (:mod:`.equations`' layout: x_n, xd_n, y, yd, d, dd,
    then x_i, xd_i from storey n - 1 down to 1); the play chain's d, dd are no output (None), nor the TMD's y, yd
    when it is ``detached`` (no link: a free mass, whose drift would make the period map's Jacobian singular)."""
    tmd: list[str | None] = [None, None] if detached else ["tmd.y", "tmd.yd"]
    out: list[str | None] = ["frame.x_top", "frame.xd_top", *tmd, None, None]
    for i in range(n - 1, 0, -1):
        out += [f"frame.x_{i}", f"frame.xd_{i}"]
    return tuple(out)


@dataclass(frozen=True)
class FramePairSystem:
    """The frame and its TMD as a :class:`~pyfmu_wrapper.cosim.system.CosimSystem` (module doc)."""

    unit: ModelUnit  #: the frame unit (the package gives it: :func:`engine`)
    structure: FrameParams
    tmd: TMDParams

    observed: tuple[str, str] = ("frame.x_top", "frame.xd_top")

    @property
    def state_outputs(self) -> tuple[str | None, ...]:
        return state_outputs(self.structure.n, is_detached(self.tmd))

    def with_tmd(self, tmd: TMDParams) -> FramePairSystem:
        return replace(self, tmd=tmd)

    def make_master(self, settings: CosimSettings) -> Master:
        impulse = self.tmd if settings.coupling == "impulse" else None
        return make_master(self.structure, impulse, settings.order, settings.fmi_version, settings.fmu_build)

    def parameters(self, omega: float, z: NDArray[np.float64], fmu_rtol: float) -> dict[str, Any]:
        return fmu_parameters(self.structure, self.tmd, omega, z, fmu_rtol)

    def time_scales(self) -> list[Scale]:
        return frame_scales(self.structure, self.tmd)

    def reaction_mass(self) -> float:
        return float(self.structure.masses[self.structure.tmd_at - 1])

    def shooting_scale(self, z: NDArray[np.float64], omega: float) -> NDArray[np.float64]:
        """One scale for every shot (x, xd/w) pair: the largest orbit's, at least 1e-6 F/K."""
        frame = self.structure
        pairs = np.asarray(z, dtype=float).reshape(-1, 2)
        amp = max(
            float(np.max(np.hypot(pairs[:, 0], pairs[:, 1] / omega))),
            1e-6 * abs(frame.force_amplitude) / frame.stiffness,
        )
        return np.tile([amp, amp * omega], pairs.shape[0])


def _sweep(
    make_system: Callable[[FrameParams, TMDParams], FramePairSystem],
    frame: FrameParams,
    tmd: TMDParams,
    omegas: Sequence[float] | np.ndarray,
    direction: str = "up",
    settings: CosimSettings = CosimSettings(),
    progress: Callable[..., Any] | None = None,
    z0: ArrayLike | None = None,
    workers: int = 1,
) -> pd.DataFrame:
    """The engine's sweep with the frame's defaults (:func:`frame_settings`)."""
    settings = frame_settings(frame, settings)
    return cosim_steady.sweep(make_system(frame, tmd), omegas, direction, settings, progress, z0, workers)


def frame_settings(frame: FrameParams, settings: CosimSettings) -> CosimSettings:
    """The settings with the frame's defaults: the accuracy :data:`FRAME_ACCURACY` unless the settings ask
    another, and the force coupling for the TMDI (its inerter on another storey: no impulse coupling)."""
    accuracy = FRAME_ACCURACY if settings.accuracy is None else settings.accuracy
    settings = replace(settings, accuracy=accuracy)
    if frame.terminal != frame.tmd_at:
        settings = replace(settings, coupling="force")
    return settings


def _points(
    make_system: Callable[[FrameParams, TMDParams], FramePairSystem],
    frame: FrameParams,
    tmd: TMDParams,
    settings: CosimSettings,
) -> cosim_steady.PointSolver:
    return cosim_steady.PointSolver(make_system(frame, tmd), frame_settings(frame, settings))


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
    """Co-simulated top-storey amplitudes over omegas (sorted), up, down or both (:func:`engine`'s sweep)."""
    return _sweep(partial(FramePairSystem, unit), frame, tmd, omegas, direction, settings, progress, None, workers)


def engine(unit: ModelUnit) -> CosimEngine:
    """The frame's co-simulation as ``run-scenario`` calls it, for its unit (the unit's ``cosim`` returns
    ``engine(UNIT)``; this module imports no unit): the engine's on :class:`FramePairSystem`, its sweep with the
    frame's defaults (:func:`_sweep`)."""
    make_system = partial(FramePairSystem, unit)
    return replace(
        cosim_steady.engine_of(make_system, prepare=prepare),
        sweep=partial(_sweep, make_system),
        points=partial(_points, make_system),
    )


def prepare(settings: CosimSettings) -> list[str]:
    """Builds, or checks, the frame's co-simulation FMUs in the settings' build and FMI version: their names."""
    from ...fmubuild.variants import ensure_variant

    return list(ensure_variant(frame_fmus(), settings.fmu_build, settings.fmi_version))
