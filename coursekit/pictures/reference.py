"""Per-pixel reference evaluator of genetic pictures (paper section 3.2, Sims-style).

Sims (1991) evaluated a genotype's symbolic expression once per pixel coordinate. This module
does exactly that in plain Python floats (double precision), one pixel at a time, with the
``math`` module: it is the independent definition the tensorised :mod:`.evaluate` is tested
against, and the baseline of the lesson's speed comparison. It is slow on purpose.

Each primitive's per-pixel function is bound to its name in the registry of :mod:`.primitives`
(:func:`~.primitives.pixel_kernel`, signatures by form there). Neighbourhood primitives
(``blur``, ``band-pass``, ``bump``, ``grad-mag``, ``grad-dir``) need their argument at
neighbouring pixels: the argument is evaluated pixel by pixel on the whole grid extended beyond
the window by the primitive's reach (memoised, :class:`Grid`; :func:`~.primitives.padding`) and
filtered with explicit loops, the extended grid's borders replicated. Coordinate transforms
evaluate their argument at the transformed coordinates of the pixel.
"""

from __future__ import annotations

import math

import numpy as np

from . import primitives as P
from . import textures as T
from .frame import parse_size, parse_time, parse_window
from .genome import Genome, Node
from .primitives import pixel_kernel

__all__ = ["Grid", "render_reference"]

_BIG = 1e6
TWO_PI = 2.0 * math.pi


def _sane(v: float) -> float:
    if math.isnan(v):
        return 0.0
    return min(max(v, -_BIG), _BIG)


def _fold(v: float) -> float:
    m = v % 2.0
    return 2.0 - m if m > 1.0 else m


def _smooth(t):
    return t * t * (3.0 - 2.0 * t)


def _map1(f, a):
    return tuple(f(v) for v in a)


def _map2(f, a, b):
    if len(a) < len(b):
        a = a * len(b)
    elif len(b) < len(a):
        b = b * len(a)
    return tuple(f(u, v) for u, v in zip(a, b))


def _grey(a):
    return (sum(a) / len(a),) if len(a) > 1 else a


class _Coords:
    """Pixel (i, j) -> world (x, y), memoised; ``pad``: the rows and columns beyond the window on
    each side it is evaluated on (a neighbourhood's argument, :func:`~.primitives.padding`),
    ``origin``: the warp node and the coordinates it was made from (None: unwarped)."""

    def __init__(self, fn, pad=(0, 0), origin=None):
        self.fn, self.memo, self.pad, self.origin = fn, {}, pad, origin

    def __call__(self, i, j):
        key = (i, j)
        if key not in self.memo:
            x, y = self.fn(i, j)
            self.memo[key] = (_sane(x), _sane(y))
        return self.memo[key]


