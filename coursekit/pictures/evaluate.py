"""Tensorised evaluation of genetic pictures (paper section 3.2, phenotype).

The paper formulates "all imaging operations as functions over the whole image" instead of
Sims' per-pixel evaluation. Here every primitive is a torch operation on whole images, and
genomes whose expression trees have the same shape are stacked and evaluated as one batch.

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
"""

from __future__ import annotations

import dataclasses
import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np
import torch

from . import textures as T
from .genome import Genome, Node

__all__ = ["render", "to_rgb", "default_device"]

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
    res: "_Resources"
    memo: dict = field(default_factory=dict)  # shared subtree values, shared by derived contexts

    def with_coords(self, x, y) -> "_Ctx":
        return _Ctx(_sane(x), _sane(y), self.H, self.W, self.px, self.py, self.time, self.res, self.memo)


class _Resources:
    """Noise lattice and pixel maps on one device (cached)."""

    _cache: dict = {}

    def __init__(self, device):
        self.device = device
        self.table = torch.from_numpy(T.noise_table()).to(device)
        self.flat = self.table.reshape(-1)
        wrapped = torch.cat([self.table, self.table[:1]], dim=0)
        self.wrapped = torch.cat([wrapped, wrapped[:, :1]], dim=1)[None, None].contiguous()
        self.box_matrices: dict = {}
        self.pixmaps: dict[int, torch.Tensor] = {}

    @classmethod
    def on(cls, device) -> "_Resources":
        key = str(device)
        if key not in cls._cache:
            cls._cache[key] = cls(device)
        return cls._cache[key]

    def box_matrix(self, n: int, r: int) -> torch.Tensor:
        """(n, n) matrix of three replicate-border box passes of radius r."""
        key = (n, r)
        if key not in self.box_matrices:
            b = torch.zeros(n, n, dtype=torch.float64)
            rows = torch.arange(n).repeat_interleave(2 * r + 1)
            cols = (torch.arange(n)[:, None] + torch.arange(-r, r + 1)[None, :]).clamp(0, n - 1).reshape(-1)
            b.index_put_((rows, cols), torch.full_like(rows, 1.0 / (2 * r + 1), dtype=torch.float64),
                         accumulate=True)
            self.box_matrices[key] = (b @ b @ b).float().to(self.device)
        return self.box_matrices[key]

    def pixmap(self, i: int) -> torch.Tensor:
        if i not in self.pixmaps:
            self.pixmaps[i] = torch.from_numpy(T.pixmap(i)).permute(2, 0, 1)[None].to(self.device)
        return self.pixmaps[i]


def _sane(v: torch.Tensor) -> torch.Tensor:
    """NaN -> 0 and clip to +-1e6 (inputs of indexing and integer operations)."""
    return torch.nan_to_num(v, nan=0.0, posinf=_BIG, neginf=-_BIG).clamp_(-_BIG, _BIG)


def _fmod(v: torch.Tensor, m) -> torch.Tensor:
    """Floored modulo v - m floor(v / m) (sign of m, like Python's %), cheaper than remainder."""
    return v - m * torch.floor(v / m)


def fold(v: torch.Tensor) -> torch.Tensor:
    """Mirror-repeat into [0, 1] with period 2: 1 - |(v mod 2) - 1|."""
    return 1.0 - torch.abs(_fmod(v, 2.0) - 1.0)


def to_rgb(v: torch.Tensor, H: int, W: int) -> torch.Tensor:
    """The documented final mapping: any value -> (B, 3, H, W) float32 in [0, 1]."""
    v = fold(_sane(v.float()))
    return v.expand(v.shape[0], 3, H, W)


def _grey(v):
    return v if v.shape[1] == 1 else v.mean(dim=1, keepdim=True)


def _full(v, ctx):
    return v.expand(v.shape[0], v.shape[1], ctx.H, ctx.W)


# ---- noise --------------------------------------------------------------------------------

def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


