"""Tensorised evaluation of genetic pictures (paper section 3.2, phenotype).

The paper formulates "all imaging operations as functions over the whole image" instead of
Sims' per-pixel evaluation. Here every primitive is a torch operation on whole images, and a
whole population is rendered by one call: each genome's tree, with every subtree that appears
anywhere in the population computed once; on a GPU (and for small pictures) the population is
evaluated in waves, one operation per primitive for all genomes (:mod:`.grouped`); on request (``batch=True``) genomes
whose trees have the same shape are stacked into one batch.

**Types (section 3.2).** A value is a tensor ``(B, C, Hs, Ws)``: ``C`` is 1 (grey) or 3
(RGB) and ``Hs, Ws`` are 1 or the image size. A *scalar* is ``(B, 1, 1, 1)``, a *vector*
(colour) ``(B, 3, 1, 1)``, a *matrix* (pixel map) has ``Hs = H`` or ``Ws = W``. A function of
mixed inputs returns the most complex type of its inputs, which is exactly what broadcasting
gives: scalar + vector = vector, vector * matrix = colour matrix. ``x`` is ``(1, 1, 1, W)``
and ``y`` is ``(1, 1, H, 1)``, so a chain of pointwise operations on ``x`` alone costs ``W``
evaluations, not ``H W``.

**Final mapping.** :func:`to_rgb` turns any result into RGB in [0, 1]: a grey value is copied
to the three channels, NaN becomes 0, values are clipped to +-1e6 and then *folded*
(mirror-repeat with period 2: identity on [0, 1], ``v -> 2 - v`` on [1, 2], ``v -> -v`` on
[-1, 0], and so on). Folding never saturates to flat white and is continuous.

**Coordinates.** ``window=(x0, y0, x1, y1)`` (default the unit square) gives the world
rectangle shown; pixel centres are sampled, so zooming and panning re-evaluate the genome.
Coordinate transforms (``swirl``, ``rotate``, ``warp-swirl``, ``warp-by``) re-evaluate their
first argument on transformed coordinates; neighbourhood operations (``blur``, ``band-pass``,
``bump``, ``grad-mag``, ``grad-dir``) act on the pixel grid with replicated borders and sizes
in world units.

**Speed.** Most of the time goes to a few primitives on whole images, so each picks the
cheapest exact method for the coordinates it gets. Unwarped coordinates are *separable*
(``x`` varies along columns, ``y`` along rows): noise then interpolates lattice rows, then
columns (small matrices for a few lattice cells, gathers for many), pixel maps are sampled
rows-then-columns and kept per (size, window) across renders (a gallery renders every
generation at one size), and dissolve looks its cells up per row and column. Warped
coordinates fall back to ``grid_sample``. Blurs multiply by banded matrices cut into row
tiles, touching only the band. A subtree repeated anywhere in the population (a clone, or
the parts that children of one parent share) is one node, evaluated once per coordinate
context, and the parts of a batch with the same parameters in every tree run once and
broadcast. Node values are never modified in place (cached pictures and shared subtrees are
handed to several parents); only fresh intermediates are. On the CPU, transcendental functions
and the blurs' matrix products go through numpy (faster there than torch's: :func:`_ufunc`),
torch and BLAS run one thread per image, and a big enough population is split over worker
processes (:mod:`.workers`).

**Batch invariance.** Every primitive computes each image of a batch as it would compute it
alone, bit for bit, so a picture never depends on what it was rendered with (batched, in waves,
in a worker): no reduction over a batch picks a method or a size, and no library kernel whose
rounding depends on an element's position in the tensor is used (torch's CPU ``atan2`` is one,
measured).
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import threading
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
import torch

from . import textures as T
from .genome import Genome, Node

__all__ = ["clear_cache", "default_device", "render", "to_rgb", "MAX_PIXELS"]

MAX_PIXELS = 4096 * 4096  # pixels of one rendered picture at most (a 4096^2 poster: 192 MiB of float32)

_BIG = 1e6
TWO_PI = 2.0 * math.pi


def default_device() -> torch.device:
    """CUDA when present, else CPU."""
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


@dataclass
class _Ctx:
    x: torch.Tensor  # broadcastable to (B, 1, H, W)
    y: torch.Tensor
    H: int
    W: int
    px: float  # world width of a pixel
    py: float
    time: float
    res: _Resources
    memo: _Memo  # shared subtree values, shared by derived contexts
    key: tuple | None = None  # (H, W, window) of the unwarped context: its terminals are cached

    def with_coords(self, x, y) -> _Ctx:
        return _Ctx(_sane(x), _sane(y), self.H, self.W, self.px, self.py, self.time, self.res, self.memo)


_TILE = 32  # output rows per tile of a banded blur matrix (measured best at 256^2)
_CACHE_BYTES = 64 << 20  # unwarped terminal images kept across renders (per device)


class _Resources:
    """Per device: noise lattice, pixel maps, blur matrices and sampled unwarped pixel maps."""

    _cache: ClassVar[dict] = {}

    def __init__(self, device):
        self.device = device
        self.table = torch.from_numpy(T.noise_table()).to(device)
        wrapped = torch.cat([self.table, self.table[:1]], dim=0)
        self.wrapped = torch.cat([wrapped, wrapped[:, :1]], dim=1)[None, None].contiguous()
        self.box_matrices: dict = {}
        self.pixmaps: dict[int, torch.Tensor] = {}
        self._sampled: OrderedDict = OrderedDict()
        self._sampled_bytes = 0
        self._lock = threading.Lock()

    @classmethod
    def on(cls, device) -> _Resources:
        key = str(device)
        if key not in cls._cache:
            cls._cache[key] = cls(device)
        return cls._cache[key]

    def box_matrix(self, n: int, r: int) -> list:
        """Three replicate-border box passes of radius r as a banded (n, n) matrix M, cut
        into row tiles: ``[(lo, hi, M[t0:t1, lo:hi]), ...]`` where columns outside
        ``lo:hi`` are zero in those rows (one tile, the whole matrix, when the band is wide)."""
        key = (n, r)
        if key not in self.box_matrices:
            b = torch.zeros(n, n, dtype=torch.float64)
            rows = torch.arange(n).repeat_interleave(2 * r + 1)
            cols = (torch.arange(n)[:, None] + torch.arange(-r, r + 1)[None, :]).clamp(0, n - 1).reshape(-1)
            b.index_put_((rows, cols), torch.full_like(rows, 1.0 / (2 * r + 1), dtype=torch.float64),
                         accumulate=True)
            m = (b @ b @ b).float().to(self.device)
            spans = [(t0, min(n, t0 + _TILE), max(0, t0 - 3 * r), min(n, t0 + _TILE + 3 * r))
                     for t0 in range(0, n, _TILE)]
            if sum((t1 - t0) * (hi - lo) for t0, t1, lo, hi in spans) > 0.6 * n * n:
                spans = [(0, n, 0, n)]  # wide band: one dense product is faster
            self.box_matrices[key] = [(lo, hi, m[t0:t1, lo:hi].contiguous()) for t0, t1, lo, hi in spans]
        return self.box_matrices[key]

    def sampled(self, key, compute) -> torch.Tensor:
        """``compute()``, cached under ``key`` (least recently used first out, at most
        :data:`_CACHE_BYTES`); ``key=None`` computes without caching. Thread-safe."""
        if key is None:
            return compute()
        with self._lock:
            if key in self._sampled:
                self._sampled.move_to_end(key)
                return self._sampled[key]
        value = compute()
        size = value.numel() * value.element_size()
        with self._lock:
            if key not in self._sampled and size <= _CACHE_BYTES // 4:
                self._sampled[key] = value
                self._sampled_bytes += size
                while self._sampled_bytes > _CACHE_BYTES:
                    _, old = self._sampled.popitem(last=False)
                    self._sampled_bytes -= old.numel() * old.element_size()
        return value

    def pixmap(self, i: int) -> torch.Tensor:
        if i not in self.pixmaps:
            # planar (N, C, H, W) storage: separable sampling is 2.5x faster than on interleaved RGB
            self.pixmaps[i] = torch.from_numpy(T.pixmap(i)).permute(2, 0, 1)[None].contiguous().to(self.device)
        return self.pixmaps[i]


def clear_cache() -> None:
    """Forget the cached unwarped pixel maps on every device (renders stay identical)."""
    for res in _Resources._cache.values():
        with res._lock:
            res._sampled.clear()
            res._sampled_bytes = 0


def _sane(v: torch.Tensor) -> torch.Tensor:
    """NaN -> 0 and clip to +-1e6 (inputs of indexing and integer operations)."""
    return torch.nan_to_num(v, nan=0.0, posinf=_BIG, neginf=-_BIG).clamp_(-_BIG, _BIG)


def _fmod(v: torch.Tensor, m) -> torch.Tensor:
    """Floored modulo v - m floor(v / m) (sign of m, like Python's %), cheaper than remainder."""
    if isinstance(m, float):
        return torch.sub(v, torch.floor(v / m), alpha=m)
    return v - m * torch.floor(v / m)


def fold(v: torch.Tensor) -> torch.Tensor:
    """Mirror-repeat into [0, 1] with period 2: |v - 2 round(v / 2)| (= 1 - |(v mod 2) - 1|)."""
    return torch.sub(v, (v * 0.5).round_(), alpha=2.0).abs_()


def to_rgb(v: torch.Tensor, H: int, W: int) -> torch.Tensor:
    """The documented final mapping: any value -> (B, 3, H, W) float32 in [0, 1]."""
    v = fold(_sane(v.float()))
    return v.expand(v.shape[0], 3, H, W)


# ---- numpy's kernels on the CPU -------------------------------------------------------------

_NUMPY_MIN = 4096  # elements from which numpy's ufunc beats torch's on the CPU


def _ufunc(torch_fn, numpy_fn, smallest: int = _NUMPY_MIN):
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


_sin, _cos, _exp = _ufunc(torch.sin, np.sin), _ufunc(torch.cos, np.cos), _ufunc(torch.exp, np.exp)
_log, _sqrt = _ufunc(torch.log, np.log), _ufunc(torch.sqrt, np.sqrt)
# torch's vectorised atan2 rounds the elements past the last full vector differently (measured),
# so a picture would depend on the size of its batch: numpy's, whatever the size
_atan, _atan2 = _ufunc(torch.atan, np.arctan), _ufunc(torch.atan2, np.arctan2, smallest=0)
_matmul = _ufunc(torch.matmul, np.matmul)


def _grey(v):
    return v if v.shape[1] == 1 else v.mean(dim=1, keepdim=True)


def _full(v, ctx):
    return v.expand(v.shape[0], v.shape[1], ctx.H, ctx.W)


# ---- noise --------------------------------------------------------------------------------

def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


_WIDTHS = (8, 16, 32, 48)  # interpolation matrix widths (lattice cells + 1); gathers beyond


def _cell(u: torch.Tensor):
    """Lattice cell index (wrapped into [0, L)) and smoothed fraction of coordinates u."""
    i0 = torch.floor(u)
    return _fmod(i0, float(T.LATTICE)).long(), _smooth(u - i0)


def _axis_weights(u: torch.Tensor, i0: torch.Tensor, lo: torch.Tensor, k: int):
    """Interpolation matrix (B, n, k) for lattice coordinates u (B, n) with cells i0 = floor(u)
    from lo (B, 1) on, spanning fewer than k cells."""
    s = _smooth(u - i0)
    w = torch.zeros(u.shape[0], u.shape[1], k, dtype=u.dtype, device=u.device)
    rel = (i0 - lo).long().unsqueeze(-1)
    w.scatter_(2, rel, (1.0 - s).unsqueeze(-1))
    w.scatter_add_(2, rel + 1, s.unsqueeze(-1))
    return w


def _separable_noise(table, wrapped, uu: torch.Tensor, vv: torch.Tensor) -> torch.Tensor:
    """Noise (B, 1, H, W) at columns uu (B, W) and rows vv (B, H).

    An image spanning few lattice cells is ``Wy @ block @ Wx^T`` with small interpolation
    matrices, one spanning many gathers its two neighbouring lattice rows and columns (a cost
    independent of the frequency). Each image's method and matrix width follow from its own
    span, never from the rest of the batch, so an image rendered in a batch is bit for bit the
    image rendered alone (products of other widths round differently).
    """
    fu, fv = torch.floor(uu), torch.floor(vv)
    lx, ly = fu.amin(1, keepdim=True), fv.amin(1, keepdim=True)
    span = torch.maximum(fu.amax(1) - lx[:, 0], fv.amax(1) - ly[:, 0]) + 2.0
    widths = [next((k for k in _WIDTHS if k >= s), 0) for s in span.tolist()]
    if len(set(widths)) > 1:
        out = torch.empty(uu.shape[0], 1, vv.shape[1], uu.shape[1], dtype=uu.dtype, device=uu.device)
        for k in set(widths):
            sel = torch.tensor([b for b, w in enumerate(widths) if w == k], device=uu.device)
            out[sel] = _separable_noise(table, wrapped, uu[sel], vv[sel])
        return out
    k = widths[0]
    if k:
        wx, wy = _axis_weights(uu, fu, lx, k), _axis_weights(vv, fv, ly, k)
        cells = torch.arange(k, device=uu.device)
        cols = torch.remainder(lx.long() + cells, T.LATTICE)  # (B, k)
        rows = torch.remainder(ly.long() + cells, T.LATTICE)
        block = table[rows.unsqueeze(-1), cols.unsqueeze(1)]  # (B, k, k)
        return torch.bmm(torch.bmm(wy, block), wx.transpose(1, 2)).unsqueeze(1)
    B, H, W = uu.shape[0], vv.shape[1], uu.shape[1]
    j0, sy = _cell(vv)
    i0, sx = _cell(uu)
    rows = torch.lerp(wrapped[j0], wrapped[j0 + 1], sy.unsqueeze(-1))  # (B, H, L + 1): i0 + 1 needs no wrap
    idx0, idx1 = (i.unsqueeze(1).expand(B, H, W) for i in (i0, i0 + 1))  # +1 before expanding
    return torch.lerp(torch.gather(rows, 2, idx0), torch.gather(rows, 2, idx1), sx.unsqueeze(1)).unsqueeze(1)


def _noise(ctx: _Ctx, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Value noise at lattice coordinates u (columns) and v (rows); returns (B, 1, Hs, Ws).

    Separable coordinates (u varies along columns only, v along rows only, as in an
    unwarped context) interpolate rows first, then columns (:func:`_separable_noise`).
    """
    u, v = _sane(u), _sane(v)
    res = ctx.res
    if u.shape[-2] == 1 and v.shape[-1] == 1 and u.shape[-1] == ctx.W and v.shape[-2] == ctx.H:
        B = max(u.shape[0], v.shape[0])
        return _separable_noise(res.table, res.wrapped[0, 0], u.reshape(u.shape[0], ctx.W).expand(B, ctx.W),
                                v.reshape(v.shape[0], ctx.H).expand(B, ctx.H))
    # general coordinates: bilinear lookup at i0 + smooth(frac) is exactly the smoothstep
    # interpolation; the table is padded with its first row and column to wrap around
    u, v = torch.broadcast_tensors(u, v)
    grid = torch.empty(u.shape[0], u.shape[2], u.shape[3], 2, dtype=u.dtype, device=u.device)
    _lattice_point(u[:, 0], grid[..., 0])
    _lattice_point(v[:, 0], grid[..., 1])
    grid.mul_(2.0 / T.LATTICE).sub_(1.0)
    return torch.nn.functional.grid_sample(res.wrapped.expand(grid.shape[0], -1, -1, -1), grid,
                                           mode="bilinear", align_corners=True)


def _lattice_point(t: torch.Tensor, out: torch.Tensor) -> None:
    """``out = (floor(t) mod L) + smooth(t - floor(t))``: the point of the padded table that
    bilinear lookup reads (fresh intermediates updated in place: few allocations)."""
    i0 = torch.floor(t)
    f = torch.sub(t, i0)
    s = f * f
    f.mul_(-2.0).add_(3.0).mul_(s)  # smooth(frac) = frac^2 (3 - 2 frac)
    w = torch.mul(i0, 1.0 / T.LATTICE).floor_()
    i0.sub_(w, alpha=float(T.LATTICE))  # the cell index mod L (exact: L is a power of two)
    torch.add(i0, f, out=out)


# ---- terminals (p: list of (B, 1, 1, 1) parameter tensors) ---------------------------------

def _const(ctx, p):
    return p[0]


def _color(ctx, p):
    return torch.cat(p[:3], dim=1)


def _radius(ctx, p):
    return _sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)


def _angle(ctx, p):
    return _fmod(_atan2(ctx.y - 0.5, ctx.x - 0.5) / TWO_PI, 1.0)


def _along(ctx, turns):
    a = TWO_PI * turns
    return ctx.x * _cos(a) + ctx.y * _sin(a)


def _ramp(ctx, p):
    v = p[1] * _along(ctx, p[0])
    return v - torch.floor(v)


def _gradient(ctx, p):
    t = fold(_along(ctx, p[6]))
    c0, c1 = torch.cat(p[0:3], dim=1), torch.cat(p[3:6], dim=1)
    return c0 + (c1 - c0) * t


def _bw_noise(ctx, p):
    return _noise(ctx, ctx.x * p[0] + p[1], ctx.y * p[0] + p[2])


def _stacked_noise(ctx, freq, ox, oy, scales, shifts):
    """Noise at frequencies ``freq * scales[o]`` and offsets ``(ox, oy) + shifts[o]``; returns
    (O, B, 1, Hs, Ws). Separable coordinates are evaluated in one stacked call; full coordinate
    images one octave at a time (faster: each octave's intermediates stay in cache)."""
    if ctx.x.shape[-2] > 1 or ctx.y.shape[-1] > 1:
        return torch.stack([_noise(ctx, ctx.x * (freq * s) + ox + dx, ctx.y * (freq * s) + oy + dy)
                            for s, (dx, dy) in zip(scales, shifts)])
    O = len(scales)
    k = torch.tensor([[s, dx, dy] for s, (dx, dy) in zip(scales, shifts)], dtype=torch.float32,
                     device=ctx.x.device).reshape(O, 3, 1, 1, 1, 1)
    f = freq * k[:, 0]  # (O, B, 1, 1, 1)
    u = (ctx.x * f + ox + k[:, 1]).flatten(0, 1)
    v = (ctx.y * f + oy + k[:, 2]).flatten(0, 1)
    n = _noise(ctx, u, v)
    return n.reshape(O, -1, *n.shape[1:])


def _color_noise(ctx, p):
    n = _stacked_noise(ctx, p[0], p[1], p[2], (1.0, 1.0, 1.0), T.CHANNEL_SHIFT)  # (3, B, 1, Hs, Ws)
    return n[:, :, 0].transpose(0, 1)


def _turbulence(ctx, p):
    octaves = torch.floor(p[1]).clamp(1, 8)
    count = int(octaves.max())
    shifts = [(o * T.OCTAVE_SHIFT[0], o * T.OCTAVE_SHIFT[1]) for o in range(count)]
    n = _stacked_noise(ctx, p[0], p[2], p[3], [2.0 ** o for o in range(count)], shifts)
    n = n.mul_(2.0).sub_(1.0).abs_()
    weight = torch.stack([(octaves > o).to(p[0].dtype) * 0.5 ** o for o in range(count)])  # (O, B, 1, 1, 1)
    return (weight * n).sum(dim=0) / weight.sum(dim=0)


def _bilinear_axis(f: torch.Tensor, n: int):
    """Source indices and weights of grid_sample's bilinear sampling (align_corners=False,
    border padding) at unit coordinates f along an axis of n pixels."""
    t = (f * n - 0.5).clamp_(0.0, n - 1.0)
    i0 = torch.floor(t)
    return i0.long(), (i0 + 1.0).clamp_(max=n - 1.0).long(), t - i0


def _pixmap_separable(img: torch.Tensor, x: torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Bilinear sampling of img (1, 3, h, w) at fold(x) (W,) and fold(y) (H,): rows, then columns."""
    r0, r1, wy = _bilinear_axis(fold(y), img.shape[2])
    c0, c1, wx = _bilinear_axis(fold(x), img.shape[3])
    rows = torch.lerp(img[:, :, r0], img[:, :, r1], wy[:, None])  # (1, 3, H, w)
    return torch.lerp(rows[..., c0], rows[..., c1], wx)


def _pixmap(ctx, p):
    idx = [T.pixmap_index(float(v)) for v in p[0].reshape(-1)]
    B = len(idx)
    if ctx.x.shape[:3] == (1, 1, 1) and ctx.y.shape[0] == 1 and ctx.y.shape[3] == 1:
        # separable coordinates (an unwarped context): sample rows then columns, and keep the
        # result for the whole render (and across renders of the same size and window)
        key = None if ctx.key is None else ("pixmap", ctx.key)
        pics = [ctx.res.sampled((key, i) if key else None,
                                lambda i=i: _pixmap_separable(ctx.res.pixmap(i), ctx.x[0, 0, 0], ctx.y[0, 0, :, 0]))
                for i in idx]
        return pics[0] if B == 1 else torch.cat(pics)
    x, y = torch.broadcast_tensors(fold(ctx.x), fold(ctx.y))
    grid = torch.empty(x.shape[0], ctx.H, ctx.W, 2, dtype=x.dtype, device=x.device)
    torch.mul(x[:, 0], 2.0, out=grid[..., 0])
    torch.mul(y[:, 0], 2.0, out=grid[..., 1])
    grid.sub_(1.0)
    if B == 1:  # one picture (a uniform node may see per-genome coordinates)
        return torch.nn.functional.grid_sample(ctx.res.pixmap(idx[0]).expand(grid.shape[0], -1, -1, -1), grid,
                                               mode="bilinear", padding_mode="border", align_corners=False)
    grid = grid.expand(B, ctx.H, ctx.W, 2)
    out = torch.empty(B, 3, ctx.H, ctx.W, dtype=x.dtype, device=x.device)
    for i in sorted(set(idx)):
        sel = [b for b in range(B) if idx[b] == i]
        img = ctx.res.pixmap(i).expand(len(sel), -1, -1, -1)
        out[sel] = torch.nn.functional.grid_sample(img, grid[sel].contiguous(), mode="bilinear",
                                                   padding_mode="border", align_corners=False)
    return out


def _time(ctx, p):
    return torch.full((1, 1, 1, 1), float(ctx.time), device=ctx.x.device)


# ---- pointwise functions --------------------------------------------------------------------

_HSV_N = {}  # device -> (1, 3, 1, 1) tensor (5, 3, 1): the R, G, B phase of hsv-to-rgb


def _hsv_to_rgb(a):
    h = _fmod(_sane(a[:, 0:1]), 1.0)
    n = _HSV_N.get(a.device)
    if n is None:
        n = _HSV_N[a.device] = torch.tensor([5.0, 3.0, 1.0], device=a.device).reshape(1, 3, 1, 1)
    k = _fmod(n + 6.0 * h, 6.0)  # (B, 3, Hs, Ws): all three channels at once
    chroma = torch.minimum(k, 4.0 - k).clamp_(0.0, 1.0)
    if a.shape[1] == 1:  # a grey value is the hue at full saturation and value
        return chroma.neg_().add_(1.0)
    s, v = a[:, 1:2].clamp(0, 1), a[:, 2:3].clamp(0, 1)
    return v - v * s * chroma


def _select(mask, a, b):
    """``torch.where(mask, b, a)`` as bit operations: exact (inf and NaN included) and, unlike
    ``where``, branch-free, so fast on speckled masks such as dissolve's cells."""
    a, b = torch.broadcast_tensors(a.float(), b.float())
    ai = a.view(torch.int32)
    m = mask.to(torch.int32).neg_()  # all bits set where mask
    return (ai ^ ((ai ^ b.view(torch.int32)) & m)).view(torch.float32)


def _safe_div(a, b):
    # |b| raised to 1e-3 keeping its sign (-0 counts as +0): where(|b| < 1e-3, +-1e-3, b)
    return a / torch.copysign((b + 0.0).abs().clamp_(min=1e-3), b + 0.0)


def _mod(a, b):
    small = b.abs() < 1e-3
    return torch.where(small, a, _fmod(a, torch.where(small, 1.0, b)))


def _quant(v):
    """fold(v) in 256 levels (int32); ``_sane`` gives a fresh tensor, folded in place."""
    v = _sane(v)
    return v.sub_((v * 0.5).round_(), alpha=2.0).abs_().mul_(255.999).to(torch.int32)  # >= 0: floor


def _bits(op):
    def f(a, b):  # each operand quantised at its own shape; the bit operation broadcasts
        return op(_quant(a), _quant(b)).to(torch.float32).div_(255.0)
    return f


_POINTWISE1 = {
    "abs": torch.abs,
    "sin": lambda a: 0.5 + 0.5 * _sin(TWO_PI * a),
    "cos": lambda a: 0.5 + 0.5 * _cos(TWO_PI * a),
    "log": lambda a: _log(a.abs() + 1e-6),
    "atan": lambda a: _atan(a) / math.pi + 0.5,
    "round": lambda a: torch.floor(a + 0.5),
    "invert": lambda a: 1.0 - a,
    "hsv-to-rgb": _hsv_to_rgb,
}

_POINTWISE2 = {
    "plus": torch.add,
    "minus": torch.sub,
    "times": torch.mul,
    "divide": _safe_div,
    "mod": _mod,
    "expt": lambda a, b: _exp((b * _log(a.abs() + 1e-6)).clamp(-30.0, 30.0)),
    "min": torch.minimum,
    "max": torch.maximum,
    "and": _bits(torch.bitwise_and),
    "or": _bits(torch.bitwise_or),
    "xor": _bits(torch.bitwise_xor),
}


# ---- neighbourhood functions ----------------------------------------------------------------

def _box(v, r: int, dim: int):
    """Mean over a (2r+1) window along ``dim`` with replicated borders (cumulative sums)."""
    n = v.shape[dim]
    if r == 0 or n == 1:
        return v
    idx = torch.arange(-r, n + r, device=v.device).clamp(0, n - 1)
    padded = v.double().index_select(dim, idx)
    c = torch.cumsum(padded, dim=dim)
    zero = torch.zeros_like(c.narrow(dim, 0, 1))
    c = torch.cat([zero, c], dim=dim)
    out = (c.narrow(dim, 2 * r + 1, n) - c.narrow(dim, 0, n)) / (2 * r + 1)
    return out.to(v.dtype)


def _blur_by(v, sigma: torch.Tensor, ctx):
    """Three box passes per axis; radius per batch element from sigma (world units)."""
    if v.shape[-1] == 1 and v.shape[-2] == 1:
        return v
    B = max(sigma.shape[0], v.shape[0])  # a uniform blur may see per-genome inputs
    v = v.expand(B, *v.shape[1:])
    outs = []
    for b in range(B):
        s = float(sigma[b if sigma.shape[0] > 1 else 0])
        rx = T.box_radius(abs(s) / ctx.px, 4 * ctx.W)
        ry = T.box_radius(abs(s) / ctx.py, 4 * ctx.H)
        o = v[b:b + 1]
        if max(ctx.H, ctx.W) <= 1024:  # one banded matrix per axis (fast for small images)
            if rx and o.shape[3] > 1:
                parts = [_matmul(o[..., lo:hi], m.T) for lo, hi, m in ctx.res.box_matrix(ctx.W, rx)]
                o = parts[0] if len(parts) == 1 else torch.cat(parts, dim=3)
            if ry and o.shape[2] > 1:
                parts = [_matmul(m, o[..., lo:hi, :]) for lo, hi, m in ctx.res.box_matrix(ctx.H, ry)]
                o = parts[0] if len(parts) == 1 else torch.cat(parts, dim=2)
        else:  # large images: cumulative sums, cost independent of the radius
            for _ in range(3):
                o = _box(_box(o, rx, 3), ry, 2)
        outs.append(o)
    return torch.cat(outs, dim=0)


def _diff(v, dim, step):
    """Central difference along ``dim`` with replicated borders, divided by 2 step."""
    n = v.shape[dim]
    if n == 1:
        return torch.zeros_like(v)
    pad = (1, 1, 0, 0) if dim == 3 else (0, 0, 1, 1)
    p = torch.nn.functional.pad(v, pad, mode="replicate")
    return (p.narrow(dim, 2, n) - p.narrow(dim, 0, n)).div_(2.0 * step)


def _gradients(v, ctx):
    g = _sane(_grey(v))
    return _diff(g, 3, ctx.px), _diff(g, 2, ctx.py)


def _bump(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    a = TWO_PI * p[0]
    nx, ny = -gx * p[1], -gy * p[1]
    dot = (nx * _cos(a) + ny * _sin(a) + 1.0) / math.sqrt(2.0)
    return (dot / _sqrt(nx * nx + ny * ny + 1.0)).clamp(min=0.0)


def _grad_mag(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    return p[0] * _sqrt(gx * gx + gy * gy)


def _grad_dir(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    return _fmod(_atan2(gy, gx) / TWO_PI, 1.0)


# ---- coordinate transforms ------------------------------------------------------------------

def _turn(ctx, angle):
    dx, dy = ctx.x - 0.5, ctx.y - 0.5
    c, s = _cos(angle), _sin(angle)
    return ctx.with_coords(0.5 + dx * c - dy * s, 0.5 + dx * s + dy * c)


def _swirl_ctx(ctx, p):
    r = _sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)
    return _turn(ctx, p[0] * _exp(-r / p[1].clamp(min=1e-3)))


def _warp_context(symbol: str, ctx: _Ctx, p: list, b: torch.Tensor | None) -> _Ctx:
    """The context in which a coordinate transform evaluates its first argument (``b``: the
    value of its second argument, for ``warp-swirl`` and ``warp-by``)."""
    if symbol == "swirl":
        return _swirl_ctx(ctx, p)
    if symbol == "rotate":
        return _turn(ctx, TWO_PI * p[0])
    if symbol == "warp-swirl":
        return _turn(ctx, p[0] * _grey(b))
    d0, d1 = (b[:, 0:1], b[:, 1:2]) if b.shape[1] == 3 else (b, b)  # warp-by
    return ctx.with_coords(ctx.x + p[0] * (d0 - 0.5), ctx.y + p[0] * (d1 - 0.5))


_TERMINALS = {
    "const": _const, "color": _color, "x": lambda ctx, p: ctx.x, "y": lambda ctx, p: ctx.y,
    "radius": _radius, "angle": _angle, "ramp": _ramp, "gradient": _gradient,
    "bw-noise": _bw_noise, "color-noise": _color_noise, "turbulence": _turbulence,
    "pixmap": _pixmap, "time": _time,
}

_NEIGHBOURHOOD = {"bump": _bump, "grad-mag": _grad_mag, "grad-dir": _grad_dir}


@dataclass(eq=False)
class _BNode:
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


def _stack_trees(trees: Sequence[Node], device, shared: dict) -> _BNode:
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
        node = shared[key] = _BNode(first.symbol, [], kids, uniform)
        if params[0]:
            pending.append((node, len(columns[uniform]), len(params[0])))
            columns[uniform].extend(zip(*params))
        return node

    root = build(list(trees))
    values = {u: torch.tensor(c, dtype=torch.float32, device=device).reshape(len(c), -1, 1, 1, 1).unbind(0)
              for u, c in columns.items() if c}
    for node, start, count in pending:
        node.params = list(values[node.uniform][start:start + count])
    return root


class _Memo:
    """Values of shared subtrees for one render, per (node, coordinate context); an entry is
    dropped once all ``uses`` parents have read it. Thread-safe (a race only recomputes)."""

    def __init__(self):
        self.values: dict = {}
        self.lock = threading.Lock()

    def get(self, n: _BNode, ctx: _Ctx) -> torch.Tensor:
        key = (id(n), id(ctx))
        with self.lock:
            hit = self.values.get(key)
            if hit is not None:
                hit[2] -= 1
                if hit[2] <= 0:
                    del self.values[key]
                return hit[0]
        value = _eval_node(n, ctx)
        with self.lock:
            if key not in self.values:
                self.values[key] = [value, ctx, n.uses - 1]  # ctx kept alive: its id stays unique
        return value


def _eval(n: _BNode, ctx: _Ctx) -> torch.Tensor:
    return _eval_node(n, ctx) if n.uses == 1 else ctx.memo.get(n, ctx)


def _eval_node(n: _BNode, ctx: _Ctx) -> torch.Tensor:
    s, p = n.symbol, n.params
    if s in _TERMINALS:
        return _TERMINALS[s](ctx, p)
    if s in _POINTWISE1:
        return _POINTWISE1[s](_eval(n.children[0], ctx))
    if s in _POINTWISE2:
        return _POINTWISE2[s](_eval(n.children[0], ctx), _eval(n.children[1], ctx))
    if s in _NEIGHBOURHOOD:
        return _NEIGHBOURHOOD[s](_full(_eval(n.children[0], ctx), ctx), p, ctx)
    if s == "blur":
        return _blur_by(_eval(n.children[0], ctx), p[0][:, 0, 0, 0], ctx)
    if s == "band-pass":
        a = _eval(n.children[0], ctx)
        sig = p[0][:, 0, 0, 0]
        return 0.5 + _blur_by(a, sig, ctx) - _blur_by(a, 3.0 * sig, ctx)
    if s in _WARPS:
        b = _eval(n.children[1], ctx) if len(n.children) > 1 else None
        return _eval(n.children[0], _warp_context(s, ctx, p, b))
    if s == "dissolve":
        a, b = _eval(n.children[0], ctx), _eval(n.children[1], ctx)
        # cell indices per column and per row (per pixel only in a warped context)
        ci = torch.remainder(torch.floor(_sane(ctx.x * T.DISSOLVE_CELLS + p[2])).long(), T.LATTICE)
        cj = torch.remainder(torch.floor(_sane(ctx.y * T.DISSOLVE_CELLS + p[3])).long(), T.LATTICE)
        cell = ctx.res.table[cj, ci]
        amount = _fmod(p[0] + p[1] * ctx.time, 1.0)
        return _select(cell < amount, a, b)
    raise ValueError(f"primitive {s!r} has no whole-image implementation")  # pragma: no cover


def _parse_size(size):
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        size = (size, size)
    try:
        h, w = (int(v) for v in size)
        ok = all(float(v) == int(v) for v in size)
    except (TypeError, ValueError):
        ok = False
    if not ok or h < 1 or w < 1:
        raise ValueError(f"size: {size!r} must be an int or (height, width) of positive ints")
    if h * w > MAX_PIXELS:
        raise ValueError(f"size: {h} x {w} is {h * w:,} pixels; a picture has at most {MAX_PIXELS:,} "
                         f"(4096 x 4096): render a smaller size, or zoom with window= and tile")
    return h, w


def _parse_window(window):
    try:
        x0, y0, x1, y1 = (float(v) for v in window)
    except (TypeError, ValueError):
        raise ValueError(f"window: {window!r} must be (x0, y0, x1, y1)") from None
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x0 == x1 or y0 == y1:
        raise ValueError(f"window: {window!r} must be finite with x0 != x1 and y0 != y1")
    return x0, y0, x1, y1


_POOL_PIXELS = 1 << 18  # pixels in all from which worker processes pay off (16 images at 128^2)
_WAVES_PIXELS = 64 * 64  # pixels per image up to which waves pay off on the CPU

# Milliseconds per node at 256 x 256 on one CPU core, measured over random genomes; only used
# to share a population fairly between worker processes (unlisted primitives: about 0.05).
# Sampling terminals cost about 3x more on warped coordinates (full images, not rows).
_COST = {"turbulence": 1.3, "band-pass": 1.1, "color-noise": 1.0, "dissolve": 0.6, "pixmap": 0.55,
         "blur": 0.5, "hsv-to-rgb": 0.4, "swirl": 0.4, "bw-noise": 0.4, "mod": 0.37, "bump": 0.35,
         "xor": 0.35, "and": 0.3, "or": 0.3, "warp-swirl": 0.25, "grad-mag": 0.24, "expt": 0.23,
         "grad-dir": 0.23, "gradient": 0.15, "divide": 0.15, "sin": 0.12, "rotate": 0.12,
         "angle": 0.11, "radius": 0.1, "warp-by": 0.09, "log": 0.09, "cos": 0.08, "atan": 0.08}
_SAMPLING = {"turbulence", "color-noise", "bw-noise", "pixmap", "dissolve"}
_WARPS = {"swirl", "rotate", "warp-swirl", "warp-by"}  # their first argument sees new coordinates


def _cost(node: Node, warped: bool = False) -> float:
    """Estimated evaluation time of a decoded tree (relative units, see :data:`_COST`);
    measured: correlation 0.89 with the times of 20 random genomes (tree size alone: 0.04)."""
    c = _COST.get(node.symbol, 0.05) * (3.0 if warped and node.symbol in _SAMPLING else 1.0)
    return c + sum(_cost(ch, warped or (k == 0 and node.symbol in _WARPS)) for k, ch in enumerate(node.children))


def render(genomes, size=(128, 128), *, window=(0.0, 0.0, 1.0, 1.0), time: float = 0.0,
           device=None, batch: bool = False, workers: int | None = None, group: bool | None = None,
           as_tensor: bool = False):
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
            per core, ``1`` renders in this process.
        group: evaluate the population in waves, one operation per primitive for all genomes
            (:mod:`.grouped`: about 5x fewer tensor operations for 256 random genomes, so
            fewer kernel launches on a GPU). Default: on a GPU, and on the CPU for images of at
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
    genomes = list(genomes)
    for i, g in enumerate(genomes):
        if not isinstance(g, Genome):
            raise TypeError(f"genomes[{i}]: expected a Genome, got {type(g).__name__}")
    H, W = _parse_size(size)
    window = _parse_window(window)
    if not math.isfinite(float(time)):
        raise ValueError(f"time: {time!r} must be finite")
    if workers is None:
        workers = os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ValueError(f"workers: {workers!r} must be a positive integer or None")
    if group is not None and not isinstance(group, (bool, np.bool_)):
        raise ValueError(f"group: {group!r} must be True, False or None")
    device = torch.device(device) if device is not None else default_device()
    group = (device.type != "cpu" or H * W <= _WAVES_PIXELS) if group is None else bool(group)
    with _no_gc():
        trees = [g.decode() for g in genomes]
        groups = _groups(trees, batch)
        if device.type == "cpu" and workers > 1 and len(groups) > 1 and len(genomes) * H * W >= _POOL_PIXELS:
            from .workers import render_parts

            pics = render_parts([(idx, [genomes[i] for i in idx]) for idx in groups],
                                [_cost(trees[idx[0]]) * len(idx) for idx in groups], (H, W),
                                {"window": window, "time": float(time), "group": group}, int(workers))
            if pics is not None:
                return torch.from_numpy(pics) if as_tensor else pics
        out = torch.empty(len(genomes), H, W, 3, dtype=torch.float32, device=device)
        _render_into(out, trees, groups, window, float(time), device, group)
    return out if as_tensor else out.cpu().numpy()


@contextlib.contextmanager
def _no_gc():
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


def _groups(trees: list[Node], batch: bool) -> list[list[int]]:
    """Indices of same-shaped trees (one batch each), or one index per group without ``batch``."""
    groups: dict = {}
    for i, t in enumerate(trees):
        groups.setdefault(t.structure() if batch else i, []).append(i)
    return list(groups.values())


_blas = None


def _one_blas_thread():
    """Context: numpy's BLAS (and any other) limited to one thread (threadpoolctl)."""
    global _blas
    if _blas is None:
        from threadpoolctl import ThreadpoolController

        _blas = ThreadpoolController()
    return _blas.limit(limits=1, user_api="blas")


def _render_into(out: torch.Tensor, trees, groups: list[list[int]], window, time: float, device,
                 group: bool = False) -> None:
    """Evaluate decoded ``trees`` in this process into ``out`` (N, H, W, 3): ``trees[i]`` goes
    to ``out[i]``; ``groups`` lists the indices of same-shaped trees, evaluated as one batch
    (with ``group``, all batches together in waves: :mod:`.grouped`)."""
    H, W = out.shape[1:3]
    x0, y0, x1, y1 = window
    px, py = (x1 - x0) / W, (y1 - y0) / H
    xs = (x0 + (torch.arange(W, device=device, dtype=torch.float64) + 0.5) * px).float()
    ys = (y0 + (torch.arange(H, device=device, dtype=torch.float64) + 0.5) * py).float()
    ctx = _Ctx(xs.reshape(1, 1, 1, W), ys.reshape(1, 1, H, 1), H, W, abs(px), abs(py), time,
               _Resources.on(device), _Memo(), key=(H, W, x0, y0, x1, y1))
    # subtrees repeated anywhere in the population (children of one parent share most of
    # theirs) are built as one node and evaluated once per coordinate context
    shared: dict = {}
    batches = [_stack_trees([trees[i] for i in idx], device, shared) for idx in groups]
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
                from .grouped import evaluate_population

                values = evaluate_population(batches, ctx)
            else:
                values = (_eval(tree, ctx) for tree in batches)
            for idx, v in zip(groups, values):
                rgb = to_rgb(v, H, W)
                for k, i in enumerate(idx):  # copy_ into a view: ~5x faster than out[idx] = ...
                    out[i].copy_(rgb[k if rgb.shape[0] > 1 else 0].permute(1, 2, 0))
    finally:
        torch.set_num_threads(saved)


def render_chunk(out: torch.Tensor, units: list, window, time: float, group: bool) -> None:
    """What a worker process of :mod:`.workers` runs: ``units`` are ``(rows, genomes)`` pairs,
    each a batch (validated by :func:`render`) rendered on the CPU into ``out[rows]``."""
    with _no_gc():
        trees = {r: g.decode() for rows, genomes in units for r, g in zip(rows, genomes)}
        _render_into(out, trees, [rows for rows, _ in units], window, time, torch.device("cpu"), group)
