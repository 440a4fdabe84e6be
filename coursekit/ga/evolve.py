"""The evolution loop: evaluate -> select -> vary, generation after generation (paper section 1:
"take a set of random vectors ... and let them develop by simulating evolution"; Sims 1994
section 6 for survivors, offspring and the reproduction mix).

One generation of :func:`evolve`:

1. the ``elite`` best individuals (ties: lower index) are copied unchanged, keeping their fitness;
2. ``select(fitness, n - elite, rng)`` picks parent indices;
3. ``vary(parents, rng)`` makes ``n - elite`` children (e.g. a :class:`~coursekit.ga.Variation`);
4. only the children are evaluated (see :mod:`coursekit.ga.evaluation` for parallel back ends);
5. the new population is ``elites + children``; its statistics go to the :class:`History`, the
   state is checkpointed (atomically) and ``callback`` is called.

Generation 0 is the evaluated initial population, so ``generations=G`` breeds G generations
and the history has G + 1 entries. All randomness comes from the one ``rng``, consumed in the
main process in a fixed order (evaluation takes none), so a seed fixes the run on every back end
and :func:`resume` continues a checkpoint bit for bit.
"""

from __future__ import annotations

import numbers
import os
import pickle
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .checkpoint import load_checkpoint, save_checkpoint
from .diversity import distinct_fraction
from .evaluation import evaluate
from .history import History
from .selection import ranking, tournament

__all__ = ["EvolutionResult", "evolve", "resume"]


@dataclass
class EvolutionResult:
    """Outcome of a run (also what ``callback`` receives after every generation, as a snapshot
    that later generations do not change).

    Attributes:
        population: list of genomes of the last generation (elites first).
        fitness: float64 array, fitness of ``population``.
        history: per-generation statistics.
        best: the fittest genome of the last generation (ties: first).
        best_fitness: its fitness.
        generation: number of the last generation.
    """

    population: list
    fitness: np.ndarray
    history: History
    best: Any
    best_fitness: float
    generation: int


def _result(population, fitness, history, generation) -> EvolutionResult:
    i = int(np.argmax(fitness))
    return EvolutionResult(list(population), fitness.copy(), history, population[i], float(fitness[i]), generation)


def _check_int(name, value, low) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < low:
        raise ValueError(f"{name}: expected an int >= {low}, got {value!r}")
    return int(value)


def _check_callable(name, value, shape):
    if not callable(value):
        raise TypeError(f"{name}: expected a callable {shape}, got {type(value).__name__}")
    return value


def _picklable(obj):
    """``obj`` pickled, or None if it does not pickle (a lambda): stored so resume can reuse it."""
    try:
        return pickle.dumps(obj, protocol=5)
    except Exception:
        return None


def _make_rng(state: dict) -> np.random.Generator:
    name = state.get("bit_generator") if isinstance(state, dict) else None
    cls = getattr(np.random, str(name), None)
    if not (isinstance(cls, type) and issubclass(cls, np.random.BitGenerator)):
        raise ValueError(f"rng_state: unknown bit generator {name!r}")
    bit_generator = cls()
    bit_generator.state = state
    return np.random.Generator(bit_generator)


