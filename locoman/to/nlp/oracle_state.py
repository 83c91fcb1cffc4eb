"""What the oracles (:mod:`locoman.to.nlp.oracles`) keep: per block, its calls and where
their derivatives land in the NLP's patterns; per iterate, the values the oracles share."""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sps

from locoman.to.nlp.convexify import BlockPattern
from locoman.to.nlp.sparsity import Mapped


@dataclasses.dataclass(frozen=True)
class BlockCalls:
    """One block's calls and where their derivatives land."""

    block: object
    params: slice
    val: Mapped
    grad: Mapped
    jac: Mapped | None
    hess: Mapped | None
    hess_at: np.ndarray  # (calls, nnz of the term's Hessian): positions in H_z's pattern
    jac_at: np.ndarray  # (calls, nnz of J_g): positions in J_z's pattern
    projected: BlockPattern | None  # the projected flavour's pattern


@dataclasses.dataclass(frozen=True)
class Definition:
    """A defining block: y[lifted] = F(x[inputs]), dy/dx and sum mu nabla^2 F."""

    block: object
    params: slice
    inputs: np.ndarray
    lifted: np.ndarray
    val: Mapped
    jac: Mapped
    hess: Mapped | None
    jac_keep: np.ndarray
    jac_at: np.ndarray  # (calls, kept) positions in P's pattern
    hess_keep: np.ndarray
    hess_rows: np.ndarray
    hess_cols: np.ndarray
    projected: BlockPattern | None


class Point:
    """What the oracles share at one (x, p): f, g, P, each block's inputs and the calls
    that count."""

    def __init__(self, x: np.ndarray, p: np.ndarray) -> None:
        self.x, self.p = x.copy(), p.copy()
        self.P: sps.csc_matrix | None = None
        self.f = 0.0
        self.g = np.zeros(0)
        self.definitions: list[tuple[np.ndarray, np.ndarray]] = []
        self.inputs: list[tuple[np.ndarray, np.ndarray]] = []
        self.active: list[np.ndarray | None] = []
        self.gradient: np.ndarray | None = None
        self.jacobian: sps.csc_matrix | None = None
