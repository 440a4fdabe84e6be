"""Pointwise functions of one and two arguments, and ``dissolve`` (paper section 3.2): the value
at a pixel depends on the arguments at that pixel only, so arguments broadcast beforehand give
the same values."""

from __future__ import annotations

import math

import torch

from .. import textures as T
from ..context import fmod, sane
from ..primitives import image_kernel
from .fast import TWO_PI, atan, cos, exp, log, sin

__all__: list[str] = []  # reached through the registry

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
    "sin": lambda a: 0.5 + 0.5 * sin(TWO_PI * a),
    "cos": lambda a: 0.5 + 0.5 * cos(TWO_PI * a),
    "log": lambda a: log(a.abs() + 1e-6),
    "atan": lambda a: atan(a) / math.pi + 0.5,
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
    "expt": lambda a, b: exp((b * log(a.abs() + 1e-6)).clamp(-30.0, 30.0)),
    "min": torch.minimum,
    "max": torch.maximum,
    "and": _bits(torch.bitwise_and),
    "or": _bits(torch.bitwise_or),
    "xor": _bits(torch.bitwise_xor),
}


def _dissolve(ctx, p, a, b):
    # cell indices per column and per row (per pixel only in a warped context)
    ci = torch.remainder(torch.floor(sane(ctx.x * T.DISSOLVE_CELLS + p[2])).long(), T.LATTICE)
    cj = torch.remainder(torch.floor(sane(ctx.y * T.DISSOLVE_CELLS + p[3])).long(), T.LATTICE)
    cell = ctx.res.table[cj, ci]
    amount = fmod(p[0] + p[1] * ctx.time, 1.0)
    return _select(cell < amount, a, b)


for _name, _fn in _POINTWISE1.items():
    image_kernel(_name)(lambda ctx, p, a, _fn=_fn: _fn(a))
for _name, _fn in _POINTWISE2.items():
    image_kernel(_name)(lambda ctx, p, a, b, _fn=_fn: _fn(a, b))
image_kernel("dissolve")(_dissolve)
