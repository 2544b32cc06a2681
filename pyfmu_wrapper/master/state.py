"""What the master's split-off helpers (:mod:`.cloop`, :mod:`.stepcontrol`) read and advance of a
master: its coupling state and its stepping, as a :class:`typing.Protocol`. The helpers take any
object of this shape (the :class:`~.master.Master` is one) and import nothing of the master module,
so the master imports them without an import circle."""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import numpy as np

    from .extrapolation import History
    from .instance import Instance
    from .schemes import Stepper
    from .wiring import Wiring


class MasterState(Protocol):
    """The master's state and steps, as the compiled loop and the step-size control use them."""

    stepper: Stepper  #: the scheme taking one communication step, and its instances
    wiring: Wiring  #: signals, connections and phases
    history: History  #: past communication points (for the extrapolation)
    instances: dict[str, Instance]
    signals: list[str]
    nsig: int
    y: np.ndarray  #: the signals' current values
    t: float
    steps: int
    rejected: int

    @property
    def scheme(self) -> str: ...

    @property
    def order(self) -> int: ...

    def step(self, h: float) -> None: ...

    def advance(self, n: int, h: float, rec_t: np.ndarray | None = None, rec_y: np.ndarray | None = None) -> None: ...

    def error_estimate(self, rtol: float, atol: float) -> float: ...