class _Run:
    """The loop shared by evolve and resume; holds the settings of one run."""

    def __init__(self, fitness, vary, *, select, elite, diversity, map, executor, checkpoint, progress, callback):
        self.fitness = _check_callable("fitness", fitness, "fitness(genome) -> float")
        self.vary = _check_callable("vary", vary, "vary(parents, rng) -> children")
        self.select = _check_callable("select", select, "select(fitness, k, rng) -> indices")
        self.elite = _check_int("elite", elite, 0)
        self.diversity = _check_callable("diversity", diversity, "diversity(population) -> float")
        if map is not None and executor is not None:
            raise ValueError("map/executor: give at most one of map= and executor=")
        if map is not None:
            _check_callable("map", map, "map(func, iterable) -> iterable")
        self.map, self.executor = map, executor
        if checkpoint is not None and not isinstance(checkpoint, (str, os.PathLike)):
            raise TypeError(f"checkpoint: expected a file path (str or pathlib.Path) or None, got {type(checkpoint).__name__}")
        self.checkpoint = checkpoint
        self.progress = progress
        self.callback = None if callback is None else _check_callable("callback", callback, "callback(result)")

    def check_elite(self, n: int) -> None:
        if self.elite > n:
            raise ValueError(f"elite: cannot keep {self.elite} elites in a population of {n}")

    def evaluate(self, genomes) -> np.ndarray:
        return evaluate(self.fitness, genomes, map=self.map, executor=self.executor)

    def measure_diversity(self, population) -> float:
        value = self.diversity(population)
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real) or not np.isfinite(value):
            raise ValueError(f"diversity: diversity(population) returned {value!r}; expected a finite number")
        return float(value)

    def save(self, population, fitness, history, generation, generations, rng) -> None:
        if self.checkpoint is None:
            return
        state = {
            "generation": generation,
            "generations": generations,
            "population": list(population),
            "fitness": fitness,
            "history": history.to_dict(),
            "rng_state": rng.bit_generator.state,
            "elite": self.elite,
            "select": _picklable(self.select),
            "diversity": _picklable(self.diversity),
        }
        save_checkpoint(self.checkpoint, state)

    def after_generation(self, population, fitness, history, generation, generations, rng) -> bool:
        """Checkpoint, then call back. True if the callback asked to stop."""
        self.save(population, fitness, history, generation, generations, rng)
        if self.callback is None:
            return False
        return bool(self.callback(_result(population, fitness, history.copy(), generation)))

    def parents(self, fitness, k, rng) -> np.ndarray:
        idx = self.select(fitness, k, rng)
        idx = np.asarray(idx)
        if idx.shape != (k,) or idx.dtype.kind not in "iu":
            raise ValueError(f"select: expected {k} integer indices, got an array of shape {idx.shape} and dtype {idx.dtype}")
        if k and (idx.min() < 0 or idx.max() >= fitness.size):
            raise ValueError(f"select: indices must lie in [0, {fitness.size}), got values in [{idx.min()}, {idx.max()}]")
        return idx

    def loop(self, population, fitness, history, start, generations, rng) -> EvolutionResult:
        n = len(population)
        self.check_elite(n)
        from tqdm.auto import tqdm

        # leave=True: a saved notebook shows the finished bar, never one frozen part of the way
        bar = tqdm(total=generations, initial=start, desc="evolve", unit="gen", disable=not self.progress, leave=True)
        generation = start
        try:
            while generation < generations:
                elites = ranking(fitness)[: self.elite]
                idx = self.parents(fitness, n - self.elite, rng)
                children = self.vary([population[i] for i in idx], rng)
                if isinstance(children, (str, bytes)) or not isinstance(children, Iterable):
                    raise TypeError(f"vary: expected a list of {n - self.elite} children, got {type(children).__name__}")
                children = list(children)
                if len(children) != n - self.elite:
                    raise ValueError(f"vary: returned {len(children)} children for {n - self.elite} parents; expected one per parent")
                child_fitness = self.evaluate(children)
                population = [population[i] for i in elites] + children
                fitness = np.concatenate([fitness[elites], child_fitness])
                generation += 1
                history.record(generation, fitness, self.measure_diversity(population), len(children))
                bar.set_postfix(best=f"{fitness.max():.4g}", refresh=False)  # before the update that shows it
                bar.update(1)
                if self.after_generation(population, fitness, history, generation, generations, rng):
                    bar.total = generation  # stopped early: the bar ends full, and says why
                    bar.set_description(f"evolve (stopped at generation {generation} of {generations})")
                    bar.refresh()
                    break
        finally:
            bar.close()
        return _result(population, fitness, history, generation)


