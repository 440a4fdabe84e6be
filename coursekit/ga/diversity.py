"""Diversity of a population: how much genetic variety is left for selection to work on
(paper section 1; a population that has converged to copies of one genome has stopped searching).

A diversity function maps a population (a list of opaque genomes) to one float and is
recorded in :class:`coursekit.ga.History` every generation. The default,
:func:`distinct_fraction`, needs nothing from the genome but that it pickles; labs with a
meaningful genome distance can use :func:`mean_pairwise` instead.
"""

from __future__ import annotations

import hashlib
import itertools
import pickle
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["genome_digest", "distinct_fraction", "mean_pairwise", "hamming"]


def genome_digest(genome: Any) -> str:
    """A stable hex digest of a genome: equal genomes give equal digests, in any process.

    numpy arrays hash their dtype, shape and bytes; anything else hashes its pickle.
    """
    h = hashlib.sha256()
    if isinstance(genome, np.ndarray):
        h.update(f"ndarray:{genome.dtype.str}:{genome.shape}:".encode())
        h.update(np.ascontiguousarray(genome).tobytes())
    else:
        h.update(pickle.dumps(genome, protocol=5))
    return h.hexdigest()


def distinct_fraction(population: Sequence) -> float:
    """Fraction of distinct genomes: 1.0 if all differ, ``1/n`` if all are copies of one.

    >>> distinct_fraction([np.array([0, 1]), np.array([0, 1]), np.array([1, 1]), np.array([0, 0])])
    0.75
    """
    if not hasattr(population, "__len__") or isinstance(population, (str, bytes)):
        raise TypeError(f"population: expected a sequence of genomes, got {type(population).__name__}")
    if len(population) == 0:
        return 0.0
    return len({genome_digest(g) for g in population}) / len(population)


def mean_pairwise(distance: Callable) -> Callable[[Sequence], float]:
    """Build a diversity function: the mean of ``distance(a, b)`` over all unordered pairs.

    Args:
        distance: ``distance(a, b) -> float`` between two genomes.
    Returns:
        ``diversity(population) -> float`` (0.0 for populations of fewer than 2).

    >>> mean_pairwise(hamming)([np.array([0, 0]), np.array([0, 1]), np.array([1, 1])])
    0.6666666666666666
    """
    if not callable(distance):
        raise TypeError(f"distance: expected a callable distance(a, b) -> float, got {type(distance).__name__}")

    def diversity(population: Sequence) -> float:
        if len(population) < 2:
            return 0.0
        return float(np.mean([distance(a, b) for a, b in itertools.combinations(population, 2)]))

    diversity.__name__ = f"mean_pairwise({getattr(distance, '__name__', 'distance')})"
    return diversity


def hamming(a: ArrayLike, b: ArrayLike) -> float:
    """Fraction of positions where two equal-length 1-D arrays differ."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape != b.shape:
        raise ValueError(f"b: genomes must have the same shape for a Hamming distance, got {a.shape} and {b.shape}")
    return float(np.mean(a != b)) if a.size else 0.0
