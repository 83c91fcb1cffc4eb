"""A solve's progress line: IPOPT's iterate every few iterations, through ``logging``.

IPOPT's own per-iteration table (``solver.print_level`` 5) is a screen per hundred
iterations; a pipeline's log wants to know that a solve is alive and where it stands. This
is CasADi's ``iteration_callback``: every ``every`` iterations it logs the iteration, the
objective, the largest constraint violation (unscaled, in the constraints' units) and what
the solve is (its phase or round). It reads the iterate only; the iterates do not change.
"""

from __future__ import annotations

import logging

import casadi as ca
import numpy as np

log = logging.getLogger(__name__)


class ProgressLog(ca.Callback):
    """CasADi's iteration callback for one NLP, logging at INFO every ``every`` iterations.

    Args:
        n_x: Variables.
        n_g: Constraint rows.
        n_p: Parameters.
        lbg: (n_g,) The rows' lower bounds.
        ubg: (n_g,) The rows' upper bounds.
        every: Iterations between two lines (CasADi's ``iteration_callback_step``).
    """

    def __init__(
        self, n_x: int, n_g: int, n_p: int, lbg: np.ndarray, ubg: np.ndarray, every: int
    ) -> None:
        ca.Callback.__init__(self)
        self.n_x, self.n_g, self.n_p, self.every = n_x, n_g, n_p, every
        self.lbg, self.ubg = np.asarray(lbg, float), np.asarray(ubg, float)
        self.label = "solve"
        self.calls = 0
        self.construct("progress", {})

    def start(self, label: str) -> None:
        """Name the next solve (``label``: its phase or round) and count from 0."""
        self.label, self.calls = label, 0

    def get_n_in(self) -> int:
        return ca.nlpsol_n_out()

    def get_n_out(self) -> int:
        return 1

    def get_name_in(self, i: int) -> str:
        return ca.nlpsol_out(i)

    def get_name_out(self, i: int) -> str:
        return "stop"

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        name = ca.nlpsol_out(i)
        if name == "f":
            return ca.Sparsity.scalar()
        size = {"x": self.n_x, "lam_x": self.n_x, "g": self.n_g, "lam_g": self.n_g}
        return ca.Sparsity.dense(size.get(name, self.n_p), 1)

    def eval(self, args: list) -> list:
        iteration = self.calls * self.every
        self.calls += 1
        g = np.asarray(args[2]).ravel()
        violation = max(
            float(np.max(self.lbg - g, initial=0.0)), float(np.max(g - self.ubg, initial=0.0))
        )
        log.info(
            "%s: iteration %d, objective %.6e, constraint violation %.1e",
            self.label,
            iteration,
            float(args[1]),
            violation,
        )
        return [0]  # 0: go on