def evolve(
    population: Sequence,
    fitness: Callable,
    vary: Callable,
    *,
    generations: int,
    rng: np.random.Generator,
    select: Callable = tournament,
    elite: int = 1,
    map: Callable | None = None,
    executor: Any | None = None,
    checkpoint: str | os.PathLike[str] | None = None,
    progress: bool = True,
    callback: Callable | None = None,
    diversity: Callable = distinct_fraction,
) -> EvolutionResult:
    """Run a genetic algorithm.

    Args:
        population: initial genomes (any picklable objects); the population size stays ``len``.
        fitness: ``fitness(genome) -> float``, higher is better, finite.
        vary: ``vary(parents, rng) -> children`` with one child per parent (a ``Variation``).
        generations: number of generations to breed after the initial one (>= 0).
        rng: ``numpy.random.Generator``; the only source of randomness (it is advanced).
        select: selector ``select(fitness, k, rng) -> indices`` (see :mod:`coursekit.ga.selection`;
            use ``functools.partial(tournament, size=5)`` to set parameters).
        elite: number of best individuals copied unchanged into the next generation (elitism).
        map: ``map(func, iterable)`` used to evaluate fitness; exclusive with ``executor``.
        executor: ``concurrent.futures.Executor`` or Dask ``distributed.Client`` for evaluation.
        checkpoint: path of a checkpoint file rewritten (atomically) after every generation.
        progress: show a tqdm progress bar.
        callback: ``callback(result)`` after every generation (0 included) with an
            :class:`EvolutionResult` snapshot; return True to stop the run early.
        diversity: ``diversity(population) -> float`` recorded in the history
            (default: fraction of distinct genomes).
    Returns:
        :class:`EvolutionResult` of the last generation.
    """
    if isinstance(population, (str, bytes)) or not isinstance(population, Sequence):
        raise TypeError(f"population: expected a sequence (list) of genomes, got {type(population).__name__}")
    if len(population) == 0:
        raise ValueError("population: expected at least 1 genome, got an empty population")
    generations = _check_int("generations", generations, 0)
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator (numpy.random.default_rng(seed)), got {type(rng).__name__}")
    run = _Run(fitness, vary, select=select, elite=elite, diversity=diversity, map=map, executor=executor,
               checkpoint=checkpoint, progress=progress, callback=callback)
    run.check_elite(len(population))
    population = list(population)
    fit = run.evaluate(population)
    history = History()
    history.record(0, fit, run.measure_diversity(population), len(population))
    if run.after_generation(population, fit, history, 0, generations, rng):
        return _result(population, fit, history, 0)
    return run.loop(population, fit, history, 0, generations, rng)


def resume(
    checkpoint: str | os.PathLike[str],
    fitness: Callable,
    vary: Callable,
    *,
    generations: int,
    map: Callable | None = None,
    executor: Any | None = None,
    select: Callable | None = None,
    elite: int | None = None,
    diversity: Callable | None = None,
    progress: bool = True,
    callback: Callable | None = None,
    trust_foreign: bool = False,
) -> EvolutionResult:
    """Continue a run from its checkpoint; it keeps checkpointing to the same file.

    With the same ``fitness``, ``vary`` and settings, the result equals (bit for bit) that of the
    uninterrupted run.

    Args:
        checkpoint: path of the checkpoint written by :func:`evolve` (or a previous resume).
        fitness, vary, map, executor, progress, callback: as for :func:`evolve`.
        generations: the total the run should reach -- the same number given to ``evolve``, not
            the number still to go. Larger values extend a finished run.
        select, elite, diversity: default to the values stored in the checkpoint (a ``select``
            or ``diversity`` that did not pickle, e.g. a lambda, must be given again).
        trust_foreign: load a checkpoint not signed with this user's key (see
            :func:`coursekit.ga.load_checkpoint`: it may run code; only for a trusted author).
    Returns:
        :class:`EvolutionResult` of the last generation.
    """
    state = load_checkpoint(checkpoint, trust_foreign=trust_foreign)
    stored = {}
    for name in ("select", "diversity"):
        blob = state.get(name)
        stored[name] = pickle.loads(blob) if blob is not None else None
    select = select if select is not None else stored["select"]
    diversity = diversity if diversity is not None else stored["diversity"]
    elite = elite if elite is not None else state.get("elite")
    for name, value in (("select", select), ("diversity", diversity), ("elite", elite)):
        if value is None:
            raise ValueError(f"{name}: the checkpoint does not store it (it did not pickle); pass {name}= to resume")
    start = int(state["generation"])
    generations = _check_int("generations", generations, 0)
    if generations < start:
        raise ValueError(f"generations: the checkpoint is already at generation {start}, cannot resume to {generations}")
    run = _Run(fitness, vary, select=select, elite=elite, diversity=diversity, map=map, executor=executor,
               checkpoint=checkpoint, progress=progress, callback=callback)
    rng = _make_rng(state["rng_state"])
    population = list(state["population"])
    fit = np.asarray(state["fitness"], dtype=np.float64)
    history = History.from_dict(state["history"])
    if len(fit) != len(population) or len(history) != start + 1:
        raise ValueError(f"{checkpoint}: checkpoint is inconsistent (population {len(population)}, fitness {len(fit)}, history {len(history)})")
    return run.loop(population, fit, history, start, generations, rng)
