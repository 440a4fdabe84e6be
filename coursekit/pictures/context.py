"""Coordinate contexts and per-device resources of the whole-image evaluator (paper section 3.2).

A :class:`Context` is where a tree is evaluated: the world coordinates ``x`` and ``y`` of the
pixel centres, the image size, a pixel's world size, the time, the device's :class:`Resources`
and the render's memo of shared subtree values. ``x`` is ``(1, 1, 1, W)`` and ``y`` is
``(1, 1, H, 1)`` in the unwarped context; a coordinate transform makes a new context whose
coordinates may be whole images, one per genome. A neighbourhood primitive evaluates its
argument in the context *extended* (``pad``) beyond the window by its reach, the same coordinates
on more pixels (:func:`~.tree.padded`). A context is *separable* when ``x`` varies
along columns only and ``y`` along rows only (:func:`separable`, the one test for it): noise and
pixel maps then sample rows, then columns, which is exact and much cheaper than per pixel.

:class:`Resources` keeps, per device, what every render reads: the noise lattice, the stock
pictures, banded blur matrices, and unwarped pixel maps already sampled (per size and window,
least recently used first out). :func:`to_rgb` is the documented final mapping.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import ClassVar

import torch

from . import textures as T

__all__ = ["BIG", "Context", "Resources", "CACHE_BYTES", "clear_cache", "default_device", "separable", "sane", "fmod",
           "fold", "to_rgb", "host", "upload"]

BIG = 1e6  # values are clipped to +-BIG before indexing, integer operations and the final mapping


def default_device() -> torch.device:
    """CUDA when present, else CPU."""
    return torch.device("cuda" if torch.cuda.is_available() else "cpu")


#: torch.tensor, bound here: :func:`upload` is the deliberate copy to the device, which
#: :class:`~coursekit.operations.CountHostSyncs` does not count.
_from_host = torch.tensor


def upload(values, device, dtype=torch.float32) -> torch.Tensor:
    """Host numbers as a tensor on ``device``; to a GPU through pinned memory without waiting (a
    plain copy from pageable memory makes the host wait for the device)."""
    t = _from_host(values, dtype=dtype)
    if torch.device(device).type != "cuda":
        return t.to(device)
    return t.pin_memory().to(device, non_blocking=True)


def host(p: torch.Tensor) -> list[float]:
    """The values of a parameter ``p`` (B, 1, 1, 1) as Python floats, from the host copy that
    :func:`~.tree.stack_trees` keeps beside the device tensor (``p.host``): a kernel that needs a
    parameter as a number (a blur's radius, a pixel map's index, an octave count) reads no device
    memory. A tensor without one (a kernel called directly) is read from the device."""
    values = getattr(p, "host", None)
    return list(values) if values is not None else [float(v) for v in p.reshape(-1).tolist()]


def separable(x: torch.Tensor, y: torch.Tensor, *, shared: bool = False) -> bool:
    """Whether coordinates ``x`` vary along columns only and ``y`` along rows only (the unwarped
    context, or one a warp by a uniform displacement left so); ``shared``: and they are the same
    for every image of the batch (one row of ``x``, one column of ``y``)."""
    if shared:
        return x.shape[:3] == (1, 1, 1) and y.shape[0] == 1 and y.shape[3] == 1
    return x.shape[-2] == 1 and y.shape[-1] == 1


@dataclass
class Context:
    """Where a tree is evaluated (see the module docstring)."""

    x: torch.Tensor  # broadcastable to (B, 1, H, W)
    y: torch.Tensor
    H: int
    W: int
    px: float  # world width of a pixel
    py: float
    time: float
    res: Resources
    memo: object  # shared subtree values (:class:`.tree.Memo`), shared by derived contexts
    key: tuple | None = None  # (H, W, window) of the unwarped context: its terminals are cached
    frame: tuple | None = None  # (x0, y0, signed px, signed py, H, W) of the picture's window
    pad: tuple = (0, 0)  # rows and columns on each side beyond the window (:func:`.tree.padded`)
    origin: tuple | None = None  # (warp node, context it was made in); None: unwarped
    variants: dict = field(default_factory=dict, repr=False)  # padded and warped contexts made from this one

    def with_coords(self, x, y, memo=None) -> Context:
        """The context at new coordinates (NaN -> 0 and clipped), same image and time."""
        return self.moved(sane(x), sane(y), memo=memo)

    def moved(self, x, y, origin=None, memo=None) -> Context:
        """The context at coordinates ``x``, ``y`` as they are (same image, time and extension),
        made by ``origin`` (a warp node and the context it was made in)."""
        return Context(x, y, self.H, self.W, self.px, self.py, self.time, self.res,
                       self.memo if memo is None else memo, frame=self.frame, pad=self.pad, origin=origin)

    @property
    def picture(self) -> tuple[int, int]:
        """The picture's size ``(H, W)`` (``H``, ``W`` include the extension, :attr:`pad`)."""
        return (self.frame[4], self.frame[5]) if self.frame is not None else (self.H, self.W)

    @property
    def separable(self) -> bool:
        """:func:`separable` coordinates shared by the whole batch (sampled by rows and columns
        as they are; stacking them would turn that into per-pixel sampling)."""
        return separable(self.x, self.y, shared=True)


