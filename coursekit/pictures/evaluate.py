"""Tensorised evaluation of genetic pictures (paper section 3.2, phenotype): :func:`render`.

The paper formulates "all imaging operations as functions over the whole image" instead of
Sims' per-pixel evaluation. Here every primitive is a torch operation on whole images, and a
whole population is rendered by one call, in one descent:

1. :func:`render` (here): checks the arguments, decodes each genome once and estimates its
   cost (:func:`cost`), then renders in this process or, on the CPU with enough work, in worker
   processes (:mod:`.workers`), which get the decoded trees;
2. :mod:`.local`: one process renders its trees into rows of the output, genome by genome or
   in waves (:mod:`.grouped`: one operation per primitive for all genomes, for GPUs and small
   pictures); on request (``batch=True``) same-shaped trees are stacked into one batch;
3. :mod:`.tree`: batch trees, with every subtree that appears anywhere in the population
   computed once per coordinate context;
4. :mod:`.kernels`: the primitives' whole-image implementations, on :mod:`.context`'s
   coordinate contexts and per-device resources, found through the registry of
   :mod:`.primitives`.

**Final mapping.** :func:`to_rgb` turns any result into RGB in [0, 1]: a grey value is copied
to the three channels, NaN becomes 0, values are clipped to +-1e6 and then *folded*
(mirror-repeat with period 2: identity on [0, 1], ``v -> 2 - v`` on [1, 2], ``v -> -v`` on
[-1, 0], and so on). Folding never saturates to flat white and is continuous.

**Coordinates.** ``window=(x0, y0, x1, y1)`` (default the unit square) gives the world
rectangle shown; pixel centres are sampled, so zooming and panning re-evaluate the genome. A
blur's argument is evaluated beyond the window by the blur's reach (:func:`.tree.padded`), so a
zoomed or panned window is the crop of a larger render, blurs included.

**Batch invariance.** A picture never depends on what it was rendered with (batched, in waves,
in a worker): see :mod:`.kernels`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np
import torch

from . import primitives as P
from .context import clear_cache, default_device, to_rgb
from .frame import MAX_PIXELS, parse_size, parse_time, parse_window
from .genome import Genome, Node
from .local import no_gc, render_into
from .tree import paddings
from .workers import render_parts

__all__ = ["clear_cache", "cost", "default_device", "render", "to_rgb", "MAX_PIXELS"]

_POOL_PIXELS = 1 << 18  # pixels in all from which worker processes pay off (16 images at 128^2)
_WAVES_PIXELS = 64 * 64  # pixels per image up to which waves pay off on the CPU



def cost(node: Node, warped: bool = False, frame: tuple[float, float, int, int] | None = None,
         pad: tuple[int, int] = (0, 0)) -> float:
    """Estimated evaluation time of a decoded tree, in milliseconds at 256 x 256 on one CPU core:
    the sum of its primitives' ``cost`` (:mod:`.primitives`), three times that for a primitive
    that ``samples`` coordinates warped by a transform above it (whole images, not rows).
    Measured: correlation 0.89 with the times of 20 random genomes (tree size alone: 0.04).

    With ``frame`` ``(px, py, H, W)`` (a pixel's world size, the picture's size) a primitive
    evaluated on a grid extended beyond the window -- the argument of ``blur`` and
    ``band-pass`` (and of the other primitives with a reach), by :func:`.primitives.padding`,
    as the evaluators do (:func:`.tree.paddings`) -- counts that grid's pixels, ``(H + 2 rows)
    (W + 2 columns) / (H W)`` times its cost (up to 9 times: an extension is at most the
    picture's size on each side in all); ``pad``: the extension the tree's root is already
    evaluated on. Without ``frame``, the window's pixels only."""
    prim = P.get(node.symbol)
    c = prim.cost * (3.0 if warped and prim.samples else 1.0)
    if frame is not None:
        px, py, H, W = frame
        if node.symbol in P.REACHES:
            with np.errstate(over="ignore"):
                p = [float(v) for v in np.asarray(node.params, dtype=np.float32)]  # as the kernels read them
            q = P.padding(node.symbol, p, px, py, H, W, pad)
            pad = (pad[0] + q[0], pad[1] + q[1])  # the grid of this primitive's argument (and its filter)
        c *= (H + 2 * pad[0]) * (W + 2 * pad[1]) / (H * W)
    warp = prim.form == "warp"  # the first argument sees new coordinates
    return c + sum(cost(ch, warped or (k == 0 and warp), frame, pad) for k, ch in enumerate(node.children))


def render(genomes: Genome | Sequence[Genome], size: int | tuple[int, int] = (128, 128), *,
           window: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0), time: float = 0.0,
           device: str | torch.device | None = None, batch: bool = False, workers: int | None = None,
           group: bool | None = None, as_tensor: bool = False) -> np.ndarray | torch.Tensor:
    """Render genomes as whole images.

    Args:
        genomes: a :class:`Genome` or a sequence of them.
        size: ``(height, width)`` in pixels, or one int for a square.
        window: world rectangle ``(x0, y0, x1, y1)``; zoom and pan re-evaluate.
        time: the animation time (read by ``time`` and ``dissolve``).
        device: torch device (default: CUDA when present, else CPU).
        batch: stack genomes whose trees have the same shape into one evaluation. Off by
            default: a subtree that appears anywhere in the population is computed once, and
            stacking would compute every genome's copy of it; measured on children of one
            parent at 256^2, one process: 104 ms unstacked, 178 ms stacked (random genomes,
            which rarely share a shape: the same either way). On a GPU, ``group`` stacks
            across genomes operation by operation instead, keeping the sharing.
        workers: on the CPU, worker processes that render parts of a population at once when
            there is enough work (at least 2**18 pixels in all; :mod:`.workers`); default one
            per core, ``1`` renders in this process. A population using a primitive registered
            at run time (:func:`~.primitives.register_primitive`) renders in this process: the
            workers import the built-in primitives only.
        group: evaluate the population in waves, one operation per primitive for all genomes
            (:mod:`.grouped`: about 3x fewer tensor operations for 256 random genomes -- 204
            against 676 a picture at 64^2, filters on their extended grids -- so fewer kernel
            launches on a GPU). Default: on a GPU, and on the CPU for images of at
            most 64 x 64 pixels, where calls cost more than pixels (measured in one process:
            2-16 % faster for 20 genomes, 20-55 % for 256; equal at 96^2; 15-20 % slower at
            256^2, where stacking copies cost more than the calls they save). The pictures are
            the same either way.
        as_tensor: return the torch tensor (on ``device``) instead of a numpy array.
    Returns:
        ``(N, H, W, 3)`` float32, finite, in [0, 1].
    """
    if isinstance(genomes, Genome):
        genomes = [genomes]
    if isinstance(genomes, (str, bytes)) or not hasattr(genomes, "__iter__"):
        raise TypeError(f"genomes: expected a Genome or a list of them, got {type(genomes).__name__}")
    genomes = list(genomes)
    for i, g in enumerate(genomes):
        if not isinstance(g, Genome):
            raise TypeError(f"genomes[{i}]: expected a Genome, got {type(g).__name__}")
    H, W = parse_size(size)
    window = parse_window(window)
    time = parse_time(time)
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers: {workers!r} must be a positive integer or None")
    if group is not None and not isinstance(group, (bool, np.bool_)):
        raise ValueError(f"group: {group!r} must be True, False or None")
    try:
        device = torch.device(device) if device is not None else default_device()
    except (RuntimeError, TypeError) as e:
        raise ValueError(f"device: {device!r} is not a torch device ({e})") from None
    if device.type == "cuda" and not torch.cuda.is_available():
        raise ValueError(f"device: {str(device)!r} needs CUDA, which this machine does not have; use 'cpu' or None")
    group = (device.type != "cpu" or H * W <= _WAVES_PIXELS) if group is None else bool(group)
    with no_gc():
        trees = [g.decode() for g in genomes]  # once: the workers get the trees
        groups = _groups(trees, batch, (H, W), window)
        if (device.type == "cpu" and workers > 1 and len(groups) > 1 and len(genomes) * H * W >= _POOL_PIXELS
                and not (P.REGISTERED and any(_uses(t, P.REGISTERED) for t in trees))):
            frame = (*_pixel(window, H, W), H, W)
            pics = render_parts([(idx, [trees[i] for i in idx]) for idx in groups],
                                [cost(trees[idx[0]], frame=frame) * len(idx) for idx in groups], (H, W),
                                {"window": window, "time": float(time), "group": group}, int(workers))
            if pics is not None:
                return torch.from_numpy(pics) if as_tensor else pics
        out = torch.empty(len(genomes), H, W, 3, dtype=torch.float32, device=device)
        render_into(out, trees, groups, window, float(time), device, group)
    return out if as_tensor else out.cpu().numpy()


def _uses(node: Node, names: set[str]) -> bool:
    """Whether the tree holds a primitive called one of ``names``."""
    return node.symbol in names or any(_uses(c, names) for c in node.children)


def _groups(trees: list[Node], batch: bool, size: tuple[int, int], window) -> list[list[int]]:
    """Indices of same-shaped trees whose neighbourhoods extend the picture alike (one batch
    each: :func:`.tree.paddings`), or one index per group without ``batch``."""
    H, W = size
    px, py = _pixel(window, H, W)
    groups: dict = {}
    for i, t in enumerate(trees):
        groups.setdefault((t.structure(), paddings(t, px, py, H, W)) if batch else i, []).append(i)
    return list(groups.values())


def _pixel(window, H: int, W: int) -> tuple[float, float]:
    """A pixel's world size ``(px, py)`` in a picture of ``H`` x ``W`` showing ``window``, as
    :func:`~.local.render_into` computes it."""
    return abs((window[2] - window[0]) / W), abs((window[3] - window[1]) / H)
