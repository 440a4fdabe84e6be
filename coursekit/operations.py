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

__all__ = ["CountHostSyncs", "CountOperations"]

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


#: Operations whose result the host must wait for: a value read into Python (``.item()``,
#: ``bool()``, ``int()``, ``float()`` all run ``_local_scalar_dense``), or an output whose size
#: depends on the data (``nonzero``, boolean indexing, ``masked_select``, ``unique``).
_SYNCING = {_aten._local_scalar_dense.default, _aten.nonzero.default, _aten.masked_select.default,
            _aten._unique2.default, _aten.unique_consecutive.default, _aten.unique_dim.default,
            _aten.repeat_interleave.Tensor}


class CountHostSyncs(TorchDispatchMode):
    """Context manager: ``count`` host synchronisations ran inside, on any device.

    On a GPU the host waits for the device whenever Python reads a tensor's value or an
    operation's output size depends on the data; on the CPU nothing waits, but the same calls
    happen, so counting them on the CPU tells what a GPU will pay. Counted: the operations of
    ``_SYNCING`` (boolean indexing included: it runs ``nonzero``), every copy to numpy or to
    Python (``Tensor.numpy``, ``Tensor.tolist``; ``.cpu()`` of a device tensor), and every tensor
    made from host data (``torch.tensor``, ``torch.as_tensor``, ``torch.asarray`` of a number, a
    list or a numpy array: on a GPU a copy from pageable memory, which the host waits for and a
    CUDA graph cannot capture; ``array_api_compat`` makes one of a Python number passed to
    ``maximum`` or ``minimum``). ``calls`` names each counted call, in order; a deliberate
    non-blocking upload through pinned memory binds the original function and is not counted.

        >>> import torch
        >>> x = torch.arange(4.0)
        >>> with CountHostSyncs() as syncs:
        ...     y = x * 2           # stays on the device
        ...     if bool(y.sum() > 3):   # read on the host: a synchronisation
        ...         z = x[x > 1]    # a data-dependent size: another
        >>> syncs.count, syncs.calls
        (2, ['_local_scalar_dense', 'index'])
    """

    def __init__(self):
        super().__init__()
        self.count = 0
        self.calls: list[str] = []
        self._patched: list = []

    def _hit(self, name: str) -> None:
        self.count += 1
        self.calls.append(name)

    def __torch_dispatch__(self, func, types, args=(), kwargs=None):
        kwargs = kwargs or {}
        name = func.overloadpacket.__name__
        if func in _SYNCING:
            self._hit(name)
        elif func is _aten.index.Tensor and any(isinstance(i, torch.Tensor) and i.dtype == torch.bool for i in args[1]):
            self._hit(name)
        elif func in (_aten._to_copy.default, _aten.copy_.default):
            src = args[1] if func is _aten.copy_.default else args[0]
            dst = args[0].device if func is _aten.copy_.default else kwargs.get("device", src.device)
            if src.device.type != "cpu" and torch.device(dst).type == "cpu":
                self._hit(name)
        return func(*args, **kwargs)

    def __enter__(self):
        for method in ("numpy", "tolist"):  # device to host
            original = getattr(torch.Tensor, method)

            def counted(t, *a, _original=original, _method=method, **k):
                self._hit(_method)
                return _original(t, *a, **k)

            self._patched.append((torch.Tensor, method, original))
            setattr(torch.Tensor, method, counted)
        for function in ("tensor", "as_tensor", "asarray"):  # host to device: Python numbers, lists, numpy arrays
            original = getattr(torch, function)

            def uploaded(data, *a, _original=original, **k):
                if not isinstance(data, torch.Tensor):
                    self._hit("upload")
                return _original(data, *a, **k)

            self._patched.append((torch, function, original))
            setattr(torch, function, uploaded)
        return super().__enter__()

    def __exit__(self, *exc):
        for owner, name, original in self._patched:
            setattr(owner, name, original)
        self._patched.clear()
        return super().__exit__(*exc)
