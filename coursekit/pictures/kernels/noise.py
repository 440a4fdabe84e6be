"""Value noise on whole images: ``bw-noise``, ``color-noise`` and ``turbulence`` (paper section 3.2).

On :func:`~coursekit.pictures.context.separable` coordinates noise interpolates lattice rows,
then columns (small matrices for a few lattice cells, gathers for many); warped coordinates use
``grid_sample`` on the padded lattice.
"""

from __future__ import annotations

import math

import torch

from .. import textures as T
from ..context import Context, fmod, host, sane, separable, upload
from ..primitives import image_kernel

__all__: list[str] = []  # reached through the registry

def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


#: The spans read and the images picked on the CPU only (bound here, so that
#: :class:`~coursekit.operations.CountHostSyncs` leaves this CPU-only path out, as for numpy's kernels).
_tolist, _tensor = torch.Tensor.tolist, torch.tensor

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
    image rendered alone (products of other widths round differently). On a GPU every image
    gathers: the span is data on the device, and reading it would make the host wait.
    """
    fu, fv = torch.floor(uu), torch.floor(vv)
    lx, ly = fu.amin(1, keepdim=True), fv.amin(1, keepdim=True)
    if uu.device.type == "cpu":
        span = torch.maximum(fu.amax(1) - lx[:, 0], fv.amax(1) - ly[:, 0]) + 2.0
        widths = [next((k for k in _WIDTHS if k >= s), 0) for s in _tolist(span)]
    else:
        widths = [0]
    if len(set(widths)) > 1:
        out = torch.empty(uu.shape[0], 1, vv.shape[1], uu.shape[1], dtype=uu.dtype, device=uu.device)
        for k in set(widths):
            sel = _tensor([b for b, w in enumerate(widths) if w == k])
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
    k = upload([[s, dx, dy] for s, (dx, dy) in zip(scales, shifts)], ctx.x.device).reshape(O, 3, 1, 1, 1, 1)
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
    count = int(min(max(math.floor(max(host(p[1]))), 1), 8))
    shifts = [(o * T.OCTAVE_SHIFT[0], o * T.OCTAVE_SHIFT[1]) for o in range(count)]
    n = _stacked_noise(ctx, p[0], p[2], p[3], [2.0 ** o for o in range(count)], shifts)
    n = n.mul_(2.0).sub_(1.0).abs_()
    weight = torch.stack([(octaves > o).to(p[0].dtype) * 0.5 ** o for o in range(count)])  # (O, B, 1, 1, 1)
    return (weight * n).sum(dim=0) / weight.sum(dim=0)


image_kernel("bw-noise")(_bw_noise)
image_kernel("color-noise")(_color_noise)
image_kernel("turbulence")(_turbulence)
