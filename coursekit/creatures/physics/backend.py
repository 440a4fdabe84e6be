"""Array backends for the simulator: one code path for numpy and torch (paper section 2.4).

The simulator is written against the array API (through :mod:`array_api_compat`). This module
adds the little the standard lacks -- moving index arrays to a backend and the segment sum that
accumulates children's articulated inertias into their parents -- and nothing else.

numpy (>= 2) implements the array API in its main namespace; :data:`NUMPY` is that namespace with
its ``take``, ``reshape``, ``sum`` and ``stack`` called straight on the arrays. numpy's own are
Python wrappers (a dispatcher, then ``_wrapfunc``, or ``stack``'s shape checks) that cost more
than the work on the few rows of a small batch -- the step of a lesson's one creature, or of the
three fittest that evolution re-scores; they call the same kernels, so every result is bit for
bit numpy's.
"""

from __future__ import annotations

import functools
import types

import numpy as np
import array_api_compat

BACKENDS = ("numpy", "torch")


def _take(x, indices, /, *, axis=None):
    return x.take(indices, axis=axis)


def _reshape(x, /, shape, *, copy=None):
    return x.reshape(shape) if copy is None else np.reshape(x, shape, copy=copy)


def _sum(x, /, *, axis=None, dtype=None, keepdims=False):
    return x.sum(axis=axis, dtype=dtype, keepdims=keepdims)


def _stack(arrays, /, *, axis=0):
    arrays = [np.asarray(a) for a in arrays]
    if not arrays:
        return np.stack(arrays, axis=axis)  # numpy's own error
    ndim = arrays[0].ndim + 1
    at = axis + ndim if axis < 0 else axis
    if not 0 <= at < ndim:
        return np.stack(arrays, axis=axis)  # numpy's own error
    new = (slice(None),) * at + (None,)
    return np.concatenate([a[new] for a in arrays], axis=at)


#: numpy's namespace, with ``take``, ``reshape``, ``sum`` and ``stack`` called straight on the arrays.
NUMPY = types.SimpleNamespace(**{**vars(np), "take": _take, "reshape": _reshape, "sum": _sum, "stack": _stack})


def namespace(backend: str):
    """Array namespace for ``backend`` ("numpy": :data:`NUMPY`, or "torch")."""
    if backend == "numpy":
        return NUMPY
    if backend == "torch":
        import array_api_compat.torch as xp

        return xp
    raise ValueError(f"backend: unknown backend {backend!r}; allowed: {', '.join(BACKENDS)}")


def is_numpy(xp) -> bool:
    return xp is NUMPY or xp is np


def is_torch(xp) -> bool:
    return not is_numpy(xp) and array_api_compat.is_torch_namespace(xp)


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

    numpy sums with a sparse (parents x children) CSR matrix product -- several times faster than
    ``np.add.reduceat`` or ``np.add.at`` on stacks of 6x6 matrices -- built by ``scipy.sparse`` and
    multiplied by its kernels directly (:func:`_csr_product`); torch uses an accumulating
    ``index_put_``.
    """

    def __init__(self, xp, parent: np.ndarray, parent_level: tuple[int, int], device=None):
        parent = np.asarray(parent, dtype=np.int64)
        self.sorted = not (parent.size and np.any(np.diff(parent) < 0))
        self.torch = is_torch(xp)
        self.parent = index(xp, parent, device=device)
        self.start, self.stop = parent_level
        if not self.torch:
            self._rows = parent - self.start
            self._ones = np.ones(parent.size)
            self._structures = {}  # the CSR matrix's (shape, indptr, indices), per number of terms

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
        rows += _csr_product(*self._structure(1), self._ones, np.asarray(values, dtype=np.float64).reshape(n, -1)).reshape(rows.shape)

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
        rows += _csr_product(*self._structure(k), np.ascontiguousarray(weights, dtype=np.float64).reshape(-1), x).reshape(rows.shape)

    def _structure(self, k):
        """``(shape, indptr, indices)`` of the (parents x n k) CSR matrix with an entry at (parent of
        i, i k + t) for every child i and term t, stored in exactly that order (children are sorted
        by parent; ``add_into``'s, k = 1, needs no sorting): built once per ``k`` by
        ``scipy.sparse``, only the entries change."""
        if k not in self._structures:
            import scipy.sparse

            n = self._rows.size
            A = scipy.sparse.csr_matrix((np.ones(n * k), (np.repeat(self._rows, k), np.arange(n * k))),
                                        shape=(self.stop - self.start, n * k))
            self._structures[k] = (A.shape, A.indptr, A.indices)
        return self._structures[k]


def _csr_product(shape, indptr, indices, data, x):
    """``A @ x`` for the CSR matrix ``A`` = (``data``, ``indices``, ``indptr``) of ``shape`` and a
    float64 block ``x`` (N, m): what ``scipy.sparse`` computes for it -- the same kernel
    (``csr_matvec`` for one column, ``csr_matvecs`` for more) into the same zeroed result, so
    bit for bit its product -- without its checks and dispatch, which on the few rows of a tree
    level cost three times the product."""
    M, N = shape
    m = x.shape[1]
    out = np.zeros((M, m))
    if m == 1:
        _sparsetools().csr_matvec(M, N, indptr, indices, data, np.ascontiguousarray(x).ravel(), out.ravel())
    else:
        _sparsetools().csr_matvecs(M, N, m, indptr, indices, data, x.ravel(), out.ravel())
    return out


@functools.cache
def _sparsetools():
    """scipy's sparse kernels, imported when numpy first sums segments (not with the package)."""
    from scipy.sparse import _sparsetools

    return _sparsetools


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
