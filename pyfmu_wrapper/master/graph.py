"""Connection graph of a co-simulation and its algebraic loops.

Nodes are the ports ``"instance.variable"`` of every FMU. Edges are

* connections: output (or parameter) of one FMU -> input of another (from the connection list);
* direct feed-through inside an FMU: input -> output, read from the ``ModelStructure/Outputs``
  dependencies of its ``modelDescription.xml`` (an output without a ``dependencies`` attribute
  depends on *all* inputs, FMI 2.0 Sect. 2.2.8).

An algebraic loop is a strongly connected component (Tarjan) of this graph with more than one
node: within one communication point its outputs depend on themselves (for the ideal inerter:
``base.xdd -> tmd.xdd -> tmd.force -> base.f_link -> base.xdd``). The master must solve such a
component at every communication point (or accept the error of ignoring it). Components that are
not in a loop are ordered topologically (the condensation of the graph), which is the order a
Gauss-Seidel master steps them in.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from fmpy.model_description import ModelDescription


class GraphError(ValueError):
    """An inconsistent connection list (unknown instance or variable, wrong causality, two sources)."""


#: a connection as a master is given it: a Connection, "a.x -> b.u", a dict of its fields, or (src, dst[, kind])
ConnectionLike = Any


@dataclass(frozen=True)
class Connection:
    """``src`` output -> ``dst`` input, both written ``"instance.variable"``.

    kind ``"value"`` (default): the input equals the output. kind ``"rate"``: over each
    communication step the input carries ``gain`` times the mean rate of change of the output,
    gain (src(t+h) - src(t)) / h (e.g. a force as the momentum change of a mass: the exact impulse
    over the step). The source must step before the destination; ``init_src`` names an output
    whose value the input takes during initialisation. ``integral_src`` (optional) names an
    output whose time derivative is ``src`` (a displacement for a velocity): the input over the
    step is then the linear function with the exact mean *and* first moment of gain * d(src)/dt,
    int tau f dtau = gain (h src(t+h) - (integral_src(t+h) - integral_src(t))); a mass driven by
    it gets the exact change of momentum and of position from the link over every step.
    """

    src: str
    dst: str
    kind: str = "value"
    gain: float = 1.0
    init_src: str | None = None
    integral_src: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in ("value", "rate"):
            raise GraphError(f"connection {self.src} -> {self.dst}: kind must be 'value' or 'rate'")

    @property
    def src_instance(self) -> str:
        return self.src.split(".", 1)[0]

    @property
    def dst_instance(self) -> str:
        return self.dst.split(".", 1)[0]

    @property
    def src_variable(self) -> str:
        return self.src.split(".", 1)[1]

    @property
    def dst_variable(self) -> str:
        return self.dst.split(".", 1)[1]

    @staticmethod
    def parse(item: ConnectionLike) -> Connection:
        if isinstance(item, Connection):
            return item
        if isinstance(item, str):
            a, b = (s.strip() for s in item.split("->"))
            return Connection(a, b)
        if isinstance(item, dict):
            return Connection(**item)
        a, b, *rest = item
        return Connection(str(a), str(b), *rest)


@dataclass
class ConnectionGraph:
    """Ports, edges and the strongly connected components of a coupled system."""

    connections: list[Connection]
    feedthrough: dict[str, list[str]]  #: "inst.output" -> ["inst.input", ...] it depends on directly
    edges: dict[str, list[str]] = field(default_factory=dict)
    sccs: list[list[str]] = field(default_factory=list)  #: in topological order (sources first)

    @property
    def loops(self) -> list[list[str]]:
        """The algebraic loops: components with more than one port (or a self edge)."""
        return [c for c in self.sccs if len(c) > 1 or c[0] in self.edges.get(c[0], ())]

    def loop_connections(self) -> list[list[Connection]]:
        """For every algebraic loop, the connections whose both ends lie in it (the tearing variables)."""
        out = []
        for loop in self.loops:
            s = set(loop)
            out.append([c for c in self.connections if c.src in s and c.dst in s])
        return out

    def instance_order(self) -> list[str]:
        """Instances in the order of the condensation (for Gauss-Seidel): an instance comes after
        every instance it receives an input from outside a loop."""
        seen: list[str] = []
        for comp in self.sccs:
            for port in comp:
                inst = port.split(".", 1)[0]
                if inst not in seen:
                    seen.append(inst)
        return seen


def _direct_dependencies(md: ModelDescription) -> dict[str, list[str]]:
    inputs = [v for v in md.modelVariables if v.causality == "input"]
    deps: dict[str, list[str]] = {}
    listed = set()
    for unk in md.outputs:
        v = unk.variable
        listed.add(v.name)
        if unk.dependencies is None:  # attribute absent: depends on all inputs
            deps[v.name] = [i.name for i in inputs]
        else:
            deps[v.name] = [d.name for d in unk.dependencies if d.causality == "input"]
    for v in md.modelVariables:  # outputs missing from ModelStructure: assume full dependency
        if v.causality == "output" and v.name not in listed:
            deps[v.name] = [i.name for i in inputs]
    return deps


def build_graph(
    descriptions: dict[str, ModelDescription],
    connections: Iterable[ConnectionLike],
) -> ConnectionGraph:
    """The connection graph of instances (name -> model description) and a connection list.

    ``connections`` items are :class:`Connection`, ``(src, dst)`` pairs or ``"a.x -> b.u"`` strings.
    """
    conns = [Connection.parse(c) for c in connections]
    variables = {name: {v.name: v for v in md.modelVariables} for name, md in descriptions.items()}
    dsts = set()
    for c in conns:
        for inst, var in ((c.src_instance, c.src_variable), (c.dst_instance, c.dst_variable)):
            if inst not in variables:
                raise GraphError(f"connection {c.src} -> {c.dst}: unknown instance {inst!r}")
            if var not in variables[inst]:
                raise GraphError(f"connection {c.src} -> {c.dst}: {inst} has no variable {var!r}")
        if variables[c.dst_instance][c.dst_variable].causality != "input":
            raise GraphError(f"connection {c.src} -> {c.dst}: the destination is not an input")
        if variables[c.src_instance][c.src_variable].causality not in ("output", "parameter", "calculatedParameter"):
            raise GraphError(f"connection {c.src} -> {c.dst}: the source is not an output")
        if c.dst in dsts:
            raise GraphError(f"input {c.dst} has more than one source")
        dsts.add(c.dst)

    feed: dict[str, list[str]] = {}
    edges: dict[str, list[str]] = {}
    nodes: list[str] = []
    for inst, md in descriptions.items():
        for v in md.modelVariables:
            if v.causality in ("input", "output"):
                nodes.append(f"{inst}.{v.name}")
        for out, ins in _direct_dependencies(md).items():
            feed[f"{inst}.{out}"] = [f"{inst}.{i}" for i in ins]
            for i in ins:
                edges.setdefault(f"{inst}.{i}", []).append(f"{inst}.{out}")
    for c in conns:
        if c.src not in nodes:
            nodes.append(c.src)
        if c.kind == "value":  # a rate input is known before its instance steps: no algebraic edge
            edges.setdefault(c.src, []).append(c.dst)
    g = ConnectionGraph(conns, feed, edges)
    g.sccs = _tarjan(nodes, edges)
    return g


def _tarjan(nodes: list[str], edges: dict[str, list[str]]) -> list[list[str]]:
    """Strongly connected components, returned in topological order of the condensation."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on: set[str] = set()
    stack: list[str] = []
    out: list[list[str]] = []
    counter = [0]

    def visit(v: str) -> None:
        # iterative Tarjan (no recursion limit on large graphs)
        work = [(v, iter(edges.get(v, ())))]
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        while work:
            node, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(edges.get(w, ()))))
                    advanced = True
                    break
                if w in on:
                    low[node] = min(low[node], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == node:
                        break
                out.append(sorted(comp))

    for n in nodes:
        if n not in index:
            visit(n)
    out.reverse()  # Tarjan emits sinks first
    return out
