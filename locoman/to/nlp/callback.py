"""An oracle of :mod:`locoman.to.nlp.oracles` as a CasADi function IPOPT can call: a
:class:`casadi.Callback` with fixed sparsity that forwards to NumPy code."""

from __future__ import annotations

from collections.abc import Callable, Sequence

import casadi as ca
import numpy as np


class OracleCallback(ca.Callback):
    """One oracle as a CasADi function for IPOPT: ``evaluate(*inputs) -> outputs`` on
    NumPy arrays, with fixed input and output sparsities, called on CasADi's buffers."""

    def __init__(
        self,
        name: str,
        inputs: Sequence[tuple[str, ca.Sparsity]],
        outputs: Sequence[tuple[str, ca.Sparsity]],
        evaluate: Callable,
        jacobian: ca.Function | None = None,
    ) -> None:
        ca.Callback.__init__(self)
        self._inputs, self._outputs, self._evaluate = list(inputs), list(outputs), evaluate
        self._jacobian = jacobian
        self.construct(name, {})

    def has_jacobian(self) -> bool:
        return self._jacobian is not None

    def get_jacobian(self, name, inames, onames, opts) -> ca.Function:
        return self._jacobian

    def get_n_in(self) -> int:
        return len(self._inputs)

    def get_n_out(self) -> int:
        return len(self._outputs)

    def get_name_in(self, i: int) -> str:
        return self._inputs[i][0]

    def get_name_out(self, i: int) -> str:
        return self._outputs[i][0]

    def get_sparsity_in(self, i: int) -> ca.Sparsity:
        return self._inputs[i][1]

    def get_sparsity_out(self, i: int) -> ca.Sparsity:
        return self._outputs[i][1]

    def has_eval_buffer(self) -> bool:
        return True

    def eval_buffer(self, args, results) -> int:
        arrays = [
            np.frombuffer(a, dtype=np.float64) if a is not None else np.zeros(sp.nnz())
            for a, (_, sp) in zip(args, self._inputs, strict=True)
        ]
        for out, value in zip(results, self._evaluate(*arrays), strict=True):
            if out is not None:
                np.frombuffer(out, dtype=np.float64)[:] = value
        return 0
