"""Sparsity patterns and the maps that sum many calls' values into them: a term called
over a block's calls writes its nonzeros into the NLP's fixed patterns through constant
index maps (:class:`Mapped`), evaluated in CasADi maps of a few fixed sizes."""

from __future__ import annotations

import functools
from collections.abc import Sequence

import casadi as ca
import numpy as np
import scipy.sparse as sps

# Calls are evaluated in maps of these sizes at least (powers of two above): a subset of k
# calls pads to the next size, so a block compiles no more than log2(n) maps.
_SMALLEST_MAP = 16


class Pattern:
    """A fixed sparsity pattern (CasADi's column-major order) and where each of the
    triplets it was made from lands in it (duplicates summed)."""

    def __init__(self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]) -> None:
        self.shape = shape
        linear = np.asarray(cols, np.int64) * shape[0] + np.asarray(rows, np.int64)
        if np.all(linear[1:] > linear[:-1]):  # a canonical pattern's own: nothing to sort
            self._linear, self.where = linear, np.arange(len(linear))
        else:
            self._linear, self.where = unique_rows(linear)
        self.nnz = len(self._linear)
        rows, cols = self.rows_cols()
        self._indices = rows.astype(np.int32)
        self._indptr = np.searchsorted(cols, np.arange(shape[1] + 1)).astype(np.int32)

    def extended(
        self, rows: np.ndarray, cols: np.ndarray, shape: tuple[int, int]
    ) -> tuple[Pattern, np.ndarray]:
        """This pattern with the triplets ``rows``, ``cols`` added, in ``shape`` (this
        pattern's or larger): the new pattern, whose ``where`` is those triplets', and
        where each of this pattern's entries lands in it. Its own entries are sorted
        already, so this costs about a sort of the new triplets."""
        own_rows, own_cols = self.rows_cols()
        joined = Pattern(np.r_[own_rows, rows], np.r_[own_cols, cols], shape)
        moved, joined.where = joined.where[: self.nnz], joined.where[self.nnz :]
        return joined, moved

    def rows_cols(self) -> tuple[np.ndarray, np.ndarray]:
        return self._linear % self.shape[0], self._linear // self.shape[0]

    def matrix(self, data: np.ndarray) -> sps.csc_matrix:
        """The CSC matrix with these nonzeros (in the pattern's order); its own index
        arrays (SciPy prunes zeros in place)."""
        indices, indptr = self._indices.copy(), self._indptr.copy()
        return sps.csc_matrix((data, indices, indptr), shape=self.shape)

    def values(self, matrix: sps.spmatrix) -> np.ndarray:
        """The nonzeros of ``matrix`` (whose entries lie in the pattern) in its order, 0
        where ``matrix`` has none."""
        coo = matrix.tocoo()
        linear = coo.col.astype(np.int64) * self.shape[0] + coo.row
        at = np.searchsorted(self._linear, linear)
        return np.bincount(at, coo.data, minlength=self.nnz)

    @functools.cached_property
    def sparsity(self) -> ca.Sparsity:
        # From the compressed columns as they are: triplets would be sorted again.
        return ca.Sparsity(*self.shape, self._indptr.tolist(), self._indices.tolist())


def structural(matrix: sps.spmatrix) -> Pattern:
    """The pattern of ``matrix``'s stored entries (explicit zeros included)."""
    csc = sps.csc_matrix(matrix)
    csc.sum_duplicates()  # sorted, no duplicates: the pattern needs no sort of its own
    cols = np.repeat(np.arange(csc.shape[1]), np.diff(csc.indptr))
    return Pattern(csc.indices, cols, csc.shape)


class Mapped:
    """A compiled function of one call, evaluated over many calls on NumPy buffers.

    Inputs are (calls, size) C-ordered arrays, which is CasADi's (size, calls) column-major
    layout; so are the outputs, dense (an output with structural zeros, such as a cost that
    is identically 0, has them filled in).
    """

    def __init__(self, function: ca.Function, calls: int) -> None:
        self._function, self.calls = function, calls
        self._rows = [
            np.asarray(function.sparsity_out(i).row(), int) for i in range(function.n_out())
        ]
        self._widths = [function.size1_out(i) for i in range(function.n_out())]
        self._maps: dict[int, tuple] = {}

    def _map(self, size: int) -> tuple:
        if size not in self._maps:
            buffer, run = self._function.map(size).buffer()
            outputs = [np.empty((size, len(rows))) for rows in self._rows]
            for i, out in enumerate(outputs):
                buffer.set_res(i, memoryview(out))
            self._maps[size] = (buffer, run, outputs)
        return self._maps[size]

    def __call__(self, *args: np.ndarray) -> list[np.ndarray]:
        """Every call's outputs."""
        return self._run(self.calls, args)

    def some(self, count: int, *args: np.ndarray) -> list[np.ndarray]:
        """The outputs of ``count`` calls whose inputs are ``args`` (count rows each)."""
        if count == self.calls:
            return self._run(count, args)
        size = min(max(_SMALLEST_MAP, 1 << (count - 1).bit_length()), self.calls)
        padded = [np.concatenate([a, np.repeat(a[-1:], size - count, axis=0)]) for a in args]
        return [out[:count] for out in self._run(size, padded)]

    def _run(self, size: int, args: Sequence[np.ndarray]) -> list[np.ndarray]:
        buffer, run, outputs = self._map(size)
        kept = [np.ascontiguousarray(a, dtype=float).reshape(size, -1) for a in args]
        for i, arg in enumerate(kept):
            buffer.set_arg(i, memoryview(arg))
        run()
        dense = []
        for out, rows, width in zip(outputs, self._rows, self._widths, strict=True):
            if len(rows) == width:
                dense.append(out.copy())
            else:
                full = np.zeros((size, width))
                full[:, rows] = out
                dense.append(full)
        return dense


def unique_rows(linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(linear, return_inverse=True)`` by a stable sort, which finds the runs a
    pattern extended by a few triplets is made of (a fraction of a quicksort's time)."""
    order = np.argsort(linear, kind="stable")
    ordered = linear[order]
    first = np.ones(len(ordered), bool)
    np.not_equal(ordered[1:], ordered[:-1], out=first[1:])
    where = np.empty(len(ordered), np.int64)
    where[order] = np.cumsum(first) - 1
    return ordered[first], where


def joined(parts: list[np.ndarray], dtype=np.int64) -> np.ndarray:
    return np.concatenate(parts).astype(dtype) if parts else np.zeros(0, dtype)


def split_at(array: np.ndarray, lengths: list[int]):
    start = 0
    for length in lengths:
        yield array[start : start + length]
        start += length