class _Reference:
    def __init__(self, H, W, window, time):
        self.H, self.W, self.time = H, W, float(time)
        x0, y0, x1, y1 = window
        sx, sy = (x1 - x0) / W, (y1 - y0) / H
        self.px, self.py = abs(sx), abs(sy)

        def unwarped(i, j):  # pixel centres, any row or column (beyond the window too)
            return float(np.float32(x0 + (j + 0.5) * sx)), float(np.float32(y0 + (i + 0.5) * sy))
        self.unwarped = unwarped
        self.base = _Coords(unwarped)
        self.extended = {(0, 0): self.base}
        self.table = T.noise_table().astype(np.float64)
        self.memo: dict = {}
        self.derived: dict = {}
        self.grids: dict = {}

    # -- helpers ------------------------------------------------------------------------
    def noise(self, u, v):
        u, v = _sane(u), _sane(v)
        i0, j0 = math.floor(u), math.floor(v)
        su, sv = _smooth(u - i0), _smooth(v - j0)
        L, t = T.LATTICE, self.table
        i0, j0 = i0 % L, j0 % L
        i1, j1 = (i0 + 1) % L, (j0 + 1) % L
        a = t[j0, i0] + su * (t[j0, i1] - t[j0, i0])
        b = t[j1, i0] + su * (t[j1, i1] - t[j1, i0])
        return float(a + sv * (b - a))

    def warp(self, node, C):
        """The coordinates warp ``node`` makes from ``C`` (its first argument is evaluated there)."""
        key = (id(node), id(C))
        if key not in self.derived:
            f, p, k = P.PIXEL_KERNELS[node.symbol], node.params, node.children

            def make(ii, jj):
                return f(p, *C(ii, jj), *[self.ev(c, ii, jj, C) for c in k[1:]])
            self.derived[key] = (_Coords(make, C.pad, (node, C)), C)  # keep C alive so ids stay unique
        return self.derived[key][0]

    def padded(self, C, rows, cols):
        """``C`` on the pixel grid extended to ``rows`` rows and ``cols`` columns on each side."""
        if (rows, cols) == C.pad:
            return C
        if C.origin is not None:
            node, parent = C.origin
            return self.warp(node, self.padded(parent, rows, cols))
        if (rows, cols) not in self.extended:
            self.extended[(rows, cols)] = _Coords(self.unwarped, (rows, cols))
        return self.extended[(rows, cols)]

    def inner(self, node, C):
        """Where neighbourhood ``node`` evaluated on ``C`` reads its argument: ``C`` extended by its reach."""
        q = P.padding(node.symbol, node.params, self.px, self.py, self.H, self.W, C.pad)
        return self.padded(C, C.pad[0] + q[0], C.pad[1] + q[1])

    def grid(self, node, C):
        """``node``'s values on every pixel of ``C``'s (extended) grid, rows of channel tuples."""
        key = (id(node), id(C))
        if key not in self.grids:
            (qy, qx) = C.pad
            self.grids[key] = [[self.ev(node, i, j, C) for j in range(-qx, self.W + qx)]
                               for i in range(-qy, self.H + qy)]
        return self.grids[key]

    def blur(self, node, C, sigma):
        key = ("blur", id(node), id(C), sigma)
        if key not in self.grids:
            self.grids[key] = _Shifted(self._blur(node, C, sigma), C.pad)
        return self.grids[key]

    def _blur(self, node, C, sigma):
        g = [[list(v) for v in row] for row in self.grid(node, C)]
        rx = T.box_radius(abs(sigma) / self.px, 4 * self.W)
        ry = T.box_radius(abs(sigma) / self.py, 4 * self.H)
        H, W = len(g), len(g[0])  # the extended grid, its borders replicated
        for _ in range(3):
            if rx:
                g = [[[sum(g[i][min(max(j + d, 0), W - 1)][c] for d in range(-rx, rx + 1)) / (2 * rx + 1)
                       for c in range(len(g[i][j]))] for j in range(W)] for i in range(H)]
            if ry:
                g = [[[sum(g[min(max(i + d, 0), H - 1)][j][c] for d in range(-ry, ry + 1)) / (2 * ry + 1)
                       for c in range(len(g[i][j]))] for j in range(W)] for i in range(H)]
        return g

    def gradient(self, node, C, i, j):
        g = self.grid(node, C)
        qy, qx = C.pad
        i, j = i + qy, j + qx  # into the extended grid
        H, W = len(g), len(g[0])

        def grey(a, b):
            return _sane(_grey(g[a][b])[0])

        def side(k, n, at):  # the neighbour at k, extrapolated linearly beyond the grid's edges
            if k < 0:
                return 2.0 * at(0) - at(1)
            if k >= n:
                return 2.0 * at(n - 1) - at(n - 2)
            return at(k)
        gx = gy = 0.0
        if W > 1:
            row = lambda b: grey(i, b)  # noqa: E731
            gx = (side(j + 1, W, row) - side(j - 1, W, row)) / (2.0 * self.px)
        if H > 1:
            col = lambda a: grey(a, j)  # noqa: E731
            gy = (side(i + 1, H, col) - side(i - 1, H, col)) / (2.0 * self.py)
        return gx, gy

    # -- evaluation ---------------------------------------------------------------------
    def ev(self, n: Node, i, j, C):
        key = (id(n), i, j, id(C))
        if key not in self.memo:
            self.memo[key] = self._ev(n, i, j, C)
        return self.memo[key]

    def _ev(self, n: Node, i, j, C):
        s, p, k = n.symbol, n.params, n.children
        f = P.PIXEL_KERNELS.get(s)
        if f is None:
            raise ValueError(f"primitive {s!r} has no per-pixel implementation (register one with "
                             "coursekit.pictures.primitives.register_primitive(..., pixel=...))")
        form = P.get(s).form
        if form == "terminal":
            return f(self, *C(i, j), p)
        if form == "pointwise":
            return f(self, *C(i, j), p, *[self.ev(c, i, j, C) for c in k])
        if form == "filter" or form == "neighbourhood":  # its argument on the grid extended by its reach
            return f(self, p, Grid(self, k[0], self.inner(n, C)), i, j)
        return self.ev(k[0], i, j, self.warp(n, C))  # a warp: the first argument at the transformed coordinates


