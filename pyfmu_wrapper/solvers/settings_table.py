"""The settings of both engines, declared once: name, type, default per engine, bounds, unit, meaning.

As the model parameters are declared in :mod:`pyfmu_wrapper.physics.registry`, every setting of
the monolithic engine (:class:`~pyfmu_wrapper.solvers.monolithic.SolverSettings`) and the
co-simulation engine (:class:`~pyfmu_wrapper.cosim.settings.CosimSettings`) is one row of
:data:`SETTINGS`. From it derive:

* the settings classes' defaults (:func:`default`) and their range checks
  (:meth:`Setting.problem`, applied by :meth:`pyfmu_wrapper.solvers.steady.SteadySettings.validate`);
* the scenario loader's checks (a value the settings class refuses becomes an error naming the
  file, the line, ``block.key`` and the value: one rule, not two);
* the table of settings in docs/scenarios.md (:func:`docs_table`, kept current by
  ``python -m pyfmu_wrapper.generate.docs --check``).

One rule per setting: where the loader and the settings classes disagreed, the stricter one is
kept: tol and tol_window at most 0.5 (a relative tolerance above one half accepts any response;
0 stays allowed, it means "never settled" and makes fixed-length runs); steps_per_period at least 8
(the cubic Hermite maximum of |x| between communication points needs a few points per period, the
settings class allowed 1); rtol and fmu_rtol at most 0.1; accuracy at most 0.5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

MONO, COSIM = "monolithic", "cosim"
BOTH = (MONO, COSIM)

#: the integrator's default cap on steps per call (solvers.rodas.DEFAULT_MAX_STEPS)
_MAX_STEPS = 1_000_000


@dataclass(frozen=True)
class Setting:
    """One setting. kind: "number", "integer", "choice" or "boolean"; defaults: {engine: default}
    (the engines it applies to are the keys); minimum / strict / maximum: the range of a number or
    integer (strict: minimum excluded); optional: None allowed (meaning in ``meaning``);
    choices: the allowed values of a choice; scenario: readable from a scenario file."""

    name: str
    kind: str
    defaults: dict
    unit: str
    meaning: str
    minimum: float | None = None
    strict: bool = False
    maximum: float | None = None
    optional: bool = False
    choices: tuple = ()
    #: the engines whose scenario block (solver:, cosim:) accepts the key (None: all of ``engines``)
    scenario: tuple | None = None

    @property
    def engines(self) -> tuple[str, ...]:
        return tuple(e for e in BOTH if e in self.defaults)

    @property
    def blocks(self) -> tuple[str, ...]:
        """The engines whose scenario block reads this setting."""
        return self.engines if self.scenario is None else tuple(self.scenario)

    def rule(self) -> str:
        """The range rule in words (as the error messages and the docs state it)."""
        if self.kind == "boolean":
            r = "true or false"
        elif self.kind == "choice":
            r = "one of " + ", ".join(map(str, self.choices))
        else:
            what = "an integer" if self.kind == "integer" else "a finite number"
            parts = []
            if self.minimum is not None:
                parts.append(f"{'>' if self.strict else '>='} {self.minimum:g}")
            if self.maximum is not None:
                parts.append(f"<= {self.maximum:g}")
            r = what + (" " + " and ".join(parts) if parts else "")
        return r + (" (or null)" if self.optional else "")

    def problem(self, v: Any) -> str | None:
        """None if v is allowed, else the reason ("must be ...")."""
        if v is None and self.optional:
            return None
        ok = True
        if self.kind == "boolean":
            ok = isinstance(v, (bool, np.bool_))
        elif self.kind == "choice":
            ok = v in self.choices
        else:
            if self.kind == "integer":
                ok = isinstance(v, (int, np.integer)) and not isinstance(v, bool)
            else:
                ok = (
                    isinstance(v, (int, float, np.integer, np.floating))
                    and not isinstance(v, bool)
                    and math.isfinite(v)
                )
            if ok and self.minimum is not None:
                ok = v > self.minimum if self.strict else v >= self.minimum
            if ok and self.maximum is not None:
                ok = v <= self.maximum
        return None if ok else "must be " + self.rule()


def _s(name: str, kind: str, defaults: dict[str, Any], unit: str, meaning: str, **kw: Any) -> Setting:
    return Setting(name, kind, defaults, unit, meaning, **kw)


SETTINGS: tuple[Setting, ...] = (
    # -- the steady-state definition, shared by both engines (solvers.steady) ------------------------
    _s(
        "tol",
        "number",
        {MONO: 1e-6, COSIM: 1e-6},
        "1",
        "steady-state tolerance of a periodic response (window 1): Newton correction or distance of the "
        "state to the orbit, relative (0: never settled, the run lasts max_periods)",
        minimum=0.0,
        maximum=0.5,
    ),
    _s(
        "tol_window",
        "number",
        {MONO: 1e-4, COSIM: 1e-3},
        "1",
        "agreement of two window maxima (window > 1), relative (0: never settled, for fixed-length runs); "
        "co-simulation 1e-3, below its amplitude accuracy with a gear gap (2.5e-3): its coupling error makes "
        "the rattle's window maxima scatter by about 1e-3",
        minimum=0.0,
        maximum=0.5,
    ),
    _s(
        "window",
        "integer",
        {MONO: None, COSIM: None},
        "periods",
        "periods per steady-state window (null: 20 with a gear gap, 1 otherwise)",
        minimum=1,
        optional=True,
    ),
    _s("min_periods", "integer", {MONO: 3, COSIM: 3}, "periods", "least periods per frequency", minimum=1),
    _s(
        "max_periods",
        "integer",
        {MONO: 3000, COSIM: 240},
        "periods",
        "most periods per frequency (at least min_periods)",
        minimum=1,
    ),
    _s(
        "scatter_tol",
        "number",
        {MONO: 5e-3, COSIM: 5e-3},
        "1",
        "largest scatter of the window maxima an irregular response may have and still count as converged",
        minimum=0.0,
        scenario=(),
    ),
    _s(
        "play_start",
        "choice",
        {MONO: "companion", COSIM: "companion"},
        "-",
        "where a windowed solve starts: companion (the smooth companion's orbit, chain at its contact) or "
        "previous (the previous frequency's state)",
        choices=("companion", "previous"),
        scenario=(),
    ),
    _s("shooting", "boolean", {MONO: True, COSIM: True}, "-", "Newton shooting for window 1", scenario=(COSIM,)),
    _s(
        "max_newton",
        "integer",
        {MONO: 8, COSIM: 12},
        "iterations",
        "cap on the shooting iterations",
        minimum=1,
        scenario=(),
    ),
    # -- the monolithic engine (solvers.monolithic.SolverSettings) ----------------------------------
    _s(
        "rtol",
        "number",
        {MONO: 1e-8},
        "1",
        "relative tolerance of the integrator",
        minimum=0.0,
        strict=True,
        maximum=0.1,
    ),
    _s(
        "atol_scale",
        "number",
        {MONO: 1e-6},
        "1",
        "absolute tolerance as a fraction of the static deflection F/K (rates scaled by the natural frequency)",
        minimum=0.0,
        strict=True,
    ),
    _s(
        "max_periods_window",
        "integer",
        {MONO: 600},
        "periods",
        "most periods of a windowed steady state",
        minimum=1,
        scenario=(),
    ),
    _s(
        "max_steps",
        "integer",
        {MONO: _MAX_STEPS},
        "steps",
        "cap on integrator steps per period (a stalled integration is an error naming time, state and mode)",
        minimum=1,
        scenario=(),
    ),
    # -- the co-simulation engine (cosim.settings.CosimSettings) ----------------------------------------
    _s(
        "steps_per_period",
        "integer",
        {COSIM: None},
        "steps",
        "communication steps per forcing period (null: from accuracy)",
        minimum=8,
        maximum=100_000,
        optional=True,
    ),
    _s(
        "accuracy",
        "number",
        {COSIM: None},
        "1",
        "relative amplitude accuracy asked for (null: 1e-3, 2.5e-3 with a gear gap); sets steps_per_period",
        minimum=0.0,
        strict=True,
        maximum=0.5,
        optional=True,
    ),
    _s(
        "coupling_tol",
        "number",
        {COSIM: 5e-3},
        "1",
        "tolerance of the coupling-error estimate (the amplitude's gap to the same steady state at half the "
        "steps) at every point; a point above it is refined (steps doubled) or reported not converged",
        minimum=0.0,
        strict=True,
        maximum=0.5,
    ),
    _s(
        "max_steps_per_period",
        "integer",
        {COSIM: 262_144},
        "steps",
        "most communication steps per forcing period; a point whose structure (its fastest natural frequency) "
        "needs more is refused and reported not converged",
        minimum=32,
        maximum=4_000_000,
    ),
    _s(
        "coupling",
        "choice",
        {COSIM: "impulse"},
        "-",
        "impulse (momentum exchange, no algebraic loop) or force (the inerter's loop solved by Newton)",
        choices=("impulse", "force"),
    ),
    _s(
        "scheme",
        "choice",
        {COSIM: "loop"},
        "-",
        "force coupling: master algorithm",
        choices=("loop", "jacobi", "gauss-seidel"),
    ),
    _s("order", "integer", {COSIM: 2}, "-", "extrapolation order of the exchanged inputs", minimum=0, maximum=2),
    _s(
        "fmu_rtol",
        "number",
        {COSIM: 1e-8},
        "1",
        "relative tolerance of the integrators inside the FMUs",
        minimum=0.0,
        strict=True,
        maximum=0.1,
    ),
    _s(
        "interface_jacobian",
        "boolean",
        {COSIM: True},
        "-",
        "impulse coupling: hand the TMD the base's compliance 1/M (no delay of the base's reaction)",
    ),
    _s(
        "fmi_version",
        "integer",
        {COSIM: 2},
        "-",
        "FMI version of the two FMUs the master runs (2: FMI 2.0, 3: FMI 3.0 built from the same declaration; "
        "same numbers)",
        minimum=2,
        maximum=3,
    ),
    _s(
        "fmu_build",
        "choice",
        {COSIM: "native"},
        "-",
        "which build of the two FMUs the master runs: native (the model compiled into the FMU's binary, no Python) "
        "or python (the Python-hosted FMUs, the reference; the same numbers bit for bit)",
        choices=("native", "python"),
    ),
)

BY_NAME = {s.name: s for s in SETTINGS}


def default(name: str, engine: str) -> Any:
    """The default of setting ``name`` in ``engine`` (the settings classes' field defaults)."""
    return BY_NAME[name].defaults[engine]


def settings_of(engine: str) -> tuple[Setting, ...]:
    return tuple(s for s in SETTINGS if engine in s.defaults)


def shared() -> tuple[Setting, ...]:
    """The settings of the steady-state definition, which both engines have."""
    return tuple(s for s in SETTINGS if set(s.engines) == set(BOTH))


def _fmt(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return f"{v:g}"
    return str(v)


def docs_table() -> str:
    """The Markdown table of the settings (docs/scenarios.md, between the generated markers)."""
    rows = ["| setting | block(s) | default (solver / cosim) | allowed | unit | meaning |", "|---|---|---|---|---|---|"]
    for s in SETTINGS:
        blocks = " and ".join({MONO: "solver", COSIM: "cosim"}[e] for e in s.blocks) or "(API only)"
        d = " / ".join(_fmt(s.defaults[e]) if e in s.defaults else "-" for e in BOTH)
        rows.append(f"| {s.name} | {blocks} | {d} | {s.rule()} | {s.unit} | {s.meaning} |")
    return "\n".join(rows) + "\n"
