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
from .context import Context, host, upload
from .genome import Node

__all__ = ["BNode", "Memo", "stack_trees", "evaluate", "evaluate_node", "apply_kernel", "full", "warped", "padded",
           "extension", "inner", "crop", "paddings"]


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


def warped(n: BNode, ctx: Context) -> Context:
    """The context warp node ``n`` makes in ``ctx`` (its second argument evaluated there)."""
    args = [evaluate(k, ctx) for k in n.children[1:]]
    w = n.kernel(ctx, n.params, *args)
    w.origin = (n, ctx)
    return w


def padded(ctx: Context, rows: int, cols: int) -> Context:
    """The context ``ctx`` extended to ``rows`` rows and ``cols`` columns on each side beyond the
    window: the unwarped coordinates of the extended pixel grid (the window's own pixels have
    exactly the coordinates they have in ``ctx``), warped as ``ctx``'s were (a warp's second
    argument evaluated on the extended grid too). Made once per render; a context whose
    derivation is unknown (made outside the evaluators) is returned as it is."""
    if (rows, cols) == tuple(ctx.pad):
        return ctx
    if ctx.origin is not None:  # warped: the same warp in the extended parent context
        node, parent = ctx.origin
        base = padded(parent, rows, cols)
        if base is parent:
            return ctx
        key = ("warp", id(node))
        if key not in base.variants:
            base.variants[key] = warped(node, base)
        return base.variants[key]
    if ctx.key is None or ctx.frame is None:
        return ctx
    family = ctx.variants.setdefault("padded", {})  # shared by the unwarped context and its extensions
    if (rows, cols) not in family:
        x0, y0, sx, sy, H, W = ctx.frame
        dev = ctx.x.device
        xs = (x0 + (torch.arange(-cols, W + cols, device=dev, dtype=torch.float64) + 0.5) * sx).float()
        ys = (y0 + (torch.arange(-rows, H + rows, device=dev, dtype=torch.float64) + 0.5) * sy).float()
        c = Context(xs.reshape(1, 1, 1, -1), ys.reshape(1, 1, -1, 1), H + 2 * rows, W + 2 * cols, ctx.px, ctx.py,
                    ctx.time, ctx.res, ctx.memo, key=(*ctx.key[:6], rows, cols), frame=ctx.frame, pad=(rows, cols))
        c.variants["padded"] = family
        family[(rows, cols)] = c
    return family[(rows, cols)]


def extension(n: BNode, ctx: Context) -> tuple[int, int]:
    """The rows and columns beyond the window on each side where neighbourhood node ``n``
    evaluated in ``ctx`` reads its argument: ``ctx``'s extension and ``n``'s reach
    (:func:`~.primitives.padding`; the largest over a batch, whose images
    :func:`~.evaluate.render` groups so that it is the same for all)."""
    if ctx.frame is None or n.symbol not in P.REACHES:
        return tuple(ctx.pad)
    H, W = ctx.picture
    values = [host(p) for p in n.params]
    q = [P.padding(n.symbol, [v[b if len(v) > 1 else 0] for v in values], ctx.px, ctx.py, H, W, ctx.pad)
         for b in range(max([len(v) for v in values] + [1]))]
    return ctx.pad[0] + max(r for r, _ in q), ctx.pad[1] + max(c for _, c in q)


def inner(n: BNode, ctx: Context) -> Context:
    """Where neighbourhood node ``n`` evaluated in ``ctx`` evaluates its argument: ``ctx``
    extended by :func:`extension`."""
    return padded(ctx, *extension(n, ctx))


def crop(v: torch.Tensor, where: Context, ctx: Context) -> torch.Tensor:
    """The part of ``v`` (a value in ``where``, an extension of ``ctx``) on ``ctx``'s pixels."""
    if where is ctx:
        return v
    dy, dx = where.pad[0] - ctx.pad[0], where.pad[1] - ctx.pad[1]
    if v.shape[2] == where.H:
        v = v[:, :, dy:dy + ctx.H]
    if v.shape[3] == where.W:
        v = v[:, :, :, dx:dx + ctx.W]
    return v


def evaluate_node(n: BNode, ctx: Context) -> torch.Tensor:
    """The value of ``n``, computed (not looked up in the memo); its children are evaluated."""
    f, form, kids = n.kernel, n.form, n.children
    if form == "terminal":
        return f(ctx, n.params)
    if form == "pointwise":
        if len(kids) == 1:
            return f(ctx, n.params, evaluate(kids[0], ctx))
        return f(ctx, n.params, evaluate(kids[0], ctx), evaluate(kids[1], ctx))
    if form == "filter" or form == "neighbourhood":  # on the context extended by its reach
        where = inner(n, ctx)
        a = evaluate(kids[0], where)
        return crop(f(where, n.params, a if form == "filter" else full(a, where)), where, ctx)
    return evaluate(kids[0], warped(n, ctx))


def apply_kernel(n: BNode, ctx: Context, params: list, args: list) -> torch.Tensor:
    """``n``'s kernel (not a warp) on given argument values ``args`` and ``params``."""
    if n.form == "terminal":
        return n.kernel(ctx, params)
    if n.form == "neighbourhood":
        return n.kernel(ctx, params, full(args[0], ctx))
    return n.kernel(ctx, params, *args)


def paddings(node: Node, px: float, py: float, H: int, W: int, pad: tuple[int, int] = (0, 0)) -> tuple:
    """The extension :func:`inner` gives each node of decoded tree ``node`` (depth first) in a
    picture of ``H`` x ``W`` pixels of world size ``px`` x ``py``: same-shaped trees batch
    together only where these agree, so that a batch extends each of its pictures as alone."""
    with np.errstate(over="ignore"):
        p = [float(v) for v in np.asarray(node.params, dtype=np.float32)]  # as the kernels read them (host)
    q = P.padding(node.symbol, p, px, py, H, W, pad)
    deeper = (pad[0] + q[0], pad[1] + q[1])
    return (q, *(x for c in node.children for x in paddings(c, px, py, H, W, deeper)))
