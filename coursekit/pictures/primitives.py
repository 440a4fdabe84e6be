"""The primitive set of genetic pictures (paper section 3.1, after Sims 1991).

A *chromosome* is one primitive plus its parameter values. Primitives come in three kinds, as
in the paper: ``ZeroArgChrom`` (terminals: constants, colours, coordinates, ramps, noise,
turbulence, gradients, pixel maps), ``OneArgChrom`` and ``TwoArgChrom`` (functions). This module
is the registry, the one place the genome alphabet, the whole-image evaluator and the per-pixel
reference read: name, arity, parameters (with the range a random chromosome draws them from),
what each primitive does, how the evaluator feeds it (its ``form``, below) and its two
implementations. The built-in whole-image implementations live in :mod:`.kernels` and the
per-pixel ones in :mod:`.reference`, each bound to its name with :func:`image_kernel` /
:func:`pixel_kernel`; a primitive of one's own is one call, :func:`register_primitive`, giving
both.

**Forms.** A whole-image kernel gets the :class:`~.context.Context`, the parameters ``p`` (a
list of ``(B, 1, 1, 1)`` tensors) and its arguments' values, and its form says how:

- ``terminal`` (arity 0): ``f(ctx, p)``;
- ``pointwise``: ``f(ctx, p, a[, b])``, the value at a pixel depends on the arguments at that
  pixel only (arguments may be broadcast to one shape beforehand: the values do not change);
- ``filter``: ``f(ctx, p, a)`` with ``a`` as it is (``blur``, ``band-pass``);
- ``neighbourhood``: ``f(ctx, p, a)`` with ``a`` expanded to the whole image first;
- ``warp``: ``f(ctx, p[, b])`` returns the context (new coordinates) in which the first argument
  is evaluated (``b``: the value of the second argument).

A per-pixel function gets plain floats: ``terminal`` and ``pointwise`` ones
``f(ref, x, y, p[, a, b])`` (``a``, ``b``: tuples of 1 or 3 channels; returns such a tuple),
``filter`` and ``neighbourhood`` ones ``f(ref, p, grid, i, j)`` (``grid``: the argument on the
whole pixel grid, :class:`~.reference.Grid`), ``warp`` ones ``f(p, x, y[, b])`` returning the new
``(x, y)``; ``ref`` gives ``time`` and ``noise(u, v)``.

Conventions shared by both evaluators:

- World coordinates: ``x`` grows to the right, ``y`` downwards; the default window is the unit
  square ``[0, 1] x [0, 1]``. ``radius`` and ``angle`` are measured around the centre
  ``(0.5, 0.5)``. Everything is defined in world coordinates, so zooming re-evaluates.
- Values are grey (one channel) or colour (three channels, RGB). "Nice" values lie in
  [0, 1]; the final mapping (:func:`coursekit.pictures.evaluate.to_rgb`) folds any value into
  [0, 1], so primitives need not clip.
- Parameters are floats stored in the chromosome (so random interpolation can blend them);
  integer-like parameters (octaves, picture index) are floored where used.
- ``plus``, ``times``, ``min``, ``max``, ``and``, ``or`` and ``xor`` are commutative: their
  arguments swapped give the same picture bit for bit (checked on random arguments, NaN and
  infinite ones included, in both evaluators). ``minus`` is not, though at the root it looks
  so: the final mapping folds ``-v`` like ``v``.
- Neighbourhoods see the picture beyond the window: a ``filter`` or ``neighbourhood``
  primitive declares its *reach* (:data:`REACHES`: how many pixels beyond the window its value
  at the window's pixels reads), and both evaluators evaluate its argument on the window
  extended by that many pixels (:func:`padding`), filter, and keep the window, so a zoomed or
  panned window is the matching crop of a larger render. The extension of one picture is at
  most its own size on each side in all (nested filters add up); beyond it borders are
  replicated.
- ``grad-dir`` is 0 where its argument is flat, its gradient under :data:`FLAT_GRADIENT` per
  world unit: there the direction is only the rounding error of a constant field (which would
  show as noise at every size).

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

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from math import isqrt

from .frame import MAX_PIXELS

__all__ = ["Param", "Primitive", "PRIMITIVES", "FORMS", "IMAGE_KERNELS", "PIXEL_KERNELS", "names", "arity", "get",
           "terminals", "functions", "max_arity", "register_primitive", "image_kernel", "pixel_kernel", "PIXMAPS",
           "FLAT_GRADIENT", "REACHES", "reach", "padding"]

#: How the evaluators feed a primitive (module docstring).
FORMS = ("terminal", "pointwise", "filter", "neighbourhood", "warp")

#: A gradient (per world unit, the larger of its two components) under which ``grad-dir`` calls
#: its argument flat and gives 0: a change of 1/100 across the unit square, under three grey
#: levels, which no picture shows.
FLAT_GRADIENT = 1e-2


@dataclass(frozen=True)
class Param:
    """A chromosome parameter: its name and the uniform range random chromosomes draw from."""

    name: str
    low: float
    high: float


@dataclass(frozen=True)
class Primitive:
    """One primitive: name, arity (0, 1 or 2), parameters, a one-line description, and what the
    evaluators need: its ``form`` (default ``terminal`` for arity 0, else ``pointwise``), its
    ``cost`` (milliseconds per node at 256 x 256 on one CPU core, used only to share a
    population fairly between worker processes), whether it ``samples`` coordinates (noise,
    pictures: about 3x dearer on warped coordinates, whole images instead of rows) and whether
    it is ``commutative``: its two arguments swapped give the same picture, bit for bit, in both
    evaluators (the gallery then counts the two expressions as one:
    :func:`~coursekit.pictures.operators.coding`)."""

    name: str
    arity: int
    params: tuple[Param, ...]
    doc: str
    sims: bool = False  # in Sims' 1991 function list (or his published genotypes)
    weight: float = 1.0  # relative chance that a random chromosome of its kind is this one
    root: float = 1.0  # relative chance that a random genome's root is this one (functions)
    form: str = ""
    cost: float = 0.05
    samples: bool = False
    commutative: bool = False

    def __post_init__(self):
        if not self.form:
            object.__setattr__(self, "form", "terminal" if self.arity == 0 else "pointwise")

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
    Primitive("radius", 0, (), "distance from the centre (0.5, 0.5)", cost=0.1),
    Primitive("angle", 0, (), "angle around the centre, 0..1 for a full turn", cost=0.11),
    Primitive("ramp", 0, (Param("direction", 0.0, 1.0), Param("frequency", 0.5, 6.0)),
              "sawtooth ramp frac(frequency * (p . d)) along direction d (turns)"),
    Primitive("gradient", 0, (Param("r0", 0.0, 1.0), Param("g0", 0.0, 1.0), Param("b0", 0.0, 1.0),
                              Param("r1", 0.0, 1.0), Param("g1", 0.0, 1.0), Param("b1", 0.0, 1.0),
                              Param("direction", 0.0, 1.0)),
              "colour gradient from colour 0 to colour 1 along a direction, mirrored each unit", weight=1.5, cost=0.15),
    Primitive("bw-noise", 0, (Param("frequency", 1.0, 12.0),) + _OFF,
              "smooth value noise, grey; the offsets make each chromosome's field its own", True, cost=0.4, samples=True),
    Primitive("color-noise", 0, (Param("frequency", 1.0, 12.0),) + _OFF,
              "smooth value noise, one field per RGB channel", True, weight=1.5, cost=1.0, samples=True),
    Primitive("turbulence", 0, (Param("frequency", 1.0, 8.0), Param("octaves", 2.0, 5.0)) + _OFF,
              "multi-octave noise: sum of |2 noise - 1| halving amplitude per octave", cost=1.3, samples=True),
    Primitive("pixmap", 0, (Param("picture", 0.0, float(len(PIXMAPS))),),
              "a picture from scikit-image covering the unit square, mirrored outside", weight=0.3, cost=0.55, samples=True),
    Primitive("time", 0, (), "the animation time (the render option time=)", weight=0.2),
    # ---- OneArgChrom --------------------------------------------------------------------
    Primitive("abs", 1, (), "absolute value", True),
    Primitive("sin", 1, (), "0.5 + 0.5 sin(2 pi a): one period per unit, into [0, 1]", True, cost=0.12),
    Primitive("cos", 1, (), "0.5 + 0.5 cos(2 pi a)", True, cost=0.08),
    Primitive("log", 1, (), "protected natural log: log(|a| + 1e-6)", True, cost=0.09),
    Primitive("atan", 1, (), "atan(a) / pi + 0.5, into (0, 1)", True, cost=0.08),
    Primitive("round", 1, (), "nearest integer, floor(a + 0.5)", True, root=0.0),
    Primitive("invert", 1, (), "1 - a (the photographic negative)", True),
    Primitive("hsv-to-rgb", 1, (),
              "read a colour as (hue, saturation, value); a grey a is the hue at full s, v", True, root=4.0, cost=0.4),
    Primitive("swirl", 1, (Param("strength", -8.0, 8.0), Param("extent", 0.1, 0.8)),
              "re-evaluate a on coordinates turned about the centre by strength*exp(-r/extent)", form="warp", cost=0.4),
    Primitive("rotate", 1, (Param("turns", 0.0, 1.0),),
              "re-evaluate a on coordinates rotated about the centre", True, form="warp", cost=0.12),
    Primitive("blur", 1, (Param("sigma", 0.002, 0.05),),
              "Gaussian-like blur (three box passes), sigma in world units", True, form="filter", cost=0.5),
    Primitive("band-pass", 1, (Param("sigma", 0.002, 0.03),),
              "0.5 + blur(a, sigma) - blur(a, 3 sigma)", True, form="filter", cost=1.1),
    Primitive("bump", 1, (Param("azimuth", 0.0, 1.0), Param("height", 0.005, 0.1)),
              "emboss: light a height field (grey of a) from an azimuth", True, root=0.0, form="neighbourhood", cost=0.35),
    Primitive("grad-mag", 1, (Param("gain", 0.01, 0.3),),
              "gain * |gradient of a| (grey of a), world units", True, root=0.0, form="neighbourhood", cost=0.24),
    Primitive("grad-dir", 1, (), "direction of the gradient of a, 0..1 for a full turn; 0 where a is flat", True, root=0.0, form="neighbourhood", cost=0.23),
    # ---- TwoArgChrom --------------------------------------------------------------------
    Primitive("plus", 2, (), "a + b", True, commutative=True),
    Primitive("minus", 2, (), "a - b", True),
    Primitive("times", 2, (), "a * b", True, commutative=True),
    Primitive("divide", 2, (), "protected a / b: |b| is kept at least 1e-3", True, cost=0.15),
    Primitive("mod", 2, (), "protected a mod b (sign of b); a where |b| < 1e-3", True, cost=0.37),
    Primitive("expt", 2, (), "protected |a| ** b = exp(clip(b log(|a| + 1e-6), -30, 30))", True, cost=0.23),
    Primitive("min", 2, (), "smaller of a and b", True, commutative=True),
    Primitive("max", 2, (), "larger of a and b", True, commutative=True),
    Primitive("and", 2, (), "bitwise and of a and b quantised to 8 bits (after folding)", True, commutative=True, cost=0.3),
    Primitive("or", 2, (), "bitwise or of a and b quantised to 8 bits", True, commutative=True, cost=0.3),
    Primitive("xor", 2, (), "bitwise xor of a and b quantised to 8 bits", True, commutative=True, cost=0.35),
    Primitive("dissolve", 2, (Param("amount", 0.0, 1.0), Param("rate", 0.0, 1.0)) + _OFF,
              "per-cell random choice of b over a; the fraction frac(amount + rate*time) picks b",
              True, cost=0.6, samples=True),
    Primitive("warp-swirl", 2, (Param("strength", -8.0, 8.0),),
              "re-evaluate a on coordinates swirled by strength * grey(b)", form="warp", cost=0.25),
    Primitive("warp-by", 2, (Param("amount", -0.5, 0.5),),
              "re-evaluate a on coordinates displaced by amount * (b - 0.5) (first two channels)",
              True, form="warp", cost=0.09),
]

PRIMITIVES: dict[str, Primitive] = {p.name: p for p in _LIST}
#: Whole-image implementations by primitive name (the built-ins: :mod:`.kernels`).
IMAGE_KERNELS: dict = {}
#: Per-pixel implementations by primitive name (the built-ins: :mod:`.reference`).
PIXEL_KERNELS: dict = {}
#: Reaches of neighbourhood primitives by name (the built-ins: :mod:`.textures`):
#: ``reach(p, px, py, H, W) -> (rows, columns)``, the pixels beyond the window on each side that
#: the value at the window's pixels reads (``p``: the parameters as floats; ``px``, ``py``: a
#: pixel's world size; ``H``, ``W``: the picture's size). A filter without one sees replicated
#: borders at the window's edges.
REACHES: dict = {}
#: Extensions of a picture's grid are multiples of its size divided by this (:func:`padding`).
EXTENSION_STEPS = 16
_MAX_SIDE = isqrt(MAX_PIXELS)
#: Names given to :func:`register_primitive` in this process: worker processes (:mod:`.workers`)
#: import the built-ins only, so genomes using these render in-process.
REGISTERED: set[str] = set()
#: Counts registrations that redefined a primitive (``replace=True``): trees decoded before one
#: may read a changed arity, so genomes decode again (:meth:`~.genome.Genome.decode`).
REDEFINED = 0


def register_primitive(primitive: Primitive, *, image: Callable | None = None, pixel: Callable | None = None,
                       reach: Callable | None = None, replace: bool = False) -> Primitive:
    """Add ``primitive`` to the alphabet, with its whole-image (``image``) and per-pixel
    (``pixel``) implementations (module docstring, *Forms*). From then on random genomes and
    mutations can draw it (in proportion to its ``weight``), genomes holding it decode,
    render and are read back from files, and the reference evaluates it.

    Args:
        primitive: the declaration; its name must be new unless ``replace``.
        image, pixel: the implementations (both needed to render it with both evaluators).
        reach: for a ``filter`` or ``neighbourhood`` primitive, its reach (:data:`REACHES`).
        replace: allow redefining a primitive of the same name (a notebook cell run again).
    Returns:
        ``primitive``.

    For example (a pointwise function of one argument)::

        register_primitive(Primitive("tanh", 1, (), "hyperbolic tangent"),
                           image=lambda ctx, p, a: torch.tanh(a),
                           pixel=lambda ref, x, y, p, a: tuple(math.tanh(v) for v in a))

    The whole-image kernel must compute each image of a batch as it would compute it alone
    (plain arithmetic does; some vectorised library functions round the last elements of a
    tensor differently, see :mod:`.kernels`), or pictures rendered in waves differ in the last
    bits. Registering changes what random genomes draw from: same seed, other genomes (a
    ``weight`` and ``root`` of 0 keep it out of random draws). Worker processes know only the
    built-ins, so a population holding a registered primitive renders in this process.
    """
    if not isinstance(primitive, Primitive):
        raise TypeError(f"primitive: expected a Primitive, got {type(primitive).__name__}")
    if not isinstance(primitive.name, str) or not primitive.name or any(c.isspace() or c in "()" for c in primitive.name):
        raise ValueError(f"primitive.name: {primitive.name!r} must be a non-empty name without spaces or parentheses")
    if primitive.arity not in (0, 1, 2) or isinstance(primitive.arity, bool):
        raise ValueError(f"primitive.arity: {primitive.arity!r} must be 0, 1 or 2 (the tail length depends on the largest)")
    if primitive.form not in FORMS:
        raise ValueError(f"primitive.form: {primitive.form!r} must be one of {', '.join(FORMS)}")
    if (primitive.form == "terminal") != (primitive.arity == 0) or (primitive.form in ("filter", "neighbourhood")
                                                                   and primitive.arity != 1):
        raise ValueError(f"primitive.form: {primitive.form!r} does not fit arity {primitive.arity} (terminal: 0; "
                         "filter, neighbourhood: 1; pointwise, warp: 1 or 2)")
    if primitive.commutative and primitive.arity != 2:
        raise ValueError(f"primitive.commutative: only a primitive of two arguments can be commutative "
                         f"({primitive.name!r} has {primitive.arity})")
    for k, prm in enumerate(primitive.params):
        if not isinstance(prm, Param) or not prm.low <= prm.high:
            raise ValueError(f"primitive.params[{k}]: {prm!r} must be a Param with low <= high")
    if primitive.name in PRIMITIVES and not replace:
        raise ValueError(f"primitive.name: {primitive.name!r} is already registered (replace=True redefines it)")
    if reach is not None and primitive.form not in ("filter", "neighbourhood"):
        raise ValueError(f"reach: only a filter or neighbourhood primitive reads pixels beyond its own "
                         f"({primitive.name!r} is {primitive.form})")
    for where, fn in (("image", image), ("pixel", pixel), ("reach", reach)):
        if fn is not None and not callable(fn):
            raise TypeError(f"{where}: expected a function, got {type(fn).__name__}")
    global REDEFINED
    if primitive.name in PRIMITIVES:
        REDEFINED += 1
    PRIMITIVES[primitive.name] = primitive
    REGISTERED.add(primitive.name)
    for table, fn in ((IMAGE_KERNELS, image), (PIXEL_KERNELS, pixel), (REACHES, reach)):
        if fn is not None:
            table[primitive.name] = fn
        else:
            table.pop(primitive.name, None)
    return primitive


def _binder(table: dict, what: str) -> Callable[[str], Callable[[Callable], Callable]]:
    def bind(name: str) -> Callable[[Callable], Callable]:
        get(name)  # a declared primitive

        def decorate(fn):
            table[name] = fn
            return fn
        return decorate
    bind.__doc__ = f"Decorator: ``fn`` is the {what} implementation of the declared primitive ``name``."
    return bind


image_kernel = _binder(IMAGE_KERNELS, "whole-image")
pixel_kernel = _binder(PIXEL_KERNELS, "per-pixel")
reach = _binder(REACHES, "reach")


def padding(name: str, p: Sequence[float], px: float, py: float, H: int, W: int, pad: tuple[int, int] = (0, 0)) -> tuple[int, int]:
    """Rows and columns on each side by which primitive ``name`` (parameters ``p``, floats) in a
    context already extended by ``pad`` evaluates its argument beyond that: its reach
    (:data:`REACHES`), rounded up so that the extension in all is a multiple of a
    :data:`EXTENSION_STEPS`-th of the picture's size (few distinct extended grids in a
    population, so that waves stack more of them: :mod:`.grouped`), and at most ``H`` rows and
    ``W`` columns beyond the window in all (nor more than the largest picture,
    :data:`~.frame.MAX_PIXELS`, allows: a poster of 4096 x 4096 is not extended); ``(0, 0)`` for a primitive without a
    reach. The one rule both evaluators follow."""
    f = REACHES.get(name)
    if f is None:
        return 0, 0
    rows, cols = f(p, px, py, H, W)
    return _extension(int(rows), pad[0], H), _extension(int(cols), pad[1], W)


def _extension(reach: int, pad: int, n: int) -> int:
    if reach <= 0:
        return 0
    most = max(0, min(n, (_MAX_SIDE - n) // 2))  # never a grid larger than the largest picture
    step = -(-n // EXTENSION_STEPS)
    return max(0, min(-(-(pad + reach) // step) * step, most) - pad)


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
    return [p.name for p in PRIMITIVES.values() if p.arity == 0]


def functions() -> list[str]:
    """Names of the OneArgChrom and TwoArgChrom primitives."""
    return [p.name for p in PRIMITIVES.values() if p.arity > 0]


def max_arity() -> int:
    """n, the largest arity in the set (it fixes the tail length t = h (n - 1) + 1): 2."""
    return 2
