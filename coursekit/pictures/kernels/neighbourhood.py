"""Neighbourhood operations on the pixel grid: ``blur``, ``band-pass``, ``bump``, ``grad-mag``,
``grad-dir`` (paper section 3.2), sizes in world units. Each gets its argument on the context
extended by its reach (:data:`~..primitives.REACHES`, bound in :mod:`..textures`), so the
replicated borders of the extended grid never reach the window's pixels. Blurs multiply by
banded matrices cut into row tiles (:meth:`~coursekit.pictures.context.Resources.box_matrix`),
touching only the band; large images use cumulative sums."""

from __future__ import annotations

import math

import numpy as np
import torch

from .. import textures as T
from ..context import fmod, host, sane
from ..primitives import FLAT_GRADIENT, image_kernel
from .fast import TWO_PI, atan2, cos, grey, matmul, sin, sqrt

__all__: list[str] = []  # reached through the registry

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


def _blur_by(v, sigmas: list, ctx):
    """Three box passes per axis; radius per batch element from ``sigmas`` (world units; host
    numbers, :func:`~..context.host`)."""
    if v.shape[-1] == 1 and v.shape[-2] == 1:
        return v
    B = max(len(sigmas), v.shape[0])  # a uniform blur may see per-genome inputs
    H, W = ctx.picture
    v = v.expand(B, *v.shape[1:])
    outs = []
    for b in range(B):
        s = sigmas[b if len(sigmas) > 1 else 0]
        rx = T.box_radius(abs(s) / ctx.px, 4 * W)  # the picture's size, not the extension's
        ry = T.box_radius(abs(s) / ctx.py, 4 * H)
        o = v[b:b + 1]
        if max(ctx.H, ctx.W) <= 1024:  # one banded matrix per axis (fast for small images)
            if rx and o.shape[3] > 1:
                parts = [matmul(o[..., lo:hi], m.T) for lo, hi, m in ctx.res.box_matrix(ctx.W, rx)]
                o = parts[0] if len(parts) == 1 else torch.cat(parts, dim=3)
            if ry and o.shape[2] > 1:
                parts = [matmul(m, o[..., lo:hi, :]) for lo, hi, m in ctx.res.box_matrix(ctx.H, ry)]
                o = parts[0] if len(parts) == 1 else torch.cat(parts, dim=2)
        else:  # large images: cumulative sums, cost independent of the radius
            for _ in range(3):
                o = _box(_box(o, rx, 3), ry, 2)
        outs.append(o)
    return torch.cat(outs, dim=0)


def _diff(v, dim, step):
    """Derivative along ``dim`` per world unit: central differences, one-sided on the first and
    last pixel (the picture beyond them extrapolated linearly)."""
    n = v.shape[dim]
    if n == 1:
        return torch.zeros_like(v)
    pad = (1, 1, 0, 0) if dim == 3 else (0, 0, 1, 1)
    p = torch.nn.functional.pad(v, pad, mode="replicate")
    # extrapolated neighbours: 2 v[0] - v[1] before the first pixel, 2 v[-1] - v[-2] after the last
    p.narrow(dim, 0, 1).mul_(2.0).sub_(v.narrow(dim, 1, 1))
    p.narrow(dim, n + 1, 1).mul_(2.0).sub_(v.narrow(dim, n - 2, 1))
    return (p.narrow(dim, 2, n) - p.narrow(dim, 0, n)).div_(2.0 * step)


def _gradients(v, ctx):
    g = sane(grey(v))
    return _diff(g, 3, ctx.px), _diff(g, 2, ctx.py)


def _bump(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    a = TWO_PI * p[0]
    nx, ny = -gx * p[1], -gy * p[1]
    dot = (nx * cos(a) + ny * sin(a) + 1.0) / math.sqrt(2.0)
    return (dot / sqrt(nx * nx + ny * ny + 1.0)).clamp(min=0.0)


def _grad_mag(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    return p[0] * sqrt(gx * gx + gy * gy)


def _grad_dir(v, p, ctx):
    gx, gy = _gradients(v, ctx)
    flat = torch.maximum(gx.abs(), gy.abs()) < FLAT_GRADIENT  # only rounding error: no direction
    return fmod(atan2(gy, gx) / TWO_PI, 1.0).masked_fill(flat, 0.0)


def _blur(ctx, p, a):
    return _blur_by(a, host(p[0]), ctx)


def _band_pass(ctx, p, a):
    sig = host(p[0])
    with np.errstate(over="ignore"):  # a hostile sigma overflows to inf, as on the device
        wide = (np.float32(3.0) * np.asarray(sig, dtype=np.float32)).tolist()  # as the device rounds 3 sigma
    return 0.5 + _blur_by(a, sig, ctx) - _blur_by(a, wide, ctx)


image_kernel("blur")(_blur)
image_kernel("band-pass")(_band_pass)
for _name, _fn in {"bump": _bump, "grad-mag": _grad_mag, "grad-dir": _grad_dir}.items():
    image_kernel(_name)(lambda ctx, p, a, _fn=_fn: _fn(a, p, ctx))
