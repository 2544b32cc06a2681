"""The base + TMD pair as two co-simulated FMUs: connections, FMU parameters, the master, SSP export.

The two FMUs are BaseOscillator (``base``) and TMDInerter (``tmd``). Force coupling
(:data:`CONNECTIONS`)::

    base.x -> tmd.x, base.xd -> tmd.xd, base.xdd -> tmd.xdd, tmd.force -> base.f_link

(the ideal inerter makes ``base.xdd -> tmd.xdd -> tmd.force -> base.f_link -> base.xdd`` an
algebraic loop), or the momentum (impulse) coupling of :func:`impulse_connections`.
:func:`fmu_parameters` maps :class:`BaseParams` / :class:`TMDParams` and a start state onto the
FMU parameters (through the parameter registry), :func:`make_master` builds the generic
:class:`~pyfmu_wrapper.master.master.Master` for the pair and :func:`export_tmd_system` writes
the pair as an SSP file (:func:`pyfmu_wrapper.master.ssp.export_ssp`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..master.graph import Connection
from ..master.master import Master
from ..master.ssp import export_ssp
from ..physics import registry
from ..physics.params import BaseParams, TMDParams, has_gap
from ..solvers.start import initial_guess, play_atol

CONNECTIONS = ("base.x -> tmd.x", "base.xd -> tmd.xd", "base.xdd -> tmd.xdd", "tmd.force -> base.f_link")
RECORD = ("tmd.y", "tmd.yd")
#: smallest absolute tolerance [m] given to the FMUs: with no forcing (F = 0) the scale 1e-8 F/K is 0,
#: which the FMUs refuse (atol must be > 0); any forced configuration of the paper is far above it
ATOL_FLOOR = 1e-14

#: how the TMD force reaches the base (CosimSettings.coupling)
COUPLINGS = ("impulse", "force")


def fmu_parameters(base: BaseParams, tmd: TMDParams, omega: float, z0: ArrayLike, fmu_rtol: float = 1e-8) -> dict:
    """The FMU parameter values ("instance.variable" -> value) of a configuration and start state."""
    z = np.asarray(z0, dtype=float)
    out = registry.fmu_start_values(base, tmd, omega)
    out.update(
        {
            "base.x0": z[0],
            "base.xd0": z[1],
            "base.rtol": fmu_rtol,
            "base.atol": max(1e-8 * abs(base.force_amplitude) / base.stiffness, ATOL_FLOOR),
            "tmd.y0": z[2],
            "tmd.yd0": z[3],
            "tmd.d0": z[4],
            "tmd.dd0": z[5],
            "tmd.rtol": fmu_rtol,
            "tmd.atol": _tmd_atol(base, tmd),
        }
    )
    return out


def _tmd_atol(base: BaseParams, tmd: TMDParams) -> float:
    a = max(1e-8 * abs(base.force_amplitude) / base.stiffness, ATOL_FLOOR)
    if has_gap(tmd):
        a = min(a, play_atol(base, tmd))
    return a


def impulse_connections(tmd: TMDParams, interface_jacobian: bool = True) -> list:
    """Momentum coupling: the base gets the exact impulse of the links over each step, from the
    TMD's momentum balance m ydd = (force of the links) (the inerter chain is massless): mean
    f_link = m (yd(t + h) - yd(t)) / h over the step, handed to the base as a linear function with
    that mean and the slope between consecutive means; the TMD steps first. The base's change of
    momentum from the links is exact whatever the gear does inside the step, and no algebraic
    loop remains.

    interface_jacobian (default): the TMD gets the base's acceleration without the link force
    (``base.xdd_free -> tmd.xdd``) and, as the parameter ``tmd.base_compliance`` = 1/M set by
    :func:`make_master`, the base's compliance, so that within a step it adds the base's
    instantaneous reaction -force/M to its own force: the gear-mesh rattle meets a base that
    reacts without a step of delay. The base's force then also matches the first moment of the
    impulse (``integral_src="tmd.y"``: exact change of momentum *and* of position over every
    step), which without the interface Jacobian was less accurate because the TMD fed on the
    base's then jumpy end-of-step acceleration (docs/cosimulation.md, "interface Jacobian")."""
    if not interface_jacobian:
        return [*CONNECTIONS[:3], Connection("tmd.yd", "base.f_link", "rate", float(tmd.mass), "tmd.force")]
    return [
        CONNECTIONS[0],
        CONNECTIONS[1],
        "base.xdd_free -> tmd.xdd",
        Connection("tmd.yd", "base.f_link", "rate", float(tmd.mass), "tmd.force", integral_src="tmd.y"),
    ]


