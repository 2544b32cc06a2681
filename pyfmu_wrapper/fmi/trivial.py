"""The support FMU Trivial (y = gain * u, a step only advances time): its declaration and its slave, one place.

It belongs to no model: the stub's per-call overhead benchmark and the tests of the FMU machinery use it.
:mod:`pyfmu_wrapper.models.catalog` lists it after the models' FMUs; ``build-fmus`` builds it only on
request. Every Python-hosted FMU bundles this module (:data:`pyfmu_wrapper.fmubuild.bundle.ROOTS`): a model's
FMUs carry the same bundle with or without Trivial, and share it with a Trivial built with them.
"""

from __future__ import annotations

from typing import Any

from numpy.typing import NDArray

from .fmumodel import FmuModel
from .slave import Slave, guarded
from .varspec import REAL, FmuSpec, Variable, parameter

# A do-nothing model used only to measure the per-call overhead of the stub (benchmarks).
TRIVIAL = FmuSpec(
    model_name="Trivial",
    model_identifier="Trivial",
    description="y = gain * u; doStep only advances time (stub overhead benchmark)",
    variables=(
        parameter("gain", 0, 2.0, None, "gain"),
        Variable(
            name="u",
            vr=1,
            type=REAL,
            causality="input",
            variability="continuous",
            description="input",
            unit=None,
            start=0.0,
        ),
        Variable(
            name="y",
            vr=2,
            type=REAL,
            causality="output",
            variability="continuous",
            description="gain * u",
            unit=None,
            initial="calculated",
            depends_on=("u",),
            dependencies_kind=("fixed",),
            initial_depends_on=("gain", "u"),
        ),
    ),
    provides_directional_derivative=True,
)


class TrivialSlave(Slave):
    """y = gain * u; a step only advances time (measures the stub's own overhead)."""

    spec = TRIVIAL
    n_state = 0

    def outputs(self, inputs: NDArray[Any]) -> list[Any]:
        return [self.r[0] * inputs[0]]

    @guarded
    def do_step(self, t: float, h: float, no_set_prior: int) -> None:
        self.t = t + h
        self.r[2] = self.r[0] * self.r[1]


FMU = FmuModel(spec=TRIVIAL, slave=TrivialSlave)
