"""Array backends for the simulator: one code path for numpy and torch (paper section 2.4).

The simulator is written against the array API (through :mod:`array_api_compat`). This module
adds the little the standard lacks -- moving index arrays to a backend and the segment sum that
accumulates children's articulated inertias into their parents -- and nothing else.
"""

from __future__ import annotations

import numpy as np
import array_api_compat

BACKENDS = ("numpy", "torch")


def namespace(backend: str):
    """Array namespace for ``backend`` ("numpy" or "torch")."""
    if backend == "numpy":
        return np  # numpy >= 2 implements the array API in its main namespace (no wrapper overhead)
    if backend == "torch":
        import array_api_compat.torch as xp

        return xp
    raise ValueError(f"backend: unknown backend {backend!r}; allowed: {', '.join(BACKENDS)}")


def is_torch(xp) -> bool:
    return xp is not np and array_api_compat.is_torch_namespace(xp)


def asarray(xp, a, *, dtype=None, device=None):
    """Convert ``a`` (numpy or backend array) to a float64 (or ``dtype``) array of ``xp``."""
    if dtype is None:
        dtype = xp.float64
    if is_torch(xp):
        import torch

        if isinstance(a, torch.Tensor):
            return a.to(dtype=dtype, device=device if device is not None else a.device)
        return torch.as_tensor(np.asarray(a), dtype=dtype, device=device)
    return np.ascontiguousarray(np.asarray(a), dtype=dtype)


def index(xp, a, *, device=None):
    """An int64 index array of ``xp``."""
    return asarray(xp, np.asarray(a, dtype=np.int64), dtype=xp.int64, device=device)


def contiguous(xp, a):
    """``a`` laid out row-major (a copy when it is a transposed view)."""
    return a.contiguous() if is_torch(xp) else np.ascontiguousarray(a)


def to_numpy(a) -> np.ndarray:
    """Any backend array as a numpy array (copied from the device when needed)."""
    if hasattr(a, "detach"):
        return a.detach().cpu().numpy()
    return np.asarray(a)


class Segments:
    """Children (of one tree level, or every joint) to be summed into their parents.

    Args:
        parent: (n,) parent index (into the full body array) of each child; non-decreasing for
            :meth:`add_weighted`.
        parent_level: ``(start, stop)`` of the parents (a contiguous slice of bodies).

    numpy sums with a sparse (parents x children) 0/1 matrix product through ``scipy.sparse``'s
    public API -- several times faster than ``np.add.reduceat`` or ``np.add.at`` on stacks of
    6x6 matrices; torch uses an accumulating ``index_put_``.
    """

    def __init__(self, xp, parent: np.ndarray, parent_level: tuple[int, int], device=None):
        parent = np.asarray(parent, dtype=np.int64)
        self.sorted = not (parent.size and np.any(np.diff(parent) < 0))
        self.torch = is_torch(xp)
        self.parent = index(xp, parent, device=device)
        self.start, self.stop = parent_level
        if not self.torch:
            import scipy.sparse

            n = parent.size
            self._rows = parent - self.start
            self._pattern = {}  # index structure of add_weighted's matrix, per number of terms
            self.matrix = scipy.sparse.csr_matrix((np.ones(n), (self._rows, np.arange(n))), shape=(self.stop - self.start, n))

    def add_into(self, target, values) -> None:
        """``target[parent[k]] += values[k]`` for every child ``k`` (in place); ``values`` may be
        flattened per row."""
        n = values.shape[0]
        if n == 0:
            return
        if self.torch:
            target.index_put_((self.parent,), values.reshape((-1,) + tuple(target.shape[1:])), accumulate=True)
            return
        rows = target[self.start : self.stop]
        rows += (self.matrix @ np.asarray(values, dtype=np.float64).reshape(n, -1)).reshape(rows.shape)

    def add_weighted(self, target, weights, values) -> None:
        """``target[parent[k]] += sum_t weights[k, t] values[k, t]`` (in place) for (n, k) weights
        and (n, k, ...) values: one sparse product with the weights as the matrix entries."""
        n, k = tuple(weights.shape)
        if n == 0:
            return
        if not self.sorted:
            raise ValueError("Segments.add_weighted: children must be sorted by parent")
        if self.torch:  # broadcast and sum: faster than torch's small stacked products on the CPU
            terms = (weights[:, :, None] * values.reshape(n, k, -1)).sum(1)
            target.index_put_((self.parent,), terms.reshape((n,) + tuple(target.shape[1:])), accumulate=True)
            return
        x = np.asarray(values, dtype=np.float64).reshape(n * k, -1)
        rows = target[self.start : self.stop]
        rows += (self._weighted_matrix(k, weights) @ x).reshape(rows.shape)

    def _weighted_matrix(self, k, weights):
        """(parents x n k) CSR matrix with entry ``weights[i, t]`` at (parent of i, i k + t); its
        entries are stored in exactly that order (children are sorted by parent), so the index
        structure is built once per ``k`` and only the weights change."""
        import scipy.sparse

        n = weights.shape[0]
        shape = (self.stop - self.start, n * k)
        if k not in self._pattern:
            A = scipy.sparse.csr_matrix((np.ones(n * k), (np.repeat(self._rows, k), np.arange(n * k))), shape=shape)
            self._pattern[k] = (A.indptr, A.indices)
        indptr, indices = self._pattern[k]
        return scipy.sparse.csr_matrix((np.asarray(weights, dtype=np.float64).reshape(-1), indices, indptr), shape=shape)


def scatter_add(xp, target, idx, values) -> None:
    """``target[idx[k]] += values[k]`` in place, repeated indices accumulating."""
    if is_torch(xp):
        target.index_put_((idx,), values, accumulate=True)  # much faster than index_add_ on CPU
    else:  # one bincount per column: many times faster than np.add.at
        flat = values.reshape(len(idx), -1)
        sums = [np.bincount(idx, weights=flat[:, k], minlength=target.shape[0]) for k in range(flat.shape[1])]
        target += np.stack(sums, axis=1).reshape(target.shape)


def nonzero(xp, mask):
    """Indices (1-D) of the true entries of a boolean vector."""
    return xp.nonzero(mask)[0]


def add_at(xp, target, idx, values) -> None:
    """``target[idx[k]] += values[k]`` in place for a few rows (repeats accumulate)."""
    if is_torch(xp):
        target.index_put_((idx,), values, accumulate=True)
    else:
        np.add.at(target, idx, values)


def solve(xp, A, b, static=False):
    """``x`` with ``A x = b`` for stacks of small symmetric positive-definite matrices ``A`` (n, k, k)
    and vectors ``b`` (n, k).

    ``static``: Gauss-Jordan elimination without pivoting (a positive-definite matrix needs none),
    ``k`` steps over the whole stack with no branch on the data. The library solvers check their
    factorisation on the host (a synchronisation on a GPU, which a CUDA graph cannot capture);
    this reads nothing there. Equal to the library's solve up to rounding.
    """
    if not static:
        return xp.linalg.solve(A, b[:, :, None])[:, :, 0]
    k = A.shape[1]
    M = xp.concat([A, b[:, :, None]], axis=2)
    for i in range(k):
        row = M[:, i : i + 1, :] / M[:, i : i + 1, i : i + 1]
        M = M - M[:, :, i : i + 1] * row
        M[:, i : i + 1, :] = row
    return M[:, :, k]
