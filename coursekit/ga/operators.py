"""Reference variation operators for 1-D numpy genomes (paper section 1: "recombination of pairs
of vectors and mutation of singles").

These are the two operator shapes every lab uses -- unary ``mutate(genome, rng) -> genome`` and
binary ``crossover(a, b, rng) -> (child1, child2)`` -- implemented for the simplest genomes: 1-D
arrays of bits or small integers. Students re-implement them in ``exercises/01_selection.ipynb``.
Operators never modify their inputs.
"""

from __future__ import annotations

import numbers

import numpy as np
from numpy.typing import ArrayLike

from .selection import _check_rng

__all__ = ["point_mutation", "one_point_crossover"]


def _check_genome(name: str, genome) -> np.ndarray:
    if not isinstance(genome, np.ndarray):
        raise TypeError(f"{name}: expected a 1-D numpy array, got {type(genome).__name__}")
    if genome.ndim != 1:
        raise ValueError(f"{name}: expected a 1-D numpy array, got shape {genome.shape}")
    if genome.dtype.kind not in "biu":
        raise TypeError(f"{name}: expected a bool or integer array of bits, got dtype {genome.dtype}")
    return genome


def point_mutation(genome: ArrayLike, rng: np.random.Generator, rate: float | None = None) -> np.ndarray:
    """Flip each bit independently with probability ``rate``.

    Args:
        genome: 1-D numpy array of 0/1 values (bool or integer dtype).
        rng: ``numpy.random.Generator``.
        rate: per-bit flip probability in [0, 1]; default ``1 / len(genome)`` (one flip expected).
    Returns:
        A new array, same shape and dtype.

    >>> point_mutation(np.zeros(8, dtype=np.int8), np.random.default_rng(1), rate=0.5).tolist()
    [0, 0, 1, 0, 1, 1, 0, 1]
    """
    genome = _check_genome("genome", genome)
    rng = _check_rng(rng)
    if genome.dtype != bool:
        not_bit = (genome != 0) & (genome != 1)
        if not_bit.any():
            i = int(np.flatnonzero(not_bit)[0])
            raise ValueError(f"genome: expected bits (0 or 1), got {genome[i]} at index {i}")
    if genome.size == 0:
        return genome.copy()
    if rate is None:
        rate = 1.0 / genome.size
    if isinstance(rate, bool) or not isinstance(rate, numbers.Real) or not 0.0 <= rate <= 1.0:
        raise ValueError(f"rate: expected a probability in [0, 1], got {rate!r}")
    flip = rng.random(genome.size) < rate
    child = genome.copy()
    if child.dtype == bool:
        child[flip] = ~child[flip]
    else:
        child[flip] = 1 - child[flip]
    return child


def one_point_crossover(a: ArrayLike, b: ArrayLike, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Cut both parents at one random point and swap the tails.

    The cut ``c`` is drawn uniformly from ``1 .. len - 1`` (so both children mix both parents);
    ``child1 = a[:c] + b[c:]`` and ``child2 = b[:c] + a[c:]``. Parents of length < 2 are copied.

    Args:
        a, b: 1-D numpy arrays of equal length and dtype.
        rng: ``numpy.random.Generator``.
    Returns:
        ``(child1, child2)``, new arrays.

    >>> c1, c2 = one_point_crossover(np.zeros(6, int), np.ones(6, int), np.random.default_rng(0))
    >>> c1.tolist(), c2.tolist()
    ([0, 0, 0, 0, 0, 1], [1, 1, 1, 1, 1, 0])
    """
    a = _check_genome("a", a)
    b = _check_genome("b", b)
    if a.shape != b.shape or a.dtype != b.dtype:
        raise ValueError(f"b: parents must have the same length and dtype, got {a.shape}/{a.dtype} and {b.shape}/{b.dtype}")
    rng = _check_rng(rng)
    if a.size < 2:
        return a.copy(), b.copy()
    cut = int(rng.integers(1, a.size))
    return np.concatenate([a[:cut], b[cut:]]), np.concatenate([b[:cut], a[cut:]])