class _Shifted:
    """Rows of an extended grid indexed by the window's pixel numbers: ``[i][j]`` for ``i`` from
    minus the extension on (``pad``: its rows and columns on each side)."""

    __slots__ = ("g", "pad")

    def __init__(self, g, pad):
        self.g, self.pad = g, pad

    def __getitem__(self, i):
        return _Row(self.g[_index(i, self.pad[0], len(self.g))], self.pad[1])


class _Row:
    __slots__ = ("row", "cols")

    def __init__(self, row, cols):
        self.row, self.cols = row, cols

    def __getitem__(self, j):
        return self.row[_index(j, self.cols, len(self.row))]


def _index(i: int, pad: int, n: int) -> int:
    """Pixel number ``i`` of a window extended by ``pad`` as an index into its ``n`` rows or columns."""
    if not -pad <= i < n - pad:
        raise IndexError(f"pixel {i} is outside the grid extended by {pad}")
    return i + pad


class Grid:
    """An argument of a neighbourhood primitive on the whole pixel grid (evaluated once), extended
    beyond the window by the primitive's reach (:func:`~.primitives.padding`)."""

    __slots__ = ("ref", "node", "C")

    def __init__(self, ref: _Reference, node: Node, C):
        self.ref, self.node, self.C = ref, node, C

    def blur(self, sigma: float) -> list:
        """Rows of channel lists, indexed by the window's pixels (``[i][j]``, ``i`` and ``j`` from
        minus the extension on): three box passes of radius ``sigma`` (world units) per axis."""
        return self.ref.blur(self.node, self.C, sigma)

    def gradient(self, i: int, j: int) -> tuple[float, float]:
        """Central differences of the grey value at pixel ``(i, j)``, per world unit (one-sided
        on the grid's edges)."""
        return self.ref.gradient(self.node, self.C, i, j)


# ---- terminals: f(ref, x, y, p) ---------------------------------------------------------------

def _along(x, y, turns):
    a = TWO_PI * turns
    return x * math.cos(a) + y * math.sin(a)


def _ramp(ref, x, y, p):
    v = p[1] * _along(x, y, p[0])
    return (v - math.floor(v),)


def _gradient(ref, x, y, p):
    t = _fold(_along(x, y, p[6]))
    return tuple(p[c] + (p[3 + c] - p[c]) * t for c in range(3))


def _turbulence(ref, x, y, p):
    octaves = int(min(max(math.floor(p[1]), 1), 8))
    total = norm = 0.0
    for o in range(octaves):
        f = p[0] * 2.0 ** o
        nv = ref.noise(x * f + p[2] + o * T.OCTAVE_SHIFT[0], y * f + p[3] + o * T.OCTAVE_SHIFT[1])
        total += 0.5 ** o * abs(2.0 * nv - 1.0)
        norm += 0.5 ** o
    return (total / norm,)


