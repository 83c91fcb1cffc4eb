"""The projected Hessian: each term call's Hessian made positive semidefinite.

IPOPT's Newton step needs the Lagrangian's Hessian positive definite on the constraints'
null space. Far from an optimum the exact Hessian is not, and IPOPT adds delta_w I and
refactorises until it is (an inertia correction); on S1 nearly every exact-Hessian iteration
needed one, its steps kept short by a delta_w that restarts large. The Gauss-Newton Hessian
has none of the constraints' curvature (the moment arms, the kinematics), and its steps
wander.

The projected Hessian keeps the curvature that is convex: each term call's Hessian H_k (its
constraints' second derivatives weighted by their multipliers, its costs', and each virtual
variable definition's sum mu_i nabla^2 F_i) is replaced by its projection onto the positive
semidefinite cone,

    H_k+ = V max(Lambda, 0) V',   H_k = V Lambda V',

the nearest positive semidefinite matrix in the Frobenius norm. A sum of positive
semidefinite matrices is one, and so is P' H_z P of the chain rule: the assembled Hessian
is positive semidefinite by construction (acados's ``regularize_method: PROJECT`` does this
per stage; here it is per call, before the sums, where the matrices are small).

A call's Hessian is block diagonal over the groups of inputs that its pattern couples (the
regularisation cost's is nearly diagonal); each block is projected on its own, which is the
same projection, keeps the pattern sparse and costs a small eigendecomposition per block.
"""

from __future__ import annotations

import dataclasses

import numpy as np


@dataclasses.dataclass(frozen=True)
class _SameSize:
    """The blocks of one size m of a pattern: where the pattern's entries land in them, and
    where their dense upper triangles land in the projected pattern."""

    entries: np.ndarray  # the pattern's entries in these blocks
    block: np.ndarray  # each entry's block (0 .. count - 1)
    row: np.ndarray  # its row and column inside the block
    col: np.ndarray
    count: int  # blocks of this size
    size: int  # m
    out: np.ndarray  # (count, m (m + 1) / 2) positions in the projected pattern


@dataclasses.dataclass(frozen=True)
class BlockPattern:
    """A term's Hessian pattern (upper triangle, the term's input indices) split into the
    blocks of inputs it couples, each made dense.

    Attributes:
        rows, cols: The projected pattern: each block's dense upper triangle, as the term's
            input indices (row <= col); the projected values come in this order.
    """

    rows: np.ndarray
    cols: np.ndarray
    groups: tuple[_SameSize, ...]


def block_pattern(rows: np.ndarray, cols: np.ndarray) -> BlockPattern:
    """The blocks of the Hessian pattern ``rows``, ``cols`` (upper triangle, each entry
    once): the connected groups of inputs that its off-diagonal entries couple."""
    rows, cols = np.asarray(rows, int), np.asarray(cols, int)
    inputs = np.unique(np.concatenate([rows, cols]))
    parent = {int(i): int(i) for i in inputs}

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
        parent[root(r)] = root(c)
    members: dict[int, list[int]] = {}
    for i in inputs.tolist():
        members.setdefault(root(i), []).append(i)
    blocks = sorted(members.values(), key=lambda b: (len(b), b[0]))
    entry_block = np.array([root(int(r)) for r in rows])
    out_rows, out_cols, groups, start = [], [], [], 0
    for size in sorted({len(b) for b in blocks}):
        same = [b for b in blocks if len(b) == size]
        upper_r, upper_c = np.triu_indices(size)
        index = {root(b[0]): k for k, b in enumerate(same)}
        entries = np.flatnonzero(np.isin(entry_block, list(index)))
        block = np.array([index[int(b)] for b in entry_block[entries]], dtype=int)
        local = {i: (k, j) for k, b in enumerate(same) for j, i in enumerate(b)}
        for b in same:
            out_rows.append(np.asarray(b)[upper_r])
            out_cols.append(np.asarray(b)[upper_c])
        width = len(upper_r)
        out = start + np.arange(len(same) * width).reshape(len(same), width)
        start += len(same) * width
        groups.append(
            _SameSize(
                entries,
                block,
                np.array([local[int(r)][1] for r in rows[entries]], dtype=int),
                np.array([local[int(c)][1] for c in cols[entries]], dtype=int),
                len(same),
                size,
                out,
            )
        )
    return BlockPattern(np.concatenate(out_rows), np.concatenate(out_cols), tuple(groups))


def project_psd(values: np.ndarray, pattern: BlockPattern) -> np.ndarray:
    """Each call's Hessian projected onto the positive semidefinite cone, block by block.

    Args:
        values: (calls, nnz) each call's Hessian in the pattern's entries (upper triangle).

    Returns:
        (calls, len(pattern.rows)) each projection in the projected pattern's order.
    """
    calls = len(values)
    out = np.zeros((calls, len(pattern.rows)))
    for g in pattern.groups:
        m = g.size
        H = np.zeros((calls, g.count, m, m))
        H[:, g.block, g.row, g.col] = values[:, g.entries]
        H[:, g.block, g.col, g.row] = values[:, g.entries]
        if m == 1:
            projected = np.maximum(H, 0.0)
        else:
            eigenvalues, V = np.linalg.eigh(H)
            projected = (V * np.maximum(eigenvalues, 0.0)[..., None, :]) @ np.swapaxes(V, -1, -2)
        upper_r, upper_c = np.triu_indices(m)
        out[:, g.out.ravel()] = projected[:, :, upper_r, upper_c].reshape(calls, -1)
    return out
