"""Fitness evaluation: judging every phenotype (paper section 1, "a fitness function is required
which judges from the quality of a phenotype"), serially or in parallel.

Evaluation is the expensive part of a GA (a creature is a physics simulation), and it is
embarrassingly parallel. :func:`evaluate` runs ``fitness(genome)`` over a list of genomes
through one of:

- nothing: the builtin ``map`` (serial, in this process; lambdas are fine);
- ``map=``: any ``map(func, iterable) -> iterable`` callable -- ``multiprocessing.Pool.map``, a
  Ray pool's map, or your own batching function that simulates many genomes at once;
- ``executor=``: a ``concurrent.futures.Executor`` (``ProcessPoolExecutor``,
  ``ThreadPoolExecutor``) or a Dask ``distributed.Client``.

Results always come back in the order of the genomes, whatever order the workers finish in, so
a run gives the same history on every back end. With processes, ``fitness`` and the genomes
must pickle (define the fitness function at module top level).
"""

from __future__ import annotations

import math
import numbers
import os
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import numpy as np

__all__ = ["evaluate", "is_dask_client", "parallel_map", "workers"]


def is_dask_client(obj: object) -> bool:
    """True if ``obj`` is a ``distributed.Client`` (checked without importing Dask otherwise)."""
    if type(obj).__module__.split(".")[0] != "distributed":
        return False
    from distributed import Client

    return isinstance(obj, Client)


def parallel_map(func: Callable, items: Sequence, executor: Any, *, chunksize: int = 1) -> list:
    """``[func(x) for x in items]`` on ``executor`` (a ``concurrent.futures.Executor`` or a Dask
    ``distributed.Client``), in order; ``chunksize`` items travel together to a process."""
    if is_dask_client(executor):
        return executor.gather(executor.map(func, items, pure=False))
    if hasattr(executor, "submit") and hasattr(executor, "map"):
        return list(executor.map(func, items, chunksize=chunksize))
    raise TypeError(f"executor: expected a concurrent.futures.Executor or a dask distributed.Client, got {type(executor).__name__}")


def workers(executor: Any) -> int:
    """How many tasks ``executor`` runs at once (its processes or Dask threads)."""
    if is_dask_client(executor):
        return max(1, sum(executor.nthreads().values()))
    return max(1, int(getattr(executor, "_max_workers", None) or os.cpu_count() or 1))


def evaluate(fitness: Callable, genomes: Sequence, *, map: Callable | None = None,
             executor: Any | None = None) -> np.ndarray:
    """Fitness of each genome, in order.

    Args:
        fitness: ``fitness(genome) -> float`` (higher is better).
        genomes: the genomes to evaluate.
        map: a ``map(func, iterable)`` callable; exclusive with ``executor``.
        executor: a ``concurrent.futures.Executor`` or a Dask ``distributed.Client``.
    Returns:
        float64 array, ``out[i] = fitness(genomes[i])``.
    Raises:
        ValueError: if a fitness is not finite, or the map returns the wrong number of results.
        TypeError: if a fitness is not a real number.
    """
    if map is not None and executor is not None:
        raise ValueError("map/executor: give at most one of map= and executor=")
    if not callable(fitness):
        raise TypeError(f"fitness: expected a callable fitness(genome) -> float, got {type(fitness).__name__}")
    if isinstance(genomes, (str, bytes)) or not isinstance(genomes, Iterable):
        raise TypeError(f"genomes: expected a list of genomes, got {type(genomes).__name__}")
    genomes = list(genomes)
    if not genomes:
        return np.zeros(0, dtype=np.float64)
    if map is not None:
        if not callable(map):
            raise TypeError(f"map: expected a map(func, iterable) callable, got {type(map).__name__}")
        results = list(map(fitness, genomes))
    elif executor is None:
        results = [fitness(g) for g in genomes]
    else:
        results = parallel_map(fitness, genomes, executor, chunksize=max(1, math.ceil(len(genomes) / 32)))
    if len(results) != len(genomes):
        raise ValueError(f"map: returned {len(results)} fitness values for {len(genomes)} genomes")
    out = np.empty(len(genomes), dtype=np.float64)
    for i, r in enumerate(results):
        if isinstance(r, (bool, np.bool_)) or not isinstance(r, (numbers.Real, np.number)) or isinstance(r, np.complexfloating):
            raise TypeError(f"fitness: genome #{i} got fitness {r!r} of type {type(r).__name__}; expected a real number")
        out[i] = float(r)
        if not math.isfinite(out[i]):
            raise ValueError(
                f"fitness: genome #{i} got fitness {float(out[i])!r}; fitness must be finite (score failures as a low finite value)"
            )
    return out
