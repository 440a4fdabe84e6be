"""Population-wide evaluation of genetic pictures: one operation per primitive and wave, whatever
the genomes (paper section 3.2, phenotype; for GPUs).

Genome by genome, a population of 256 random genomes costs 256 evaluations of about 550 tensor
operations each (measured; stacking same-shaped genomes barely helps, random genomes rarely share
a shape): on a GPU, about 140,000 kernel launches, each on one small image, and launches, not
arithmetic, bound the speed. Here the whole population is evaluated in *waves*: every node whose
inputs are ready, in any genome and any coordinate context, joins the wave, and the nodes of a
wave with the same primitive and the same input types (scalar, colour, pixel map; see
:mod:`.kernels`) are evaluated together by one call of that primitive on their stacked inputs
and parameters. The number of operations then grows with the number of waves (the trees'
depth) and of distinct primitives, not with the population.

Coordinate transforms re-evaluate their first argument in a new context; ``warp-swirl`` and
``warp-by`` build it from their second argument, so that subtree joins a later wave; the
transforms of a wave are grouped too. Values keep their compact shapes (an expression of ``x``
alone stays one row); the arguments of pointwise functions of two arguments are broadcast to
one shape first, which leaves their values unchanged and makes fewer, larger groups. Warped
coordinates are stacked as they are, except a separable context (unwarped, or a warp by a
uniform displacement), which is used unstacked, since noise and pixel maps sample such
coordinates by rows and columns. A blur reads its argument on the grid extended by its reach
(:func:`.tree.padded`); a warped context is extended by making its warps again on the extended
grid, in later waves (``coords`` instances), and the blur waits for it (``then``). The pictures are bit for bit those of genome-by-genome
evaluation, because every primitive computes each image of a batch as it would alone (see
:mod:`.kernels`, batch invariance; tested).
"""

from __future__ import annotations

from collections import defaultdict

import torch

from .context import Context
from .tree import BNode, Memo, apply_kernel, crop, extension, padded

__all__ = ["evaluate_population"]


def _broadcast(*shapes) -> tuple:
    """The broadcast of (C, Hs, Ws) shapes whose entries are 1 or one common size."""
    return tuple(max(sizes) for sizes in zip(*shapes))


class _Inst:
    """One node evaluated in one coordinate context (``alias``: its value is ``inputs[0]``'s;
    ``coords``: its value is the context the warp node makes; ``then``: ``resume()`` goes on
    once its inputs are ready)."""

    __slots__ = ("ctx", "inputs", "kind", "node", "parents", "resume", "value", "waiting", "where")

    def __init__(self, node: BNode, ctx: Context):
        self.node, self.ctx = node, ctx
        self.where = ctx  # where its inputs are evaluated: ``ctx`` extended by a neighbourhood's reach
        self.inputs: list[_Inst] = []
        self.kind = "eval"
        self.value = None
        self.parents: list[_Inst] = []
        self.waiting = 0
        self.resume = None

    def batch(self) -> int:
        """Images this instance stands for: 1 when nothing in it differs between genomes."""
        sizes = [p.shape[0] for p in self.node.params] + [i.value.shape[0] for i in self.inputs]
        return max([self.where.x.shape[0], self.where.y.shape[0], *sizes])