TILE = 32  # output rows per tile of a banded blur matrix (measured best at 256^2)
CACHE_BYTES = 64 << 20  # unwarped terminal images kept across renders (per device)


class Resources:
    """Per device: noise lattice, pixel maps, blur matrices and sampled unwarped pixel maps."""

    _cache: ClassVar[dict] = {}

    def __init__(self, device):
        self.device = device
        self.table = torch.from_numpy(T.noise_table()).to(device)
        wrapped = torch.cat([self.table, self.table[:1]], dim=0)
        self.wrapped = torch.cat([wrapped, wrapped[:, :1]], dim=1)[None, None].contiguous()
        self.box_matrices: dict = {}
        self.pixmaps: dict[int, torch.Tensor] = {}
        self._sampled: OrderedDict = OrderedDict()
        self._sampled_bytes = 0
        self._lock = threading.Lock()

    @classmethod
    def on(cls, device) -> Resources:
        key = str(device)
        if key not in cls._cache:
            cls._cache[key] = cls(device)
        return cls._cache[key]

    def box_matrix(self, n: int, r: int) -> list:
        """Three replicate-border box passes of radius r as a banded (n, n) matrix M, cut
        into row tiles: ``[(lo, hi, M[t0:t1, lo:hi]), ...]`` where columns outside
        ``lo:hi`` are zero in those rows (one tile, the whole matrix, when the band is wide)."""
        key = (n, r)
        if key not in self.box_matrices:
            b = torch.zeros(n, n, dtype=torch.float64)
            rows = torch.arange(n).repeat_interleave(2 * r + 1)
            cols = (torch.arange(n)[:, None] + torch.arange(-r, r + 1)[None, :]).clamp(0, n - 1).reshape(-1)
            b.index_put_((rows, cols), torch.full_like(rows, 1.0 / (2 * r + 1), dtype=torch.float64),
                         accumulate=True)
            m = (b @ b @ b).float().to(self.device)
            spans = [(t0, min(n, t0 + TILE), max(0, t0 - 3 * r), min(n, t0 + TILE + 3 * r))
                     for t0 in range(0, n, TILE)]
            if sum((t1 - t0) * (hi - lo) for t0, t1, lo, hi in spans) > 0.6 * n * n:
                spans = [(0, n, 0, n)]  # wide band: one dense product is faster
            self.box_matrices[key] = [(lo, hi, m[t0:t1, lo:hi].contiguous()) for t0, t1, lo, hi in spans]
        return self.box_matrices[key]

    def sampled(self, key, compute) -> torch.Tensor:
        """``compute()``, cached under ``key`` (least recently used first out, at most
        :data:`CACHE_BYTES`); ``key=None`` computes without caching. Thread-safe."""
        if key is None:
            return compute()
        with self._lock:
            if key in self._sampled:
                self._sampled.move_to_end(key)
                return self._sampled[key]
        value = compute()
        size = value.numel() * value.element_size()
        with self._lock:
            if key not in self._sampled and size <= CACHE_BYTES // 4:
                self._sampled[key] = value
                self._sampled_bytes += size
                while self._sampled_bytes > CACHE_BYTES:
                    _, old = self._sampled.popitem(last=False)
                    self._sampled_bytes -= old.numel() * old.element_size()
        return value

    def pixmap(self, i: int) -> torch.Tensor:
        if i not in self.pixmaps:
            # planar (N, C, H, W) storage: separable sampling is 2.5x faster than on interleaved RGB
            self.pixmaps[i] = torch.from_numpy(T.pixmap(i)).permute(2, 0, 1)[None].contiguous().to(self.device)
        return self.pixmaps[i]


def clear_cache() -> None:
    """Forget the cached unwarped pixel maps on every device (renders stay identical)."""
    for res in Resources._cache.values():
        with res._lock:
            res._sampled.clear()
            res._sampled_bytes = 0


def sane(v: torch.Tensor) -> torch.Tensor:
    """NaN -> 0 and clip to +-1e6 (inputs of indexing and integer operations)."""
    return torch.nan_to_num(v, nan=0.0, posinf=BIG, neginf=-BIG).clamp_(-BIG, BIG)


def fmod(v: torch.Tensor, m) -> torch.Tensor:
    """Floored modulo v - m floor(v / m) (sign of m, like Python's %), cheaper than remainder."""
    if isinstance(m, float):
        return torch.sub(v, torch.floor(v / m), alpha=m)
    return v - m * torch.floor(v / m)


def fold(v: torch.Tensor) -> torch.Tensor:
    """Mirror-repeat into [0, 1] with period 2: ``|v - 2 round(v / 2)|`` (= ``1 - |(v mod 2) - 1|``)."""
    return torch.sub(v, (v * 0.5).round_(), alpha=2.0).abs_()


def to_rgb(v: torch.Tensor, H: int, W: int) -> torch.Tensor:
    """The documented final mapping: any value -> (B, 3, H, W) float32 in [0, 1]."""
    v = fold(sane(v.float()))
    return v.expand(v.shape[0], 3, H, W)