def pair_fmus() -> tuple[Any, ...]:
    """The pair's FMU declarations (BaseOscillator, TMDInerter), for the builders.

    TEMPORARY upward import (listed in tests/test_architecture.py's KNOWN_VIOLATIONS): the pair's
    co-simulation is moving into its model's folder (models/base_tmd/, issue 39), which gives its FMUs
    without reaching up."""
    from ..models.base_tmd import UNIT

    return UNIT.fmus()


def make_master(
    base: BaseParams | None = None,
    tmd: TMDParams | None = None,
    scheme: str = "loop",
    order: int = 2,
    fmus: dict | None = None,
    coupling: str = "force",
    interface_jacobian: bool = True,
    fmi_version: int = 2,
    fmu_build: str = "native",
) -> Master:
    """A master for the base + TMD pair (the FMUs are built if missing or stale).

    coupling: "force" (tmd.force -> base.f_link, the algebraic loop of the ideal inerter) or
    "impulse" (:func:`impulse_connections`; needs ``tmd``; ``interface_jacobian`` sets
    ``tmd.base_compliance`` = 1/M of ``base``); fmi_version: 2 or 3 (the FMUs of that version);
    fmu_build: "native" (the model compiled into the FMUs' binaries) or "python" (the Python-hosted
    FMUs, the reference)."""
    if fmus is None:
        if fmu_build == "native":
            from ..fmubuild.native_build import ensure_native_fmus

            paths = ensure_native_fmus(pair_fmus(), fmi_version=fmi_version)
        else:
            from ..fmubuild.build import ensure_fmus

            paths = ensure_fmus(pair_fmus(), fmi_version=fmi_version)
        fmus = {"base": paths["BaseOscillator"], "tmd": paths["TMDInerter"]}
    if coupling == "impulse":
        pars = {"tmd.base_compliance": 1.0 / (base or BaseParams()).mass} if interface_jacobian else {}
        return Master(
            fmus,
            impulse_connections(tmd or TMDParams(), interface_jacobian),
            pars,
            scheme="jacobi",
            order=order,
            record=RECORD,
        )
    return Master(fmus, CONNECTIONS, {}, scheme=scheme, order=order, record=RECORD)


def export_tmd_system(
    path: str | Path,
    base: BaseParams,
    tmd: TMDParams,
    omega: float,
    z0: ArrayLike | None = None,
    stop_time: float | None = None,
    step_size: float | None = None,
) -> Path:
    """SSP of the base + TMD pair of this project at excitation omega [rad/s] (start state z0,
    default the linear steady state of :func:`~pyfmu_wrapper.solvers.monolithic.initial_guess`;
    step_size: OMSimulator's master step, see :func:`pyfmu_wrapper.master.ssp.ssd_xml`)."""
    from ..fmubuild.build import ensure_fmus

    paths = ensure_fmus(pair_fmus())
    fmus = {"base": paths["BaseOscillator"], "tmd": paths["TMDInerter"]}
    z = initial_guess(base, tmd, omega) if z0 is None else z0
    return export_ssp(
        path,
        fmus,
        CONNECTIONS,
        fmu_parameters(base, tmd, omega, z),
        name="BaseTMD",
        stop_time=stop_time,
        step_size=step_size,
    )
