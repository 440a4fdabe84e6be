"""numpy's kernels on the CPU, and small helpers every kernel module uses (paper section 3.2, speed)."""

from __future__ import annotations

import math

import numpy as np
import torch

__all__ = ["TWO_PI", "ufunc", "sin", "cos", "exp", "log", "sqrt", "atan", "atan2", "matmul", "grey"]

TWO_PI = 2.0 * math.pi

_NUMPY_MIN = 4096  # elements from which numpy's ufunc beats torch's on the CPU


def ufunc(torch_fn, numpy_fn, smallest: int = _NUMPY_MIN):
    """``torch_fn``, computed on CPU images by numpy instead (zero-copy views).

    On the CPU numpy's vectorised transcendental functions are 2-10x faster than torch's
    (measured on 256x256 float32: sin 27 vs 73 us, atan 14 vs 148 us, log 17 vs 55 us), and its
    matrix products (OpenBLAS) 1.1-2x faster than torch's (a 768x256 by 256x256 product: 0.49 ms
    vs 1.06 ms; 0.94 ms where ``OPENBLAS_CORETYPE=Haswell`` is forced); both release the GIL
    like torch. GPU tensors and images of fewer than ``smallest`` elements keep torch's function
    (the choice depends on one image's size, never on the batch's).
    """
    def f(*args):
        if args[0].device.type != "cpu" or max(a.numel() // a.shape[0] for a in args) < smallest:
            return torch_fn(*args)
        with np.errstate(all="ignore"):  # inf and NaN inputs are expected (torch is silent too)
            return torch.from_numpy(numpy_fn(*(a.numpy() for a in args)))
    f.__name__ = torch_fn.__name__
    return f


sin, cos, exp = ufunc(torch.sin, np.sin), ufunc(torch.cos, np.cos), ufunc(torch.exp, np.exp)
log, sqrt = ufunc(torch.log, np.log), ufunc(torch.sqrt, np.sqrt)
# torch's vectorised atan2 rounds the elements past the last full vector differently (measured),
# so a picture would depend on the size of its batch: numpy's, whatever the size
atan, atan2 = ufunc(torch.atan, np.arctan), ufunc(torch.atan2, np.arctan2, smallest=0)
matmul = ufunc(torch.matmul, np.matmul)


def grey(v):
    return v if v.shape[1] == 1 else v.mean(dim=1, keepdim=True)
