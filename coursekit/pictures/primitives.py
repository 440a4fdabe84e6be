"""The primitive set of genetic pictures (paper section 3.1, after Sims 1991).

A *chromosome* is one primitive plus its parameter values. Primitives come in three kinds, as
in the paper: ``ZeroArgChrom`` (terminals: constants, colours, coordinates, ramps, noise,
turbulence, gradients, pixel maps), ``OneArgChrom`` and ``TwoArgChrom`` (functions). This module
is the registry: name, arity, parameters (with the range a random chromosome draws them
from) and what each primitive does. The whole-image implementations live in
:mod:`coursekit.pictures.evaluate`, the per-pixel ones in :mod:`coursekit.pictures.reference`.

Conventions shared by both evaluators:

- World coordinates: ``x`` grows to the right, ``y`` downwards; the default window is the unit
  square ``[0, 1] x [0, 1]``. ``radius`` and ``angle`` are measured around the centre
  ``(0.5, 0.5)``. Everything is defined in world coordinates, so zooming re-evaluates.
- Values are grey (one channel) or colour (three channels, RGB). "Nice" values lie in
  [0, 1]; the final mapping (:func:`coursekit.pictures.evaluate.to_rgb`) folds any value into
  [0, 1], so primitives need not clip.
- Parameters are floats stored in the chromosome (so random interpolation can blend them);
  integer-like parameters (octaves, picture index) are floored where used.

**Draw weights** (for random genomes, not part of the paper, which is silent on them): a random
chromosome picks a primitive of the wanted kind with probability proportional to its
``weight``, and a random genome's root (the first PreHeader chromosome, or the root of its only
string) is a function picked in proportion to ``root``. Measured on 600 random genomes at 64^2
(``benchmarks/picture_variety.py``), uniform draws gave about half greyscale pictures and one in
six flat: so colour leaves (``color``, ``gradient``, ``color-noise``) weigh 1.5, grey ``const``
0.6, the stock photos 0.3 (an ingredient, not the whole picture) and ``time`` 0.2 (it is 0 in a
still picture: a black leaf); ``hsv-to-rgb``, which turns any grey structure into colour, is 4
times as likely at the root, and the root is never a primitive that collapses to grey
(``bump``, ``grad-mag``, ``grad-dir``) or to a few flat levels (``round``). With these
weights, same protocol: 36 % greyscale, 12 % flat, 3 % black (the gallery's first generation,
:func:`coursekit.pictures.variety.random_population`, also redraws flat and black ones). Every
primitive stays in the set and can reach the root by mutation.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Param", "Primitive", "PRIMITIVES", "names", "arity", "get", "terminals", "functions",
           "max_arity", "PIXMAPS"]


@dataclass(frozen=True)
class Param:
    """A chromosome parameter: its name and the uniform range random chromosomes draw from."""

    name: str
    low: float
    high: float


@dataclass(frozen=True)
class Primitive:
    """One primitive: name, arity (0, 1 or 2), parameters and a one-line description."""

    name: str
    arity: int
    params: tuple[Param, ...]
    doc: str
    sims: bool = False  # in Sims' 1991 function list (or his published genotypes)
    weight: float = 1.0  # relative chance that a random chromosome of its kind is this one
    root: float = 1.0  # relative chance that a random genome's root is this one (functions)

    @property
    def kind(self) -> str:
        """``ZeroArgChrom``, ``OneArgChrom`` or ``TwoArgChrom`` (the paper's names)."""
        return ("ZeroArgChrom", "OneArgChrom", "TwoArgChrom")[self.arity]


# Pictures shipped inside scikit-image (nothing is downloaded at run time).
PIXMAPS = ("astronaut", "camera", "coffee", "chelsea", "rocket", "moon", "coins",
           "immunohistochemistry")

_OFF = (Param("offset_x", 0.0, 256.0), Param("offset_y", 0.0, 256.0))

_LIST = [
    # ---- ZeroArgChrom -------------------------------------------------------------------
    Primitive("const", 0, (Param("value", 0.0, 1.0),), "a grey constant (scalar)", True, weight=0.6),
    Primitive("color", 0, (Param("r", 0.0, 1.0), Param("g", 0.0, 1.0), Param("b", 0.0, 1.0)),
              "a colour constant (vector)", True, weight=1.5),
    Primitive("x", 0, (), "the horizontal pixel position", True),
    Primitive("y", 0, (), "the vertical pixel position", True),
    Primitive("radius", 0, (), "distance from the centre (0.5, 0.5)"),
    Primitive("angle", 0, (), "angle around the centre, 0..1 for a full turn"),
    Primitive("ramp", 0, (Param("direction", 0.0, 1.0), Param("frequency", 0.5, 6.0)),
              "sawtooth ramp frac(frequency * (p . d)) along direction d (turns)"),
    Primitive("gradient", 0, (Param("r0", 0.0, 1.0), Param("g0", 0.0, 1.0), Param("b0", 0.0, 1.0),
                              Param("r1", 0.0, 1.0), Param("g1", 0.0, 1.0), Param("b1", 0.0, 1.0),
                              Param("direction", 0.0, 1.0)),
              "colour gradient from colour 0 to colour 1 along a direction, mirrored each unit", weight=1.5),
    Primitive("bw-noise", 0, (Param("frequency", 1.0, 12.0),) + _OFF,
              "smooth value noise, grey; the offsets make each chromosome's field its own", True),
    Primitive("color-noise", 0, (Param("frequency", 1.0, 12.0),) + _OFF,
              "smooth value noise, one field per RGB channel", True, weight=1.5),
    Primitive("turbulence", 0, (Param("frequency", 1.0, 8.0), Param("octaves", 2.0, 5.0)) + _OFF,
              "multi-octave noise: sum of |2 noise - 1| halving amplitude per octave"),
    Primitive("pixmap", 0, (Param("picture", 0.0, float(len(PIXMAPS))),),
              "a picture from scikit-image covering the unit square, mirrored outside", weight=0.3),
    Primitive("time", 0, (), "the animation time (the render option time=)", weight=0.2),
    # ---- OneArgChrom --------------------------------------------------------------------
    Primitive("abs", 1, (), "absolute value", True),
    Primitive("sin", 1, (), "0.5 + 0.5 sin(2 pi a): one period per unit, into [0, 1]", True),
    Primitive("cos", 1, (), "0.5 + 0.5 cos(2 pi a)", True),
    Primitive("log", 1, (), "protected natural log: log(|a| + 1e-6)", True),
    Primitive("atan", 1, (), "atan(a) / pi + 0.5, into (0, 1)", True),
    Primitive("round", 1, (), "nearest integer, floor(a + 0.5)", True, root=0.0),
    Primitive("invert", 1, (), "1 - a (the photographic negative)", True),
    Primitive("hsv-to-rgb", 1, (),
              "read a colour as (hue, saturation, value); a grey a is the hue at full s, v", True, root=4.0),
    Primitive("swirl", 1, (Param("strength", -8.0, 8.0), Param("extent", 0.1, 0.8)),
              "re-evaluate a on coordinates turned about the centre by strength*exp(-r/extent)"),
    Primitive("rotate", 1, (Param("turns", 0.0, 1.0),),
              "re-evaluate a on coordinates rotated about the centre", True),
    Primitive("blur", 1, (Param("sigma", 0.002, 0.05),),
              "Gaussian-like blur (three box passes), sigma in world units", True),
    Primitive("band-pass", 1, (Param("sigma", 0.002, 0.03),),
              "0.5 + blur(a, sigma) - blur(a, 3 sigma)", True),
    Primitive("bump", 1, (Param("azimuth", 0.0, 1.0), Param("height", 0.005, 0.1)),
              "emboss: light a height field (grey of a) from an azimuth", True, root=0.0),
    Primitive("grad-mag", 1, (Param("gain", 0.01, 0.3),),
              "gain * |gradient of a| (grey of a), world units", True, root=0.0),
    Primitive("grad-dir", 1, (), "direction of the gradient of a, 0..1 for a full turn", True, root=0.0),
    # ---- TwoArgChrom --------------------------------------------------------------------
    Primitive("plus", 2, (), "a + b", True),
    Primitive("minus", 2, (), "a - b", True),
    Primitive("times", 2, (), "a * b", True),
    Primitive("divide", 2, (), "protected a / b: |b| is kept at least 1e-3", True),
    Primitive("mod", 2, (), "protected a mod b (sign of b); a where |b| < 1e-3", True),
    Primitive("expt", 2, (), "protected |a| ** b = exp(clip(b log(|a| + 1e-6), -30, 30))", True),
    Primitive("min", 2, (), "smaller of a and b", True),
    Primitive("max", 2, (), "larger of a and b", True),
    Primitive("and", 2, (), "bitwise and of a and b quantised to 8 bits (after folding)", True),
    Primitive("or", 2, (), "bitwise or of a and b quantised to 8 bits", True),
    Primitive("xor", 2, (), "bitwise xor of a and b quantised to 8 bits", True),
    Primitive("dissolve", 2, (Param("amount", 0.0, 1.0), Param("rate", 0.0, 1.0)) + _OFF,
              "per-cell random choice of b over a; the fraction frac(amount + rate*time) picks b",
              True),
    Primitive("warp-swirl", 2, (Param("strength", -8.0, 8.0),),
              "re-evaluate a on coordinates swirled by strength * grey(b)"),
    Primitive("warp-by", 2, (Param("amount", -0.5, 0.5),),
              "re-evaluate a on coordinates displaced by amount * (b - 0.5) (first two channels)",
              True),
]

PRIMITIVES: dict[str, Primitive] = {p.name: p for p in _LIST}


def names() -> list[str]:
    """All primitive names, terminals first, in a fixed order."""
    return list(PRIMITIVES)


def get(name: str) -> Primitive:
    """The :class:`Primitive` called ``name``; ValueError naming the allowed names otherwise."""
    try:
        return PRIMITIVES[name]
    except (KeyError, TypeError):
        raise ValueError(f"primitive: unknown name {name!r}; allowed: {', '.join(PRIMITIVES)}") from None


def arity(name: str) -> int:
    """Number of arguments of primitive ``name`` (0, 1 or 2)."""
    return get(name).arity


def terminals() -> list[str]:
    """Names of the ZeroArgChrom primitives (allowed in a tail)."""
    return [p.name for p in _LIST if p.arity == 0]


def functions() -> list[str]:
    """Names of the OneArgChrom and TwoArgChrom primitives."""
    return [p.name for p in _LIST if p.arity > 0]


_MAX_ARITY = max(p.arity for p in _LIST)


def max_arity() -> int:
    """n, the largest arity in the set (it fixes the tail length t = h (n - 1) + 1)."""
    return _MAX_ARITY
