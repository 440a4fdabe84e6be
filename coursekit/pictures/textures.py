"""Fixed data both picture evaluators share: the noise lattice and the pixel maps (section 3.1).

Noise is *value noise* on a 256 x 256 lattice of random values generated once from a fixed
seed, so a chromosome's noise is the same in every run, every window and both evaluators.
Each noise chromosome carries two offset parameters that shift where it reads the lattice:
that is what makes its field its own, and it is continuous, so interpolation can blend it.
Pixel maps are pictures that ship with scikit-image (nothing is downloaded).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .primitives import PIXMAPS

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
