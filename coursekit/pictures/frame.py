"""The frame of a picture: its size in pixels, the world window it shows (paper section 3.2) and
its animation time.

Both evaluators (:mod:`.evaluate`, :mod:`.reference`) read ``size``, ``window`` and ``time``
through these functions, so a bad value gets the same clear error from either.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = ["MAX_PIXELS", "parse_size", "parse_window", "parse_time"]

MAX_PIXELS = 4096 * 4096  # pixels of one rendered picture at most (a 4096^2 poster: 192 MiB of float32)


def parse_size(size: int | tuple[int, int]) -> tuple[int, int]:
    """``(height, width)`` from an int or a pair of positive ints (ValueError naming ``size``)."""
    if isinstance(size, (int, np.integer)) and not isinstance(size, bool):
        size = (size, size)
    try:
        h, w = (int(v) for v in size)
        ok = all(float(v) == int(v) for v in size)
    except (TypeError, ValueError):
        ok = False
    if not ok or h < 1 or w < 1:
        raise ValueError(f"size: {size!r} must be an int or (height, width) of positive ints")
    if h * w > MAX_PIXELS:
        raise ValueError(f"size: {h} x {w} is {h * w:,} pixels; a picture has at most {MAX_PIXELS:,} "
                         f"(4096 x 4096): render a smaller size, or zoom with window= and tile")
    return h, w


def parse_window(window: Sequence[float]) -> tuple[float, float, float, float]:
    """``(x0, y0, x1, y1)`` as floats, finite, with a non-empty extent (ValueError naming ``window``)."""
    try:
        x0, y0, x1, y1 = (float(v) for v in window)
    except (TypeError, ValueError):
        raise ValueError(f"window: {window!r} must be (x0, y0, x1, y1)") from None
    if not all(math.isfinite(v) for v in (x0, y0, x1, y1)) or x0 == x1 or y0 == y1:
        raise ValueError(f"window: {window!r} must be finite with x0 != x1 and y0 != y1")
    return x0, y0, x1, y1


def parse_time(time: float) -> float:
    """``time`` as a finite float (ValueError naming ``time``)."""
    if isinstance(time, (bool, np.bool_)) or not isinstance(time, (int, float, np.integer, np.floating)) or not math.isfinite(time):
        raise ValueError(f"time: {time!r} must be a finite number")
    return float(time)
