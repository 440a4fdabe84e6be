"""Selection: who gets to reproduce ("survival of the fittest", paper section 1; Sims 1994 section 6).

Every selector has the shape ``select(fitness, k, rng, **params) -> indices``: ``fitness`` is a
1-D array of finite floats (higher is better), ``k`` is how many parents to pick, and the result
is a numpy ``int64`` array of ``k`` indices into the population (an index may repeat). Selectors
never look at genomes, so the same functions drive bit strings, pictures and creatures.

- :func:`truncation` -- uniform among the best ``ceil(survival * n)`` ("top fifth" with 0.2);
- :func:`tournament` -- best of ``size`` random contestants, ``k`` times;
- :func:`roulette` -- fitness-proportional (roulette wheel) sampling;
- :func:`sims_offspring` / :func:`sims_select` -- Sims 1994: the top fifth survive and each
  survivor gets a number of offspring proportional to its fitness (deterministic counts).

Elitism is not a selector: it is the ``elite=`` argument of :func:`coursekit.ga.evolve`.
Ranking ties are always broken towards the lower index, so results are reproducible.
"""

from __future__ import annotations

import math
import numbers

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["truncation", "tournament", "roulette", "sims_offspring", "sims_select", "ranking"]


def _check_fitness(fitness) -> np.ndarray:
    f = np.asarray(fitness)
    if f.ndim != 1:
        raise ValueError(f"fitness: expected a 1-D array of floats, got shape {f.shape}")
    if f.size == 0:
        raise ValueError("fitness: the population is empty (0 fitness values); need at least 1")
    if f.dtype.kind not in "biuf":
        raise TypeError(f"fitness: expected real numbers, got dtype {f.dtype}")
    f = f.astype(np.float64, copy=False)
    bad = ~np.isfinite(f)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise ValueError(f"fitness: value {float(f[i])!r} at index {i} is not finite; all fitness values must be finite")
    return f


def _check_count(name: str, k) -> int:
    if isinstance(k, bool) or not isinstance(k, numbers.Integral):
        raise TypeError(f"{name}: expected a non-negative int, got {k!r} ({type(k).__name__})")
    if k < 0:
        raise ValueError(f"{name}: expected a non-negative int, got {k}")
    return int(k)


