"""Wiring: the signals the master exchanges and where every FMU port reads and writes them.

A *signal* is one source port (``instance.output``) the master holds a value of: every source of
a connection, the ``init_src`` / ``integral_src`` ports of rate connections and the recorded
ports. The master keeps their values in one array ``y``; each :class:`~.instance.Instance` gets
the indices of its outputs in ``y`` (``sig_out``), of the sources of its inputs (``sig_in``),
the connection of each input (``conn_idx``) and, for rate connections, the ``rate_*`` fields.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .graph import ConnectionGraph
from .instance import Instance, MasterError

if TYPE_CHECKING:
    from typing import Any

    from .graph import Connection


@dataclass
class Wiring:
    """Result of :func:`wire`."""

    signals: list  #: port names, in the order of the signal array
    index: dict  #: port name -> position in the signal array
    conn_sig: np.ndarray  #: signal of the source of every connection (the coupling unknowns u_j)
    order_gs: list  #: instance names in the order of the graph condensation (Gauss-Seidel, loop-free pass)
    has_loops: bool
    rate: bool  #: any rate connection
    phase1: list  #: with rate connections: instances without rate inputs (they step first)
    phase2: list  #: instances with rate inputs

    @property
    def nsig(self) -> int:
        return len(self.signals)


def wire(
    instances: dict[str, Instance], graph: ConnectionGraph, record: list[Any | str], scheme: str, order: int
) -> Wiring:
    """Set every instance's ports and signal indices for the connections of ``graph`` plus the
    ``record`` ports; ``order`` is the extrapolation degree (:meth:`Instance.set_order`)."""
    conns = graph.connections
    # one signal per distinct source port, plus recorded ports
    signals: list[str] = []
    for c in conns:
        if c.src not in signals:
            signals.append(c.src)
        for extra in (c.init_src, c.integral_src):
            if extra is not None and extra not in signals:
                signals.append(extra)
    for r in record:
        if r not in signals:
            signals.append(r)
    sig_index = {s: i for i, s in enumerate(signals)}
    for s in signals:
        inst, var = s.split(".", 1)
        if inst not in instances or var not in instances[inst].vars:
            raise MasterError(f"unknown port {s!r}")
        instances[inst].outputs.append(var)
    for c in conns:
        instances[c.dst_instance].inputs.append(c.dst_variable)
    for ins in instances.values():
        ins.finalize_ports()
        ins.sig_out = np.array([sig_index[f"{ins.name}.{o}"] for o in ins.outputs], dtype=np.int64)
        src = {c.dst_variable: sig_index[c.src] for c in conns if c.dst_instance == ins.name}
        ins.sig_in = np.array([src[i] for i in ins.inputs], dtype=np.int64)
        ins.set_order(order)
        ins.conn_idx = np.array(
            [next(k for k, c in enumerate(conns) if c.dst == f"{ins.name}.{i}") for i in ins.inputs], dtype=np.int64
        )
        _wire_rate(ins, conns, sig_index)
    inst_list = list(instances.values())
    has_loops = bool(graph.loops)
    rate = any(len(ins.rate_pos) for ins in inst_list)
    phase1 = [i for i in inst_list if not len(i.rate_pos)] if rate else []
    phase2 = [i for i in inst_list if len(i.rate_pos)] if rate else []
    if rate:
        srcs2 = {s for i in phase2 for s in i.rate_src}
        if any(s in srcs2 for i in phase2 for s in i.sig_out):
            raise MasterError("an instance fed by a rate connection cannot be the source of one")
        if has_loops and scheme == "loop":
            raise MasterError("algebraic loops and rate connections together are not supported by the 'loop' scheme")
    return Wiring(
        signals=signals,
        index=sig_index,
        conn_sig=np.array([sig_index[c.src] for c in conns], dtype=np.int64),
        order_gs=graph.instance_order(),
        has_loops=has_loops,
        rate=rate,
        phase1=phase1,
        phase2=phase2,
    )


def _wire_rate(ins: Instance, conns: list[Connection], sig_index: dict) -> None:
    """The rate-connection fields of an instance: positions of its rate inputs, their source
    signals and gains, the ports giving their initial values and exact integrals."""
    rate = [(j, conns[k]) for j, k in enumerate(ins.conn_idx) if conns[k].kind == "rate"]
    ins.rate_pos = np.array([j for j, _ in rate], dtype=np.int64)
    ins.rate_src = np.array([sig_index[c.src] for _, c in rate], dtype=np.int64)
    ins.rate_gain = np.array([c.gain for _, c in rate], dtype=float)
    ins.rate_init = [None if c.init_src is None else sig_index[c.init_src] for _, c in rate]
    ins.rate_int = np.array(
        [-1 if c.integral_src is None else sig_index[c.integral_src] for _, c in rate], dtype=np.int64
    )
    ins.rate_has_int = ins.rate_int >= 0
    reset_rate(ins)


def reset_rate(ins: Instance) -> None:
    """Forget the previous step's mean rate (at initialisation)."""
    ins.rate_prev = np.zeros(len(ins.rate_pos))  # mean of the previous step (for the slope)
    ins.rate_ready = False
