"""Rendering decoded trees in this process (paper section 3.2).

:func:`render_into` builds the unwarped coordinate context of a picture, stacks the trees into
batch trees (:func:`.tree.stack_trees`: a subtree repeated anywhere in the population is one
node) and evaluates them genome by genome (:func:`.tree.evaluate`) or in waves
(:func:`.grouped.evaluate_population`), writing the final mapping (:func:`.context.to_rgb`) of
each into its row of the output. On the CPU torch and BLAS run one thread per image. The worker
processes of :mod:`.workers` run :func:`render_chunk`, the same on their part of a population.
"""

from __future__ import annotations

import contextlib
import gc

import torch

from .context import Context, Resources, to_rgb
from .grouped import evaluate_population
from .tree import Memo, evaluate, stack_trees

__all__ = ["no_gc", "render_into", "render_chunk"]


@contextlib.contextmanager
def no_gc():
    """Python's cycle collector paused: decoding and evaluating a population makes tens of
    thousands of small objects, which it would scan again and again (measured: 16 % of a render
    of 256 genomes at 32^2). Cycles made meanwhile are collected afterwards."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if collecting:
            gc.enable()


_blas = None


def _one_blas_thread():
    """Context: numpy's BLAS (and any other) limited to one thread (threadpoolctl)."""
    global _blas
    if _blas is None:
        from threadpoolctl import ThreadpoolController

        _blas = ThreadpoolController()
    return _blas.limit(limits=1, user_api="blas")


def render_into(out: torch.Tensor, trees, groups: list[list[int]], window, time: float, device,
                 group: bool = False) -> None:
    """Evaluate decoded ``trees`` in this process into ``out`` (N, H, W, 3): ``trees[i]`` goes
    to ``out[i]``; ``groups`` lists the indices of same-shaped trees, evaluated as one batch
    (with ``group``, all batches together in waves: :mod:`.grouped`)."""
    H, W = out.shape[1:3]
    x0, y0, x1, y1 = window
    px, py = (x1 - x0) / W, (y1 - y0) / H
    xs = (x0 + (torch.arange(W, device=device, dtype=torch.float64) + 0.5) * px).float()
    ys = (y0 + (torch.arange(H, device=device, dtype=torch.float64) + 0.5) * py).float()
    ctx = Context(xs.reshape(1, 1, 1, W), ys.reshape(1, 1, H, 1), H, W, abs(px), abs(py), time,
                  Resources.on(device), Memo(), key=(H, W, x0, y0, x1, y1), frame=(x0, y0, px, py, H, W))
    # subtrees repeated anywhere in the population (children of one parent share most of
    # theirs) are built as one node and evaluated once per coordinate context
    shared: dict = {}
    batches = [stack_trees([trees[i] for i in idx], device, shared) for idx in groups]
    saved = torch.get_num_threads()
    single = device.type == "cpu" and (len(groups) > 1 or H * W <= 512 * 512)
    if single:
        # small images: single-threaded torch and BLAS operations (intra-op threads on small
        # images thrash: measured 10-30x slower on a loaded 2-core machine, and idle BLAS
        # threads spin on the cores of the other worker processes); one big image (a file
        # export) keeps the libraries' threads
        torch.set_num_threads(1)
    try:
        with torch.inference_mode(), (_one_blas_thread() if single else contextlib.nullcontext()):
            if group:
                values = evaluate_population(batches, ctx)
            else:
                values = (evaluate(tree, ctx) for tree in batches)
            for idx, v in zip(groups, values):
                rgb = to_rgb(v, H, W)
                for k, i in enumerate(idx):  # copy_ into a view: ~5x faster than out[idx] = ...
                    out[i].copy_(rgb[k if rgb.shape[0] > 1 else 0].permute(1, 2, 0))
    finally:
        torch.set_num_threads(saved)


def render_chunk(out: torch.Tensor, units: list, window, time: float, group: bool) -> None:
    """What a worker process of :mod:`.workers` runs: ``units`` are ``(rows, trees)`` pairs,
    each a batch of decoded trees (checked by :func:`.evaluate.render`) rendered on the CPU
    into ``out[rows]``."""
    with no_gc():
        trees = {r: t for rows, batch in units for r, t in zip(rows, batch)}
        render_into(out, trees, [rows for rows, _ in units], window, time, torch.device("cpu"), group)