class _Waves:
    def __init__(self):
        self.instances: dict = {}
        self.ready: list[_Inst] = []

    def request(self, node: BNode, ctx: Context) -> _Inst:
        key = (id(node), id(ctx))
        inst = self.instances.get(key)
        if inst is None:
            inst = self.instances[key] = _Inst(node, ctx)
            if node.form == "warp":  # first the displacement (if any), then the warped subtree
                self._wait(inst, [self.request(c, ctx) for c in node.children[1:]], "warp")
            elif node.form in ("filter", "neighbourhood"):  # its argument on the extended grid
                where = self._padded(ctx, *extension(node, ctx))
                if isinstance(where, Context):
                    self._evaluate_in(inst, where)
                else:  # the extended context of a warp is made in a later wave
                    inst.resume = lambda: self._evaluate_in(inst, where.value)
                    self._wait(inst, [where], "then")
            else:
                self._wait(inst, [self.request(c, ctx) for c in node.children], "eval")
        return inst

    def _evaluate_in(self, inst: _Inst, where: Context) -> None:
        inst.where = where
        self._wait(inst, [self.request(c, where) for c in inst.node.children], "eval")

    def _padded(self, ctx: Context, rows: int, cols: int):
        """:func:`.tree.padded`, a warped context's made in waves: the context, or an instance
        whose value it will be."""
        if ctx.origin is None or (rows, cols) == tuple(ctx.pad):
            return padded(ctx, rows, cols)
        key = ("padded", id(ctx), rows, cols)
        if key not in self.instances:
            node, parent = ctx.origin
            base = self._padded(parent, rows, cols)
            if isinstance(base, Context):
                self.instances[key] = ctx if base is parent else self._coords(node, base)
            else:
                inst = self.instances[key] = _Inst(node, ctx)

                def resume():
                    made = self._coords(node, base.value)
                    self._wait(inst, [made], "alias")
                inst.resume = resume
                self._wait(inst, [base], "then")
        return self.instances[key]

    def _coords(self, node: BNode, ctx: Context) -> _Inst:
        """An instance whose value is the context warp ``node`` makes in ``ctx``."""
        key = ("coords", id(node), id(ctx))
        if key not in self.instances:
            inst = self.instances[key] = _Inst(node, ctx)
            self._wait(inst, [self.request(c, ctx) for c in node.children[1:]], "coords")
        return self.instances[key]

    def _wait(self, inst: _Inst, inputs: list[_Inst], kind: str) -> None:
        inst.inputs, inst.kind = inputs, kind
        pending = [i for i in inputs if i.value is None]
        for i in pending:
            i.parents.append(inst)
        inst.waiting = len(pending)
        if not pending:
            self.ready.append(inst)

    def _done(self, inst: _Inst, value: torch.Tensor) -> None:
        inst.value = value
        for parent in inst.parents:
            parent.waiting -= 1
            if parent.waiting == 0:
                self.ready.append(parent)
        inst.parents = []

    def run(self) -> None:
        while self.ready:
            wave, self.ready = self.ready, []
            groups = defaultdict(list)
            for inst in wave:
                if inst.kind == "alias":
                    self._done(inst, inst.inputs[0].value)
                    continue
                if inst.kind == "then":
                    inst.resume()
                    continue
                s, ctx = inst.node.symbol, inst.where
                # coordinates keep their shapes (a warp can leave them separable, which changes
                # how noise and pixel maps are sampled); inputs are broadcast to one shape before
                # stacking where that gives the same values: fewer, larger groups
                if ctx.separable:  # not stacked: the primitive sees this very context
                    coords = id(ctx)
                else:
                    coords = (ctx.x.shape[1:], ctx.y.shape[1:])
                shapes = tuple(i.value.shape[1:] for i in inst.inputs)
                form = inst.node.form
                if form == "pointwise":  # broadcast beforehand: the same values
                    shapes = (_broadcast(*shapes),) * len(shapes)
                elif form == "neighbourhood":
                    shapes = tuple((v[0], ctx.H, ctx.W) for v in shapes)
                groups[(s, coords, shapes)].append(inst)
            for (_, coords, shapes), insts in groups.items():
                self._evaluate(insts, coords, shapes)

    def _evaluate(self, insts: list[_Inst], coords, shapes: tuple) -> None:
        """One call for all ``insts``: inputs, parameters and (in warped contexts) coordinates
        stacked along the batch; a coordinate transform makes the warped contexts of its
        instances and asks for their first argument there."""
        sizes = [inst.batch() for inst in insts]
        first = insts[0]
        c = first.where

        def stack(tensors, shape=None):
            parts = [t.expand(b, *(shape or t.shape[1:])) for t, b in zip(tensors, sizes)]
            return parts[0] if len(parts) == 1 else torch.cat(parts)

        def split(v):
            if v.shape[0] == 1:  # the same for every instance (it read nothing batched)
                return [v] * len(insts)
            assert v.shape[0] == sum(sizes), (first.node.symbol, v.shape, sizes)
            return torch.split(v, sizes)

        ctx = c if isinstance(coords, int) else c.moved(stack([i.where.x for i in insts]),
                                                        stack([i.where.y for i in insts]), memo=Memo())
        def stack_params(tensors):
            out = stack(tensors)
            if all(hasattr(t, "host") for t in tensors):  # and their host copies (context.host)
                out.host = [v for t, b in zip(tensors, sizes) for v in (t.host * b if len(t.host) < b else t.host)]
            return out

        p = [stack_params([i.node.params[k] for i in insts]) for k in range(len(first.node.params))]
        inputs = [stack([i.inputs[k].value for i in insts], shapes[k]) for k in range(len(first.inputs))]
        if first.kind == "eval":
            value = apply_kernel(first.node, ctx, p, inputs)
            for inst, v in zip(insts, split(value)):
                self._done(inst, crop(v, inst.where, inst.ctx))
            return
        w = first.node.kernel(ctx, p, *inputs)
        for inst, x, y in zip(insts, split(w.x), split(w.y)):
            w = inst.ctx.moved(x, y, origin=(inst.node, inst.ctx))
            if inst.kind == "coords":
                self._done(inst, w)
            else:
                self._wait(inst, [self.request(inst.node.children[0], w)], "alias")


def evaluate_population(roots: list[BNode], ctx: Context) -> list[torch.Tensor]:
    """Values of the batch trees ``roots`` in the context ``ctx``, evaluated in waves."""
    waves = _Waves()
    insts = [waves.request(r, ctx) for r in roots]
    waves.run()
    return [i.value for i in insts]