def _pixmap(ref, x, y, p):
    img = T.pixmap(T.pixmap_index(p[0]))
    h, w = img.shape[:2]
    fx = min(max(_fold(x) * w - 0.5, 0.0), w - 1.0)
    fy = min(max(_fold(y) * h - 0.5, 0.0), h - 1.0)
    x0, y0 = int(math.floor(fx)), int(math.floor(fy))
    x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
    tx, ty = fx - x0, fy - y0
    return tuple(float((img[y0, x0, c] * (1 - tx) + img[y0, x1, c] * tx) * (1 - ty)
                       + (img[y1, x0, c] * (1 - tx) + img[y1, x1, c] * tx) * ty) for c in range(3))


_TERMINALS = {
    "const": lambda ref, x, y, p: (p[0],),
    "color": lambda ref, x, y, p: tuple(p[:3]),
    "x": lambda ref, x, y, p: (x,),
    "y": lambda ref, x, y, p: (y,),
    "radius": lambda ref, x, y, p: (math.hypot(x - 0.5, y - 0.5),),
    "angle": lambda ref, x, y, p: ((math.atan2(y - 0.5, x - 0.5) / TWO_PI) % 1.0,),
    "ramp": _ramp,
    "gradient": _gradient,
    "bw-noise": lambda ref, x, y, p: (ref.noise(x * p[0] + p[1], y * p[0] + p[2]),),
    "color-noise": lambda ref, x, y, p: tuple(ref.noise(x * p[0] + p[1] + sx, y * p[0] + p[2] + sy)
                                              for sx, sy in T.CHANNEL_SHIFT),
    "turbulence": _turbulence,
    "pixmap": _pixmap,
    "time": lambda ref, x, y, p: (ref.time,),
}


def _turn(x, y, ang):
    dx, dy = x - 0.5, y - 0.5
    c, s = math.cos(ang), math.sin(ang)
    return 0.5 + dx * c - dy * s, 0.5 + dx * s + dy * c


def _hsv(a):
    if len(a) == 1:
        h, s, v = a[0], 1.0, 1.0
    else:
        h, s, v = a[0], min(max(a[1], 0.0), 1.0), min(max(a[2], 0.0), 1.0)
    h = _sane(h) % 1.0
    out = []
    for n in (5.0, 3.0, 1.0):
        k = (n + 6.0 * h) % 6.0
        out.append(v - v * s * min(max(min(k, 4.0 - k), 0.0), 1.0))
    return tuple(out)


def _quant(v):
    return int(math.floor(_fold(_sane(v)) * 255.999))


def _div(a, b):
    if abs(b) < 1e-3:
        b = -1e-3 if b < 0 else 1e-3
    return a / b


def _exp_clipped(a, b):
    return math.exp(min(max(b * math.log(abs(a) + 1e-6), -30.0), 30.0))


_ONE = {
    "abs": lambda a: _map1(abs, a),
    "sin": lambda a: _map1(lambda v: 0.5 + 0.5 * math.sin(TWO_PI * v), a),
    "cos": lambda a: _map1(lambda v: 0.5 + 0.5 * math.cos(TWO_PI * v), a),
    "log": lambda a: _map1(lambda v: math.log(abs(v) + 1e-6), a),
    "atan": lambda a: _map1(lambda v: math.atan(v) / math.pi + 0.5, a),
    "round": lambda a: _map1(lambda v: float(math.floor(v + 0.5)), a),
    "invert": lambda a: _map1(lambda v: 1.0 - v, a),
    "hsv-to-rgb": _hsv,
}

_TWO = {
    "plus": lambda a, b: a + b,
    "minus": lambda a, b: a - b,
    "times": lambda a, b: a * b,
    "divide": _div,
    "mod": lambda a, b: a if abs(b) < 1e-3 else a % b,
    "expt": _exp_clipped,
    "min": min,
    "max": max,
}

_BITS = {"and": lambda u, v: u & v, "or": lambda u, v: u | v, "xor": lambda u, v: u ^ v}


# ---- dissolve, neighbourhoods and warps ----------------------------------------------------

