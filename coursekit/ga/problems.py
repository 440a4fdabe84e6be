"""Small benchmark problems for lessons and tests: OneMax and matching a target bitmap.

The simplest possible genotype/phenotype pair (paper section 1): the genotype is a string of
bits, the phenotype is the picture those bits draw, and the fitness is how close the picture is
to a target. Everything here is defined at module top level so it pickles into worker processes.
"""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from .selection import _check_rng

__all__ = ["onemax", "TargetMatch", "random_bits", "smiley"]


def onemax(genome: ArrayLike) -> float:
    """OneMax: the fraction of ones in a bit string (optimum 1.0 at all ones)."""
    g = np.asarray(genome)
    if g.dtype.kind not in "biuf":
        raise TypeError(f"onemax: genome must be an array of 0/1 bits, got {type(genome).__name__}")
    return float(g.mean()) if g.size else 0.0


class TargetMatch:
    """Fitness = fraction of bits equal to a target (e.g. a flattened bitmap).

    Args:
        target: array of 0/1 values; genomes are compared with ``target.ravel()``.
    """

    def __init__(self, target: ArrayLike) -> None:
        t = np.asarray(target)
        if t.size == 0 or t.dtype.kind not in "biuf" or not np.isin(t, (0, 1)).all():
            raise ValueError(f"target: expected a non-empty array of 0/1 values, got {_shown(target)}")
        self.target = t.astype(np.int8).ravel()

    def __call__(self, genome) -> float:
        g = np.asarray(genome)
        if g.shape != self.target.shape:
            raise ValueError(f"genome: expected shape {self.target.shape} (the target's), got {g.shape}")
        return float(np.mean(g == self.target))

    def __repr__(self) -> str:
        return f"TargetMatch(<{self.target.size} bits>)"


def _shown(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _check_size(name: str, value, low: int) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ValueError(f"{name}: must be an integer >= {low}, got {value!r}")
    return int(value)


def random_bits(rng: np.random.Generator, n: int, length: int) -> list:
    """``n`` random bit strings (``int8`` arrays of 0/1) of ``length`` bits."""
    rng = _check_rng(rng)
    n, length = _check_size("n", n, 0), _check_size("length", length, 0)
    return list(rng.integers(0, 2, size=(n, length), dtype=np.int8))


def smiley(size: int = 16) -> np.ndarray:
    """A ``size x size`` 0/1 bitmap of a smiley face (1 = ink): the lesson's target picture."""
    from skimage.draw import circle_perimeter, disk, ellipse_perimeter

    size = _check_size("size", size, 1)
    img = np.zeros((size, size), dtype=np.int8)
    c, r = (size - 1) / 2, size / 2 - 1
    rr, cc = circle_perimeter(round(c), round(c), round(r), shape=img.shape)
    img[rr, cc] = 1
    for x in (c - r * 0.4, c + r * 0.4):
        rr, cc = disk((c - r * 0.35, x), max(1.0, r * 0.14), shape=img.shape)
        img[rr, cc] = 1
    rr, cc = ellipse_perimeter(round(c + r * 0.2), round(c), max(1, round(r * 0.35)), max(1, round(r * 0.55)), shape=img.shape)
    keep = rr > c + r * 0.2
    img[rr[keep], cc[keep]] = 1
    return img
