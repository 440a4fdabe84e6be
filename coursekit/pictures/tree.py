"""Evaluating expression trees on whole images (paper section 3.2, phenotype).

A population's decoded trees become *batch trees* (:func:`stack_trees`): same-shaped trees
stacked into one, their parameters on the device, and every subtree that appears anywhere in
the population (a clone made by transposition, the parts children of one parent share) one
shared node, evaluated once per coordinate context (:class:`Memo`). :func:`evaluate` walks a
batch tree, calling each node's kernel (:mod:`.kernels`, looked up in the registry of
:mod:`.primitives` once per node) the way its form says.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import torch

from . import kernels  # noqa: F401  (importing it binds the built-in kernels in the registry)
from . import primitives as P
from .context import Context, upload
from .genome import Node

__all__ = ["BNode", "Memo", "stack_trees", "evaluate", "evaluate_node", "apply_kernel", "full"]


def full(v: torch.Tensor, ctx: Context) -> torch.Tensor:
    """``v`` expanded to the whole image (a view)."""
    return v.expand(v.shape[0], v.shape[1], ctx.H, ctx.W)


@dataclass(eq=False)
class BNode:
    """A node of a batch of same-shaped trees: one symbol, parameters stacked over the batch.

    A *uniform* node (the same parameters in every tree of the batch, and uniform children)
    has batch size 1 and is broadcast. Identical subtrees (same symbols and parameters: clones
    made by transposition, or the parts children of one parent share) are one shared node,
    evaluated once per coordinate context (``uses`` counts its parents).
    """

    symbol: str
    params: list  # of (B, 1, 1, 1) tensors, B = 1 when uniform
    children: list
    uniform: bool
    uses: int = 1
    form: str = field(init=False)
    kernel: object = field(init=False, repr=False)

    def __post_init__(self):
        self.form = P.get(self.symbol).form
        self.kernel = P.IMAGE_KERNELS.get(self.symbol)
        if self.kernel is None:
            raise ValueError(f"primitive {self.symbol!r} has no whole-image implementation (register one with "
                             "coursekit.pictures.primitives.register_primitive(..., image=...))")


def stack_trees(trees: Sequence[Node], device, shared: dict) -> BNode:
    """One batch tree for same-shaped trees; the parameters go to the device in two tensors
    (uniform ones and batched ones).

    ``shared`` maps (symbol, parameters, children) to nodes already built, in this tree or
    in other genomes' trees of the same render: such subtrees become one node.
    """
    columns: dict = {True: [], False: []}  # uniform: one value per parameter; else B values
    pending: list = []  # (node, first column, count)

    def build(trees):
        first = trees[0]
        if len(trees) == 1:
            kids = [build([c]) for c in first.children]
            params = [first.params]
            uniform = all(k.uniform for k in kids)
        else:
            kids = [build([t.children[i] for t in trees]) for i in range(len(first.children))]
            params = [t.params for t in trees]
            uniform = all(k.uniform for k in kids) and all(p == params[0] for p in params)
            if uniform:
                params = params[:1]
        key = (first.symbol, tuple(params), *map(id, kids))
        node = shared.get(key)
        if node is not None:
            node.uses += 1
            return node
        node = shared[key] = BNode(first.symbol, [], kids, uniform)
        if params[0]:
            pending.append((node, len(columns[uniform]), len(params[0])))
            columns[uniform].extend(zip(*params))
        return node

    root = build(list(trees))
    values = {u: upload(c, device).reshape(len(c), -1, 1, 1, 1).unbind(0) for u, c in columns.items() if c}
    for u, c in columns.items():  # the host copy kernels read numbers from (context.host): float32, as on the device
        for t, column in zip(values.get(u, ()), c):
            t.host = np.asarray(column, dtype=np.float32).tolist()
    for node, start, count in pending:
        node.params = list(values[node.uniform][start:start + count])
    return root


class Memo:
    """Values of shared subtrees for one render, per (node, coordinate context); an entry is
    dropped once all ``uses`` parents have read it. Thread-safe (a race only recomputes)."""

    def __init__(self):
        self.values: dict = {}
        self.lock = threading.Lock()

    def get(self, n: BNode, ctx: Context) -> torch.Tensor:
        key = (id(n), id(ctx))
        with self.lock:
            hit = self.values.get(key)
            if hit is not None:
                hit[2] -= 1
                if hit[2] <= 0:
                    del self.values[key]
                return hit[0]
        value = evaluate_node(n, ctx)
        with self.lock:
            if key not in self.values:
                self.values[key] = [value, ctx, n.uses - 1]  # ctx kept alive: its id stays unique
        return value


def evaluate(n: BNode, ctx: Context) -> torch.Tensor:
    """The value of batch tree ``n`` in context ``ctx``."""
    return evaluate_node(n, ctx) if n.uses == 1 else ctx.memo.get(n, ctx)


def evaluate_node(n: BNode, ctx: Context) -> torch.Tensor:
    """The value of ``n``, computed (not looked up in the memo); its children are evaluated."""
    f, form, kids = n.kernel, n.form, n.children
    if form == "terminal":
        return f(ctx, n.params)
    if form == "pointwise" or form == "filter":
        if len(kids) == 1:
            return f(ctx, n.params, evaluate(kids[0], ctx))
        return f(ctx, n.params, evaluate(kids[0], ctx), evaluate(kids[1], ctx))
    if form == "neighbourhood":
        return f(ctx, n.params, full(evaluate(kids[0], ctx), ctx))
    if len(kids) > 1:  # a warp by its second argument
        return evaluate(kids[0], f(ctx, n.params, evaluate(kids[1], ctx)))
    return evaluate(kids[0], f(ctx, n.params))


def apply_kernel(n: BNode, ctx: Context, params: list, args: list) -> torch.Tensor:
    """``n``'s kernel (not a warp) on given argument values ``args`` and ``params``."""
    if n.form == "terminal":
        return n.kernel(ctx, params)
    if n.form == "neighbourhood":
        return n.kernel(ctx, params, full(args[0], ctx))
    return n.kernel(ctx, params, *args)