def _dissolve(ref, x, y, p, a, b):
    ci = math.floor(_sane(x * T.DISSOLVE_CELLS + p[2])) % T.LATTICE
    cj = math.floor(_sane(y * T.DISSOLVE_CELLS + p[3])) % T.LATTICE
    amount = (p[0] + p[1] * ref.time) % 1.0
    pick = b if ref.table[cj, ci] < amount else a
    n3 = max(len(a), len(b))
    return pick * (n3 // len(pick))


def _band_pass(ref, p, grid, i, j):
    a, b = grid.blur(p[0])[i][j], grid.blur(3.0 * p[0])[i][j]
    return tuple(0.5 + u - v for u, v in zip(a, b))


def _bump(ref, p, grid, i, j):
    gx, gy = grid.gradient(i, j)
    a = TWO_PI * p[0]
    nx, ny = -gx * p[1], -gy * p[1]
    dot = (nx * math.cos(a) + ny * math.sin(a) + 1.0) / math.sqrt(2.0)
    return (max(dot / math.sqrt(nx * nx + ny * ny + 1.0), 0.0),)


def _grad_mag(ref, p, grid, i, j):
    return (p[0] * math.hypot(*grid.gradient(i, j)),)


def _grad_dir(ref, p, grid, i, j):
    gx, gy = grid.gradient(i, j)
    if max(abs(gx), abs(gy)) < P.FLAT_GRADIENT:  # a flat argument has no direction
        return (0.0,)
    return ((math.atan2(gy, gx) / TWO_PI) % 1.0,)


def _swirl(p, x, y):
    return _turn(x, y, p[0] * math.exp(-math.hypot(x - 0.5, y - 0.5) / max(p[1], 1e-3)))


def _warp_by(p, x, y, b):
    d0, d1 = (b[0], b[1]) if len(b) == 3 else (b[0], b[0])
    return x + p[0] * (d0 - 0.5), y + p[0] * (d1 - 0.5)


def _one(fn):
    return lambda ref, x, y, p, a: fn(a)


def _two(fn):
    return lambda ref, x, y, p, a, b: _map2(fn, a, b)


def _bits(op):
    return lambda ref, x, y, p, a, b: _map2(lambda u, v: op(_quant(u), _quant(v)) / 255.0, a, b)


for _table, _wrap in ((_TERMINALS, None), (_ONE, _one), (_TWO, _two), (_BITS, _bits)):
    for _name, _fn in _table.items():
        pixel_kernel(_name)(_fn if _wrap is None else _wrap(_fn))
for _name, _fn in (("dissolve", _dissolve), ("blur", lambda ref, p, grid, i, j: tuple(grid.blur(p[0])[i][j])),
                   ("band-pass", _band_pass), ("bump", _bump), ("grad-mag", _grad_mag), ("grad-dir", _grad_dir),
                   ("swirl", _swirl), ("rotate", lambda p, x, y: _turn(x, y, TWO_PI * p[0])),
                   ("warp-swirl", lambda p, x, y, b: _turn(x, y, p[0] * _grey(b)[0])), ("warp-by", _warp_by)):
    pixel_kernel(_name)(_fn)


def render_reference(genome: Genome, size: int | tuple[int, int] = (16, 16), *,
                     window: tuple[float, float, float, float] = (0.0, 0.0, 1.0, 1.0), time: float = 0.0) -> np.ndarray:
    """Evaluate ``genome`` pixel by pixel in Python floats.

    Args:
        genome: the genome.
        size: ``(height, width)`` or one int.
        window: world rectangle ``(x0, y0, x1, y1)``.
        time: animation time.
    Returns:
        ``(H, W, 3)`` float64 array in [0, 1] (the same final mapping as :func:`.evaluate.render`).
    """
    if not isinstance(genome, Genome):
        raise TypeError(f"genome: expected a Genome, got {type(genome).__name__}")
    H, W = parse_size(size)
    ref = _Reference(H, W, parse_window(window), parse_time(time))
    tree = genome.decode()
    out = np.empty((H, W, 3))
    for i in range(H):
        for j in range(W):
            v = ref.ev(tree, i, j, ref.base)
            v = v * 3 if len(v) == 1 else v
            out[i, j] = [_fold(_sane(c)) for c in v]
    return out
