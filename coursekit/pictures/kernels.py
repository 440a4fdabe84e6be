"""Whole-image kernels of the picture primitives (paper section 3.2): noise, pixel maps, blurs,
pointwise functions and coordinate transforms, each bound to its primitive in the registry
(:func:`.primitives.image_kernel`; the forms and signatures are in :mod:`.primitives`).

**Types (section 3.2).** A value is a tensor ``(B, C, Hs, Ws)``: ``C`` is 1 (grey) or 3
(RGB) and ``Hs, Ws`` are 1 or the image size. A *scalar* is ``(B, 1, 1, 1)``, a *vector*
(colour) ``(B, 3, 1, 1)``, a *matrix* (pixel map) has ``Hs = H`` or ``Ws = W``. A function of
mixed inputs returns the most complex type of its inputs, which is exactly what broadcasting
gives: scalar + vector = vector, vector * matrix = colour matrix. ``x`` is ``(1, 1, 1, W)``
and ``y`` is ``(1, 1, H, 1)``, so a chain of pointwise operations on ``x`` alone costs ``W``
evaluations, not ``H W``.

**Coordinates.** Coordinate transforms (``swirl``, ``rotate``, ``warp-swirl``, ``warp-by``)
return the context in which their first argument is evaluated; neighbourhood operations
(``blur``, ``band-pass``, ``bump``, ``grad-mag``, ``grad-dir``) act on the pixel grid with
replicated borders and sizes in world units.

**Speed.** Most of the time goes to a few primitives on whole images, so each picks the
cheapest exact method for the coordinates it gets. On :func:`.context.separable` coordinates
noise interpolates lattice rows, then columns (small matrices for a few lattice cells, gathers
for many), pixel maps are sampled rows-then-columns and kept per (size, window) across renders
(a gallery renders every generation at one size), and dissolve looks its cells up per row and
column. Warped coordinates fall back to ``grid_sample``. Blurs multiply by banded matrices cut
into row tiles, touching only the band. Node values are never modified in place (cached
pictures and shared subtrees are handed to several parents); only fresh intermediates are. On
the CPU, transcendental functions and the blurs' matrix products go through numpy (faster there
than torch's: :func:`_ufunc`).

**Batch invariance.** Every kernel computes each image of a batch as it would compute it
alone, bit for bit, so a picture never depends on what it was rendered with (batched, in waves,
in a worker): no reduction over a batch picks a method or a size, and no library kernel whose
rounding depends on an element's position in the tensor is used (torch's CPU ``atan2`` is one,
measured).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from . import textures as T
from .context import Context, fmod, fold, sane, separable
from .primitives import image_kernel

__all__: list[str] = []  # everything here is reached through the registry

TWO_PI = 2.0 * math.pi


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


# ---- noise --------------------------------------------------------------------------------

def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


_WIDTHS = (8, 16, 32, 48)  # interpolation matrix widths (lattice cells + 1); gathers beyond


def _cell(u: torch.Tensor):
    """Lattice cell index (wrapped into [0, L)) and smoothed fraction of coordinates u."""
    i0 = torch.floor(u)
    return fmod(i0, float(T.LATTICE)).long(), _smooth(u - i0)


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


def _noise(ctx: Context, u: torch.Tensor, v: torch.Tensor) -> torch.Tensor:
    """Value noise at lattice coordinates u (columns) and v (rows); returns (B, 1, Hs, Ws).

    Separable coordinates (u varies along columns only, v along rows only, as in an
    unwarped context) interpolate rows first, then columns (:func:`_separable_noise`).
    """
    u, v = sane(u), sane(v)
    res = ctx.res
    if separable(u, v) and u.shape[-1] == ctx.W and v.shape[-2] == ctx.H:  # whole rows and columns
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
    return fmod(_atan2(ctx.y - 0.5, ctx.x - 0.5) / TWO_PI, 1.0)


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
    if not separable(ctx.x, ctx.y):
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
    if ctx.separable:
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
    h = fmod(sane(a[:, 0:1]), 1.0)
    n = _HSV_N.get(a.device)
    if n is None:
        n = _HSV_N[a.device] = torch.tensor([5.0, 3.0, 1.0], device=a.device).reshape(1, 3, 1, 1)
    k = fmod(n + 6.0 * h, 6.0)  # (B, 3, Hs, Ws): all three channels at once
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
    return torch.where(small, a, fmod(a, torch.where(small, 1.0, b)))


def _quant(v):
    """fold(v) in 256 levels (int32); ``sane`` gives a fresh tensor, folded in place."""
    v = sane(v)
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
    g = sane(_grey(v))
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
    return fmod(_atan2(gy, gx) / TWO_PI, 1.0)


# ---- coordinate transforms ------------------------------------------------------------------

def _turn(ctx, angle):
    dx, dy = ctx.x - 0.5, ctx.y - 0.5
    c, s = _cos(angle), _sin(angle)
    return ctx.with_coords(0.5 + dx * c - dy * s, 0.5 + dx * s + dy * c)


def _swirl_ctx(ctx, p):
    r = _sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)
    return _turn(ctx, p[0] * _exp(-r / p[1].clamp(min=1e-3)))


def _rotate_ctx(ctx, p):
    return _turn(ctx, TWO_PI * p[0])


def _warp_swirl_ctx(ctx, p, b):
    return _turn(ctx, p[0] * _grey(b))


def _warp_by_ctx(ctx, p, b):
    d0, d1 = (b[:, 0:1], b[:, 1:2]) if b.shape[1] == 3 else (b, b)  # the first two channels
    return ctx.with_coords(ctx.x + p[0] * (d0 - 0.5), ctx.y + p[0] * (d1 - 0.5))


_TERMINALS = {
    "const": _const, "color": _color, "x": lambda ctx, p: ctx.x, "y": lambda ctx, p: ctx.y,
    "radius": _radius, "angle": _angle, "ramp": _ramp, "gradient": _gradient,
    "bw-noise": _bw_noise, "color-noise": _color_noise, "turbulence": _turbulence,
    "pixmap": _pixmap, "time": _time,
}

_NEIGHBOURHOOD = {"bump": _bump, "grad-mag": _grad_mag, "grad-dir": _grad_dir}


# ---- the registry -------------------------------------------------------------------------

def _unary(fn):
    return lambda ctx, p, a: fn(a)


def _binary(fn):
    return lambda ctx, p, a, b: fn(a, b)


def _blur(ctx, p, a):
    return _blur_by(a, p[0][:, 0, 0, 0], ctx)


def _band_pass(ctx, p, a):
    sig = p[0][:, 0, 0, 0]
    return 0.5 + _blur_by(a, sig, ctx) - _blur_by(a, 3.0 * sig, ctx)


def _dissolve(ctx, p, a, b):
    # cell indices per column and per row (per pixel only in a warped context)
    ci = torch.remainder(torch.floor(sane(ctx.x * T.DISSOLVE_CELLS + p[2])).long(), T.LATTICE)
    cj = torch.remainder(torch.floor(sane(ctx.y * T.DISSOLVE_CELLS + p[3])).long(), T.LATTICE)
    cell = ctx.res.table[cj, ci]
    amount = fmod(p[0] + p[1] * ctx.time, 1.0)
    return _select(cell < amount, a, b)


for _name, _fn in _TERMINALS.items():
    image_kernel(_name)(_fn)
for _name, _fn in _POINTWISE1.items():
    image_kernel(_name)(_unary(_fn))
for _name, _fn in _POINTWISE2.items():
    image_kernel(_name)(_binary(_fn))
for _name, _fn in _NEIGHBOURHOOD.items():
    image_kernel(_name)(lambda ctx, p, a, _fn=_fn: _fn(a, p, ctx))
for _name, _fn in (("blur", _blur), ("band-pass", _band_pass), ("dissolve", _dissolve), ("swirl", _swirl_ctx),
                   ("rotate", _rotate_ctx), ("warp-swirl", _warp_swirl_ctx), ("warp-by", _warp_by_ctx)):
    image_kernel(_name)(_fn)
