"""Coordinate transforms: ``swirl``, ``rotate``, ``warp-swirl``, ``warp-by`` (paper section 3.2).
Each returns the context in which its first argument is evaluated (new coordinates, the same
image and time)."""

from __future__ import annotations

from ..primitives import image_kernel
from .fast import TWO_PI, cos, exp, grey, sin, sqrt

__all__: list[str] = []  # reached through the registry

def _turn(ctx, angle):
    dx, dy = ctx.x - 0.5, ctx.y - 0.5
    c, s = cos(angle), sin(angle)
    return ctx.with_coords(0.5 + dx * c - dy * s, 0.5 + dx * s + dy * c)


def _swirl_ctx(ctx, p):
    r = sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)
    return _turn(ctx, p[0] * exp(-r / p[1].clamp(min=1e-3)))


def _rotate_ctx(ctx, p):
    return _turn(ctx, TWO_PI * p[0])


def _warp_swirl_ctx(ctx, p, b):
    return _turn(ctx, p[0] * grey(b))


def _warp_by_ctx(ctx, p, b):
    d0, d1 = (b[:, 0:1], b[:, 1:2]) if b.shape[1] == 3 else (b, b)  # the first two channels
    return ctx.with_coords(ctx.x + p[0] * (d0 - 0.5), ctx.y + p[0] * (d1 - 0.5))


image_kernel("swirl")(_swirl_ctx)
image_kernel("rotate")(_rotate_ctx)
image_kernel("warp-swirl")(_warp_swirl_ctx)
image_kernel("warp-by")(_warp_by_ctx)
