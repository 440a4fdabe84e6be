"""Counting the tensor operations a computation runs: on a GPU each is a kernel launch.

Both batched engines (pictures, section 3.2; swimmers, section 2.4) are judged on a GPU by how
many operations they launch, not only by arithmetic, and that count can be taken on any machine:
torch's dispatch modes see every operation torch runs. Views (reshapes, slices, expansions)
only re-describe memory and launch nothing, so they are not counted.

    >>> import torch
    >>> x = torch.ones(4, 4)
    >>> with CountOperations() as ops:
    ...     y = (x * 2 + 1).reshape(16)[:8]  # a multiplication and an addition; the views launch nothing
    >>> ops.count
    2
"""

from __future__ import annotations

from torch.utils._python_dispatch import TorchDispatchMode

__all__ = ["CountOperations"]


class CountOperations(TorchDispatchMode):
    """Context manager: ``count`` is the number of computing tensor operations run inside."""

    def __init__(self):
        super().__init__()
        self.count = 0

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        self.count += not func.is_view
        return func(*args, **(kwargs or {}))
