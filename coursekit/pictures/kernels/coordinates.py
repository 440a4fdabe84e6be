"""Terminals of constants and coordinates: ``const``, ``color``, ``x``, ``y``, ``radius``,
``angle``, ``ramp``, ``gradient``, ``time`` (paper section 3.2; ``p``: a list of ``(B, 1, 1, 1)``
parameter tensors)."""

from __future__ import annotations

import torch

from ..context import fmod, fold
from ..primitives import image_kernel
from .fast import TWO_PI, atan2, cos, sin, sqrt

__all__: list[str] = []  # reached through the registry

def _const(ctx, p):
    return p[0]


def _color(ctx, p):
    return torch.cat(p[:3], dim=1)


def _radius(ctx, p):
    return sqrt((ctx.x - 0.5) ** 2 + (ctx.y - 0.5) ** 2)


def _angle(ctx, p):
    return fmod(atan2(ctx.y - 0.5, ctx.x - 0.5) / TWO_PI, 1.0)


def _along(ctx, turns):
    a = TWO_PI * turns
    return ctx.x * cos(a) + ctx.y * sin(a)


def _ramp(ctx, p):
    v = p[1] * _along(ctx, p[0])
    return v - torch.floor(v)


def _gradient(ctx, p):
    t = fold(_along(ctx, p[6]))
    c0, c1 = torch.cat(p[0:3], dim=1), torch.cat(p[3:6], dim=1)
    return c0 + (c1 - c0) * t


def _time(ctx, p):
    return torch.full((1, 1, 1, 1), float(ctx.time), device=ctx.x.device)


for _name, _fn in {"const": _const, "color": _color, "x": lambda ctx, p: ctx.x, "y": lambda ctx, p: ctx.y,
                   "radius": _radius, "angle": _angle, "ramp": _ramp, "gradient": _gradient, "time": _time}.items():
    image_kernel(_name)(_fn)
