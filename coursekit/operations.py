"""Counting the tensor operations a computation runs: on a GPU each is a kernel launch.

Both batched engines (pictures, section 3.2; swimmers, section 2.4) are judged on a GPU by how
many operations they launch, not only by arithmetic, and that count can be taken on any machine:
torch's dispatch modes see every operation torch runs. Views (reshapes, slices, expansions)
only re-describe memory and launch nothing, so they are not counted.

The same pass estimates the work those operations do, for a roofline (lesson 09): ``flops``
counts ``2 m n k`` for a matrix product and one operation per element of the largest operand
for everything else (additions, comparisons, selections, reductions, copies); ``bytes`` adds up
every operand and result, the memory traffic of an implementation that keeps nothing in cache
between operations.

    >>> import torch
    >>> x = torch.ones(4, 4)
    >>> with CountOperations() as ops:
    ...     y = (x * 2 + 1).reshape(16)[:8]  # a multiplication and an addition; the views launch nothing
    >>> ops.count, ops.flops, ops.bytes
    (2, 32, 256)
    >>> with CountOperations() as ops:
    ...     z = x @ x  # 4 x 4 times 4 x 4: 2 * 4 * 4 * 4 operations
    >>> ops.flops
    128
"""

from __future__ import annotations

import torch
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_flatten

__all__ = ["CountOperations"]

_aten = torch.ops.aten
#: Matrix products: the operation counts ``2 m n k`` (the last two operands are the factors).
_PRODUCTS = {_aten.mm.default, _aten.bmm.default, _aten.addmm.default, _aten.baddbmm.default}


def _tensors(tree) -> list:
    return [t for t in tree_flatten(tree)[0] if isinstance(t, torch.Tensor)]


class CountOperations(TorchDispatchMode):
    """Context manager: ``count`` computing tensor operations ran inside, estimated to do ``flops``
    arithmetic operations and to move ``bytes`` (operands and results)."""

    def __init__(self):
        super().__init__()
        self.count = 0
        self.flops = 0
        self.bytes = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        out = func(*args, **(kwargs or {}))
        if not func.is_view:
            self.count += 1
            operands, results = _tensors((args, kwargs or {})), _tensors(out)
            if func in _PRODUCTS:
                a, b = operands[-2], operands[-1]
                self.flops += 2 * a.numel() * b.shape[-1]
            else:
                self.flops += max((t.numel() for t in operands + results), default=0)
            self.bytes += sum(t.numel() * t.element_size() for t in operands + results)
        return out
