"""The coupling equations u = G(u) and their solution by Newton's method.

The unknowns are the connected inputs, one per connection: u_j = value of input dst_j. G maps
them to the source outputs of the connections, G_j(u) = src_j, with the outputs depending
directly on the inputs as declared in the FMUs' ModelStructure (the feed-through edges of the
graph). The coupling Jacobian dG/du is assembled from the FMUs' directional derivatives
(``fmi2GetDirectionalDerivative``; central finite differences if an FMU does not provide it),
restricted to the declared dependencies. Newton's iteration u <- u + (I - dG/du)^-1 (G(u) - u)
reuses the Jacobian while it contracts (chord Newton) and refreshes it after three iterations;
for a linear feed-through (the ideal inerter) one correction is exact.
"""

from __future__ import annotations

import numpy as np

from .graph import ConnectionGraph
from .instance import Instance, MasterError


class CouplingSolver:
    """Solves the coupling equations at the current communication point of a set of instances.

    y: the master's signal array (read and written in place); conn_sig: the signal of the source
    of every connection; tol: relative tolerance on |G(u) - u|; max_iter: Newton iterations
    before :class:`~.instance.MasterError`."""

    def __init__(
        self,
        graph: ConnectionGraph,
        instances: dict[str, Instance],
        y: np.ndarray,
        conn_sig: np.ndarray,
        order_gs: list[str],
        has_loops: bool,
        tol: float = 1e-10,
        max_iter: int = 20,
    ) -> None:
        self.graph = graph
        self.instances = instances
        self.inst_list = list(instances.values())
        self.y = y
        self.conn_sig = conn_sig
        self.order_gs = order_gs
        self.has_loops = has_loops
        self.tol, self.max_iter = tol, max_iter
        self.jac_inv: np.ndarray | None = None  #: (I - dG/du)^-1, None until the first solve
        self.uscale: np.ndarray | None = None  #: running scale max |u|, |G(u)| of the loop unknowns

    def reset(self) -> None:
        """Forget the Jacobian (new parameters or a new initialisation)."""
        self.jac_inv = None

    def coupling_jacobian(self) -> np.ndarray:
        """dG/du over the connections: d(source output of i)/d(input of j), from the FMUs'
        partial derivatives restricted to the declared direct dependencies."""
        conns = self.graph.connections
        n = len(conns)
        J = np.zeros((n, n))
        feed = self.graph.feedthrough
        for i, ci in enumerate(conns):
            deps = feed.get(ci.src, ())
            for j, cj in enumerate(conns):
                if cj.dst not in deps:
                    continue
                J[i, j] = self.instances[ci.src_instance].partial(ci.src_variable, cj.dst_variable)
        return J

    def _refresh(self, n: int) -> np.ndarray:
        self.jac_inv = np.linalg.inv(np.eye(n) - self.coupling_jacobian())
        return self.jac_inv

    def _set_all_inputs(self, u: np.ndarray) -> None:
        for ins in self.inst_list:
            if ins.n_in:
                ins.in_val[:] = u[ins.conn_idx]
                ins.set_inputs()

    def _read_all(self) -> None:
        y = self.y
        for ins in self.inst_list:
            ins.get_outputs()
            y[ins.sig_out] = ins.out_val

    def solve(self, t: float, u0: np.ndarray | None = None) -> int:
        """Solve u = G(u) at the current point t [s] (Newton with a reused Jacobian), starting from
        the current sources (or ``u0``). Returns the iterations.

        Without loops a single pass (set inputs, read outputs) in topological order is exact."""
        y = self.y
        if not self.has_loops:
            for name in self.order_gs:
                ins = self.instances[name]
                if ins.n_in:
                    ins.in_val[:] = y[ins.sig_in]
                    ins.set_inputs()
                ins.get_outputs()
                y[ins.sig_out] = ins.out_val
            return 1
        u = y[self.conn_sig].copy() if u0 is None else u0.copy()
        jac = self.jac_inv
        if jac is None:
            self._set_all_inputs(u)
            jac = self._refresh(len(u))
        self.uscale = np.abs(u) + 1e-300
        scale = 1e-300 + np.abs(u)
        for it in range(1, self.max_iter + 1):
            self._set_all_inputs(u)
            self._read_all()
            g = y[self.conn_sig]
            r = g - u
            err = np.max(np.abs(r) / (self.tol * np.maximum(scale, np.abs(g)) + 1e-300))
            if err <= 1.0 or not np.any(r):
                return it
            u = u + jac @ r
            if it == 3:  # slow: refresh the Jacobian
                jac = self._refresh(len(u))
        raise MasterError(f"coupling equations did not converge at t = {t:.16g} s")

    def correct(self, u: np.ndarray, t: float) -> int:
        """After a step taken with inputs u (extrapolated), the outputs G(u) are in y: chord Newton
        corrections u <- u + (I - dG/du)^-1 (G(u) - u) until the coupling equations hold at t [s].
        Needs a previous :meth:`solve` (the Jacobian and the scale)."""
        y = self.y
        jac, sc = self.jac_inv, self.uscale
        if jac is None or sc is None:
            raise MasterError("the coupling correction needs a previous solve (its Jacobian and scale)")
        g = y[self.conn_sig]
        for it in range(self.max_iter):
            r = g - u
            u = u + jac @ r
            self._set_all_inputs(u)
            self._read_all()
            g = y[self.conn_sig]
            np.maximum(sc, np.abs(g), out=sc)
            if np.all(np.abs(g - u) <= self.tol * sc):
                return it + 1
            if it == 2:
                jac = self._refresh(len(u))
        raise MasterError(f"coupling equations did not converge at t = {t:.16g} s")
