"""Fixed data both picture evaluators share: the noise lattice, the pixel maps and the reach of
the neighbourhood primitives (section 3.1).

Noise is *value noise* on a 256 x 256 lattice of random values generated once from a fixed
seed, so a chromosome's noise is the same in every run, every window and both evaluators.
Each noise chromosome carries two offset parameters that shift where it reads the lattice:
that is what makes its field its own, and it is continuous, so interpolation can blend it.
Pixel maps are pictures that ship with scikit-image (nothing is downloaded).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .primitives import PIXMAPS, reach

LATTICE = 256
# Per-channel lattice offsets of color-noise, per-octave offsets of turbulence.
CHANNEL_SHIFT = ((0.0, 0.0), (57.3, 11.9), (23.1, 91.7))
OCTAVE_SHIFT = (19.7, 41.3)
DISSOLVE_CELLS = 64.0  # dissolve cells per world unit


@lru_cache(maxsize=1)
def noise_table() -> np.ndarray:
    """The (256, 256) float32 lattice of uniform [0, 1) values (seed 1991)."""
    return np.random.default_rng(1991).random((LATTICE, LATTICE)).astype(np.float32)


@lru_cache(maxsize=None)
def pixmap(index: int) -> np.ndarray:
    """Picture ``index`` of :data:`PIXMAPS` as a float32 (h, w, 3) array in [0, 1]."""
    import skimage.data

    img = getattr(skimage.data, PIXMAPS[index])()
    img = np.asarray(img, dtype=np.float32) / 255.0
    if img.ndim == 2:
        img = np.repeat(img[:, :, None], 3, axis=2)
    return np.ascontiguousarray(img[:, :, :3])


def preload() -> None:
    """Decode every stock picture of :data:`PIXMAPS` now (into :func:`pixmap`'s cache), so
    that the first render that shows one does not pay the decode (tens of milliseconds
    each). A gallery calls it when it starts, and each render worker when it starts.

    >>> preload()
    >>> pixmap.cache_info().currsize >= len(PIXMAPS)
    True
    """
    for i in range(len(PIXMAPS)):
        pixmap(i)


def pixmap_index(value: float) -> int:
    """The picture a ``pixmap`` parameter value selects: floor, clipped to the valid range."""
    return int(min(max(np.floor(value), 0), len(PIXMAPS) - 1))


def box_radius(sigma_px: float, limit: int) -> int:
    """Radius r of the box whose three passes have variance sigma**2 (r (r+1) = sigma**2)."""
    sigma_px = abs(float(sigma_px))
    sigma_px = min(sigma_px, 4.0 * limit + 4.0) if sigma_px == sigma_px else 0.0  # inf: the limit; NaN: none
    r = int(round((-1.0 + (1.0 + 4.0 * sigma_px * sigma_px) ** 0.5) / 2.0))
    return max(0, min(r, limit))


def _box_reach(scale: float):
    """The reach of three box passes of the radius :func:`box_radius` gives ``scale * sigma``
    (``sigma``: the first parameter, world units): 3 r pixels, per axis (``scale`` times sigma
    rounded as the blur rounds it, in float32)."""
    def reach_of(p, px, py, H, W):
        with np.errstate(over="ignore"):  # a hostile sigma overflows to inf, as in the blur
            s = abs(float(np.float32(scale) * np.float32(p[0]))) if scale != 1.0 else abs(float(p[0]))
        if s != s:  # NaN: no blur
            return 0, 0
        return 3 * box_radius(s / py, 4 * H), 3 * box_radius(s / px, 4 * W)
    return reach_of


# The gradients (``bump``, ``grad-mag``, ``grad-dir``) read one pixel on each side: they take
# one-sided differences on the window's edges instead (exact for a linear argument), which costs
# nothing, where extending the grid would evaluate their argument apart from the rest of the
# picture (a third more tensor operations in waves: ``benchmarks/NOTES.md``).
reach("blur")(_box_reach(1.0))
reach("band-pass")(_box_reach(3.0))  # its wider blur