def _axis_weights(u: torch.Tensor, limit: int):
    """Interpolation matrix (B, n, k) for lattice coordinates u (B, n) and its first index."""
    i0 = torch.floor(u)
    s = _smooth(u - i0)
    i0 = i0.long()
    lo = i0.min(dim=1, keepdim=True).values
    k = int((i0 - lo).max()) + 2
    if k > limit:
        return None, None, k
    w = torch.zeros(u.shape[0], u.shape[1], k, dtype=u.dtype, device=u.device)
    rel = (i0 - lo).unsqueeze(-1)
    w.scatter_(2, rel, (1.0 - s).unsqueeze(-1))
    w.scatter_add_(2, rel + 1, s.unsqueeze(-1))
    return w, lo, k


def _noise(ctx: _Ctx, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Value noise at lattice coordinates u (columns) and v (rows); returns (B, 1, Hs, Ws)."""
    u, v = _sane(u), _sane(v)
    res = ctx.res
    B = max(u.shape[0], v.shape[0])
    if u.shape[-2] == 1 and v.shape[-1] == 1 and u.shape[-1] == ctx.W and v.shape[-2] == ctx.H:
        # separable: noise = Wy @ table_block @ Wx^T with small interpolation matrices
        uu = u.reshape(u.shape[0], ctx.W).expand(B, ctx.W)
        vv = v.reshape(v.shape[0], ctx.H).expand(B, ctx.H)
        wx, lx, kx = _axis_weights(uu, 96)
        wy, ly, ky = _axis_weights(vv, 96)
        if wx is not None and wy is not None:
            cols = torch.remainder(lx + torch.arange(kx, device=u.device), T.LATTICE)  # (B, kx)
            rows = torch.remainder(ly + torch.arange(ky, device=u.device), T.LATTICE)  # (B, ky)
            block = res.table[rows.unsqueeze(-1), cols.unsqueeze(1)]  # (B, ky, kx)
            out = torch.bmm(torch.bmm(wy, block), wx.transpose(1, 2))
            return out.unsqueeze(1)
    # general coordinates: bilinear lookup at i0 + smooth(frac) is exactly the smoothstep
    # interpolation; the table is padded with its first row and column to wrap around
    u, v = torch.broadcast_tensors(u, v)
    i0, j0 = torch.floor(u), torch.floor(v)
    pu = _fmod(i0, float(T.LATTICE)) + _smooth(u - i0)
    pv = _fmod(j0, float(T.LATTICE)) + _smooth(v - j0)
    half = T.LATTICE / 2.0
    grid = torch.stack([pu[:, 0] / half - 1.0, pv[:, 0] / half - 1.0], dim=-1)
    return torch.nn.functional.grid_sample(res.wrapped.expand(grid.shape[0], -1, -1, -1), grid,
                                           mode="bilinear", align_corners=True)


# ---- terminals (p: list of (B, 1, 1, 1) parameter tensors) ---------------------------------

def _const(ctx, p):
    return p[0]


def _color(ctx, p):
    return torch.cat(p[:3], dim=1)


def _radius(ctx, p):
    return torch.sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)


def _angle(ctx, p):
    return _fmod(torch.atan2(ctx.y - 0.5, ctx.x - 0.5) / TWO_PI, 1.0)


def _along(ctx, turns):
    a = TWO_PI * turns
    return ctx.x * torch.cos(a) + ctx.y * torch.sin(a)


def _ramp(ctx, p):
    v = p[1] * _along(ctx, p[0])
    return v - torch.floor(v)


def _gradient(ctx, p):
    t = fold(_along(ctx, p[6]))
    c0, c1 = torch.cat(p[0:3], dim=1), torch.cat(p[3:6], dim=1)
    return c0 + (c1 - c0) * t


def _bw_noise(ctx, p):
    return _noise(ctx, ctx.x * p[0] + p[1], ctx.y * p[0] + p[2])


def _stacked_noise(ctx, freqs, shifts, ox, oy):
    """Noise for several (frequency, shift) pairs in one call, stacked along a new dim 0."""
    us = torch.cat([(ctx.x * f + ox + sx).expand(ox.shape[0], -1, -1, -1) for f, (sx, _) in zip(freqs, shifts)])
    vs = torch.cat([(ctx.y * f + oy + sy).expand(oy.shape[0], -1, -1, -1) for f, (_, sy) in zip(freqs, shifts)])
    n = _noise(ctx, us, vs)
    return n.reshape(len(freqs), -1, *n.shape[1:])


def _color_noise(ctx, p):
    n = _stacked_noise(ctx, [p[0]] * 3, T.CHANNEL_SHIFT, p[1], p[2])  # (3, B, 1, Hs, Ws)
    return n[:, :, 0].transpose(0, 1)


def _turbulence(ctx, p):
    octaves = torch.floor(p[1]).clamp(1, 8)
    count = int(octaves.max())
    shifts = [(o * T.OCTAVE_SHIFT[0], o * T.OCTAVE_SHIFT[1]) for o in range(count)]
    n = _stacked_noise(ctx, [p[0] * 2.0 ** o for o in range(count)], shifts, p[2], p[3])
    weight = torch.stack([(octaves > o).to(p[0].dtype) * 0.5 ** o for o in range(count)])  # (O, B, 1, 1, 1)
    return (weight * torch.abs(2.0 * n - 1.0)).sum(dim=0) / weight.sum(dim=0)


def _pixmap(ctx, p):
    x, y = torch.broadcast_tensors(fold(ctx.x), fold(ctx.y))
    B = p[0].shape[0]
    grid = torch.stack([2.0 * x[:, 0] - 1.0, 2.0 * y[:, 0] - 1.0], dim=-1).expand(B, ctx.H, ctx.W, 2)
    idx = [T.pixmap_index(float(v)) for v in p[0].reshape(-1)]
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

def _hsv_to_rgb(a):
    if a.shape[1] == 1:
        h, s, v = a, torch.ones_like(a), torch.ones_like(a)
    else:
        h, s, v = a[:, 0:1], a[:, 1:2].clamp(0, 1), a[:, 2:3].clamp(0, 1)
    h = _fmod(_sane(h), 1.0)
    out = []
    for n in (5.0, 3.0, 1.0):
        k = _fmod(n + 6.0 * h, 6.0)
        out.append(v - v * s * torch.minimum(k, 4.0 - k).clamp(0.0, 1.0))
    return torch.cat(out, dim=1)


def _safe_div(a, b):
    small = b.abs() < 1e-3
    return a / torch.where(small, torch.where(b < 0, -1e-3, 1e-3), b)


def _mod(a, b):
    small = b.abs() < 1e-3
    return torch.where(small, a, _fmod(a, torch.where(small, 1.0, b)))


def _quant(v):
    return torch.floor(fold(_sane(v)) * 255.999).to(torch.int32)


def _bits(op):
    def f(a, b):
        a, b = torch.broadcast_tensors(a, b)
        return op(_quant(a), _quant(b)).to(torch.float32) / 255.0
    return f


_POINTWISE1 = {
    "abs": torch.abs,
    "sin": lambda a: 0.5 + 0.5 * torch.sin(TWO_PI * a),
    "cos": lambda a: 0.5 + 0.5 * torch.cos(TWO_PI * a),
    "log": lambda a: torch.log(a.abs() + 1e-6),
    "atan": lambda a: torch.atan(a) / math.pi + 0.5,
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
    "expt": lambda a, b: torch.exp((b * torch.log(a.abs() + 1e-6)).clamp(-30.0, 30.0)),
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
    B = sigma.shape[0]
    v = v.expand(B, *v.shape[1:])
    outs = []
    for b in range(B):
        s = float(sigma[b])
        rx = T.box_radius(abs(s) / ctx.px, 4 * ctx.W)
        ry = T.box_radius(abs(s) / ctx.py, 4 * ctx.H)
        o = v[b:b + 1]
        if max(ctx.H, ctx.W) <= 1024:  # one banded matrix per axis (fast for small images)
            if rx and o.shape[3] > 1:
                o = o @ ctx.res.box_matrix(ctx.W, rx).T
            if ry and o.shape[2] > 1:
                o = ctx.res.box_matrix(ctx.H, ry) @ o
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
    out = torch.empty_like(v)
    if n > 2:
        out.narrow(dim, 1, n - 2).copy_(v.narrow(dim, 2, n - 2) - v.narrow(dim, 0, n - 2))
    out.narrow(dim, 0, 1).copy_(v.narrow(dim, 1, 1) - v.narrow(dim, 0, 1))
    out.narrow(dim, n - 1, 1).copy_(v.narrow(dim, n - 1, 1) - v.narrow(dim, n - 2, 1))
    return out / (2.0 * step)


def _gradients(v, ctx):
    g = _sane(_grey(v))
    return _diff(g, 3, ctx.px), _diff(g, 2, ctx.py)


def _bump(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    a = TWO_PI * p[0]
    nx, ny = -gx * p[1], -gy * p[1]
    dot = (nx * torch.cos(a) + ny * torch.sin(a) + 1.0) / math.sqrt(2.0)
    return (dot / torch.sqrt(nx * nx + ny * ny + 1.0)).clamp(min=0.0)


def _grad_mag(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    return p[0] * torch.sqrt(gx * gx + gy * gy)


def _grad_dir(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    return _fmod(torch.atan2(gy, gx) / TWO_PI, 1.0)


# ---- coordinate transforms ------------------------------------------------------------------

def _turn(ctx, angle):
    dx, dy = ctx.x - 0.5, ctx.y - 0.5
    c, s = torch.cos(angle), torch.sin(angle)
    return ctx.with_coords(0.5 + dx * c - dy * s, 0.5 + dx * s + dy * c)


def _swirl_ctx(ctx, p):
    r = torch.sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)
    return _turn(ctx, p[0] * torch.exp(-r / p[1].clamp(min=1e-3)))


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

    Identical subtrees (same symbols and parameters, e.g. clones made by transposition) are
    one shared node, evaluated once per coordinate context (``uses`` counts its parents).
    """

    symbol: str
    params: list  # of (B, 1, 1, 1) tensors
    children: list
    uses: int = 1


def _stack_trees(trees: Sequence[Node], device, shared: dict | None = None) -> _BNode:
    shared = {} if shared is None else shared
    first = trees[0]
    kids = [_stack_trees([t.children[i] for t in trees], device, shared) for i in range(len(first.children))]
    key = (first.symbol, tuple(t.params for t in trees), tuple(id(k) for k in kids))
    if key in shared:
        shared[key].uses += 1
        return shared[key]
    if first.params:
        arr = torch.tensor([t.params for t in trees], dtype=torch.float32, device=device)
        params = [arr[:, i].reshape(-1, 1, 1, 1) for i in range(arr.shape[1])]
    else:
        params = []
    node = shared[key] = _BNode(first.symbol, params, kids)
    return node


def _eval(n: _BNode, ctx: _Ctx) -> torch.Tensor:
    if n.uses == 1:
        return _eval_node(n, ctx)
    key = (id(n), id(ctx))
    if key not in ctx.memo:
        ctx.memo[key] = (_eval_node(n, ctx), ctx)  # keep ctx alive so its id is not reused
    return ctx.memo[key][0]


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
    if s == "swirl":
        return _eval(n.children[0], _swirl_ctx(ctx, p))
    if s == "rotate":
        return _eval(n.children[0], _turn(ctx, TWO_PI * p[0]))
    if s == "warp-swirl":
        b = _grey(_eval(n.children[1], ctx))
        return _eval(n.children[0], _turn(ctx, p[0] * b))
    if s == "warp-by":
        b = _eval(n.children[1], ctx)
        d0, d1 = (b[:, 0:1], b[:, 1:2]) if b.shape[1] == 3 else (b, b)
        return _eval(n.children[0], ctx.with_coords(ctx.x + p[0] * (d0 - 0.5), ctx.y + p[0] * (d1 - 0.5)))
    if s == "dissolve":
        a, b = _eval(n.children[0], ctx), _eval(n.children[1], ctx)
        x, y = torch.broadcast_tensors(ctx.x, ctx.y)
        ci = torch.remainder(torch.floor(_sane(x * T.DISSOLVE_CELLS + p[2])).long(), T.LATTICE)
        cj = torch.remainder(torch.floor(_sane(y * T.DISSOLVE_CELLS + p[3])).long(), T.LATTICE)
        cell = ctx.res.flat[cj * T.LATTICE + ci]
        amount = _fmod(p[0] + p[1] * ctx.time, 1.0)
        return torch.where(cell < amount, b, a)
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
    return h, w


def _parse_window(window):
    try:
        x0, y0, x1, y1 = (float(v) for v in window)
    except (TypeError, ValueError):
        raise ValueError(f"window: {window!r} must be (x0, y0, x1, y1)") from None
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x0 == x1 or y0 == y1:
        raise ValueError(f"window: {window!r} must be finite with x0 != x1 and y0 != y1")
    return x0, y0, x1, y1


def render(genomes, size=(128, 128), *, window=(0.0, 0.0, 1.0, 1.0), time: float = 0.0,
           device=None, batch: bool = True, workers: int | None = None, as_tensor: bool = False):
    """Render genomes as whole images.

    Args:
        genomes: a :class:`Genome` or a sequence of them.
        size: ``(height, width)`` in pixels, or one int for a square.
        window: world rectangle ``(x0, y0, x1, y1)``; zoom and pan re-evaluate.
        time: the animation time (read by ``time`` and ``dissolve``).
        device: torch device (default: CUDA when present, else CPU).
        batch: stack genomes whose trees have the same shape into one evaluation.
        workers: CPU threads evaluating genomes in parallel (default: one per core); each
            runs single-threaded torch operations.
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
    x0, y0, x1, y1 = _parse_window(window)
    if not math.isfinite(float(time)):
        raise ValueError(f"time: {time!r} must be finite")
    device = torch.device(device) if device is not None else default_device()
    res = _Resources.on(device)
    px, py = (x1 - x0) / W, (y1 - y0) / H
    xs = (x0 + (torch.arange(W, device=device, dtype=torch.float64) + 0.5) * px).float()
    ys = (y0 + (torch.arange(H, device=device, dtype=torch.float64) + 0.5) * py).float()
    ctx = _Ctx(xs.reshape(1, 1, 1, W), ys.reshape(1, 1, H, 1), H, W, abs(px), abs(py), float(time), res)
    out = torch.empty(len(genomes), H, W, 3, dtype=torch.float32, device=device)
    trees = [g.decode() for g in genomes]
    groups: dict = {}
    for i, t in enumerate(trees):
        groups.setdefault(t.structure() if batch else i, []).append(i)

    def run(idx):
        with torch.inference_mode():
            tree = _stack_trees([trees[i] for i in idx], device)
            v = _eval(tree, dataclasses.replace(ctx, memo={}))  # a fresh memo per group
            rgb = to_rgb(v, H, W)
            for k, i in enumerate(idx):  # copy_ into a view: ~5x faster than out[idx] = ...
                out[i].copy_(rgb[k if rgb.shape[0] > 1 else 0].permute(1, 2, 0))

    jobs = list(groups.values())
    if device.type != "cpu" or (len(jobs) == 1 and H * W > 512 * 512):
        # GPU, or one big image (a file export): torch's own intra-op threads
        for idx in jobs:
            run(idx)
    else:
        # Small images: one thread per core, each running whole genomes with single-threaded
        # torch ops. Intra-op threading on small images thrashes (measured 10-30x slower on
        # a loaded 2-core machine); genome-level parallelism does not.
        workers = int(workers or os.cpu_count() or 1)
        saved = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            if workers > 1 and len(jobs) > 1:
                with ThreadPoolExecutor(workers) as pool:
                    list(pool.map(run, jobs))
            else:
                for idx in jobs:
                    run(idx)
        finally:
            torch.set_num_threads(saved)
    return out if as_tensor else out.cpu().numpy()