def _check_rng(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    return rng


def _check_survival(survival) -> float:
    if isinstance(survival, bool) or not isinstance(survival, numbers.Real) or not (0.0 < float(survival) <= 1.0):
        raise ValueError(f"survival: expected a fraction in (0, 1], got {survival!r}")
    return float(survival)


def ranking(fitness: ArrayLike) -> np.ndarray:
    """Indices of the population from best to worst (ties: lower index first).

    Args:
        fitness: 1-D array of finite fitness values.
    Returns:
        ``int64`` array, a permutation of ``range(n)``.

    >>> ranking([1.0, 3.0, 3.0, 2.0]).tolist()
    [1, 2, 3, 0]
    """
    f = _check_fitness(fitness)
    return np.argsort(-f, kind="stable").astype(np.int64)


def n_survivors(n: int, survival: float) -> int:
    """How many of ``n`` individuals survive truncation: ``ceil(survival * n)`` (at least 1)."""
    # round() first so that e.g. 0.2 * 300 = 60.00000000000001 does not become 61
    return max(1, math.ceil(round(survival * n, 9)))


def truncation(fitness: ArrayLike, k: int, rng: np.random.Generator, survival: float = 0.2) -> np.ndarray:
    """Truncation selection: parents drawn uniformly, with replacement, from the best survivors.

    Args:
        fitness: 1-D array of finite fitness values (higher is better).
        k: number of parents to return.
        rng: ``numpy.random.Generator``.
        survival: fraction of the population that survives, in (0, 1]; the best
            ``ceil(survival * n)`` individuals (ties: lower index) are the survivors.
    Returns:
        ``int64`` array of ``k`` indices, all among the survivors.

    >>> truncation([0.1, 0.9, 0.5, 0.3], 3, np.random.default_rng(0), survival=0.25).tolist()
    [1, 1, 1]
    """
    f = _check_fitness(fitness)
    k = _check_count("k", k)
    rng = _check_rng(rng)
    survival = _check_survival(survival)
    survivors = ranking(f)[: n_survivors(f.size, survival)]
    return survivors[rng.integers(0, survivors.size, size=k)]


def tournament(fitness: ArrayLike, k: int, rng: np.random.Generator, size: int = 3) -> np.ndarray:
    """Tournament selection: ``k`` independent tournaments of ``size`` contestants each.

    Contestants are drawn uniformly with replacement; the fittest contestant wins (ties: the
    lowest population index). The best individual wins a tournament with probability
    ``1 - (1 - 1/n)**size``.

    Args:
        fitness: 1-D array of finite fitness values (higher is better).
        k: number of parents (tournaments).
        rng: ``numpy.random.Generator``.
        size: contestants per tournament, ``>= 1`` (1 is uniform random selection).
    Returns:
        ``int64`` array of ``k`` indices.
    """
    f = _check_fitness(fitness)
    k = _check_count("k", k)
    rng = _check_rng(rng)
    if isinstance(size, bool) or not isinstance(size, numbers.Integral) or size < 1:
        raise ValueError(f"size: tournament size must be an int >= 1, got {size!r}")
    contestants = rng.integers(0, f.size, size=(k, int(size)))
    scores = f[contestants]
    is_best = scores == scores.max(axis=1, keepdims=True)
    return np.where(is_best, contestants, f.size).min(axis=1).astype(np.int64)


def roulette(fitness: ArrayLike, k: int, rng: np.random.Generator) -> np.ndarray:
    """Fitness-proportional ("roulette wheel") selection.

    Each of the ``k`` draws picks individual ``i`` with probability ``f_i / sum(f)``. If every
    fitness is zero the draw is uniform.

    Args:
        fitness: 1-D array of finite, non-negative fitness values.
        k: number of parents.
        rng: ``numpy.random.Generator``.
    Returns:
        ``int64`` array of ``k`` indices.
    Raises:
        ValueError: if any fitness is negative (shift or rank your fitness first).
    """
    f = _check_fitness(fitness)
    k = _check_count("k", k)
    rng = _check_rng(rng)
    if (f < 0).any():
        i = int(np.flatnonzero(f < 0)[0])
        raise ValueError(f"fitness: roulette selection needs non-negative fitness, got {float(f[i])!r} at index {i}")
    total = f.sum()
    if total == 0:
        return rng.integers(0, f.size, size=k).astype(np.int64)
    cumulative = np.cumsum(f / total)
    cumulative[-1] = 1.0
    draws = rng.random(k)
    # side="right": a draw u picks the first i with cumulative[i] > u, so zero-fitness
    # individuals (empty slots on the wheel) are never picked.
    return np.minimum(np.searchsorted(cumulative, draws, side="right"), f.size - 1).astype(np.int64)


def sims_offspring(fitness: ArrayLike, n_offspring: int, survival: float = 0.2) -> np.ndarray:
    """Sims 1994 reproduction counts: survivors get offspring in proportion to their fitness.

    The best ``ceil(survival * n)`` individuals survive (Sims: the top fifth). Survivor ``i``
    gets a quota ``n_offspring * f_i / sum(f_survivors)``; counts are the quotas rounded by the
    largest-remainder method (floors first, then one more each for the largest fractional
    parts; ties go to the better-ranked survivor), so they sum to exactly ``n_offspring``. If
    all survivors have zero fitness they share equally.

    Args:
        fitness: 1-D array of finite fitness values; survivors' fitness must be non-negative.
        n_offspring: total number of offspring to share out.
        survival: surviving fraction in (0, 1].
    Returns:
        ``int64`` array of length ``n`` (one count per individual; 0 for non-survivors),
        summing to ``n_offspring``. Deterministic: no rng.

    >>> sims_offspring([4.0, 0.0, 1.0, 3.0, 2.0], 10, survival=0.6).tolist()
    [5, 0, 0, 3, 2]
    """
    f = _check_fitness(fitness)
    n_offspring = _check_count("n_offspring", n_offspring)
    survival = _check_survival(survival)
    survivors = ranking(f)[: n_survivors(f.size, survival)]
    fs = f[survivors]
    if (fs < 0).any():
        raise ValueError(f"fitness: offspring proportional to fitness need non-negative survivor fitness, got {float(fs.min())!r}")
    total = fs.sum()
    shares = fs / total if total > 0 else np.full(fs.size, 1.0 / fs.size)
    quotas = n_offspring * shares
    counts = np.floor(quotas).astype(np.int64)
    missing = n_offspring - int(counts.sum())
    if missing:
        remainders = quotas - counts
        order = np.argsort(-remainders, kind="stable")  # survivors are already in rank order
        counts[order[:missing]] += 1
    out = np.zeros(f.size, dtype=np.int64)
    out[survivors] = counts
    return out


def sims_select(fitness: ArrayLike, k: int, rng: np.random.Generator, survival: float = 0.2) -> np.ndarray:
    """Selector built on :func:`sims_offspring`: survivor ``i`` appears ``counts[i]`` times.

    Usable as ``evolve(..., select=sims_select)``; with ``elite=ceil(survival * n)`` this is
    Sims' scheme exactly (survivors are kept, the rest of the population are their offspring).
    The parent list is shuffled with ``rng`` so that pairing for crossover is random.

    Args:
        fitness: 1-D array of finite fitness values (survivors' non-negative).
        k: number of parents (offspring slots).
        rng: ``numpy.random.Generator`` (used only to shuffle the order).
        survival: surviving fraction in (0, 1].
    Returns:
        ``int64`` array of ``k`` indices, index ``i`` occurring exactly ``sims_offspring(...)[i]`` times.
    """
    k = _check_count("k", k)
    rng = _check_rng(rng)
    counts = sims_offspring(fitness, k, survival=survival)
    return rng.permutation(np.repeat(np.arange(counts.size, dtype=np.int64), counts))
