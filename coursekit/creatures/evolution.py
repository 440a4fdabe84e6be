"""Evolving swimmers: the paper's GA (section 2.2) driven by swimming speed (section 2.4).

:func:`evolve_swimmers` plugs the creature operators into the shared engine
(:func:`coursekit.ga.evolve`; :func:`resume_swimmers` continues its checkpoint) with Sims' 1994 settings by default: survivors are the best fifth,
offspring per survivor proportional to fitness (:func:`coursekit.ga.sims_select`), survivors kept
(elitism), and children made 40 % by mutation, 30 % by the paper's recombination and 30 % by
grafting (mated children are mutated at a reduced rate, as Sims did). Fitness is evaluated for
the whole generation in one batched simulation (:func:`coursekit.creatures.simulate.simulate`),
so it goes in as the engine's ``map``. Every operator is a parameter: a student's own
``mutate(creature, rng)`` or ``crossover(a, b, rng)`` plugs in where the library's does.
"""

from __future__ import annotations

import functools
import inspect
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from coursekit import ga
from coursekit.creatures import audit, operators
from coursekit.creatures.genotype import Creature
from coursekit.creatures.neural import is_int, is_real
from coursekit.creatures.simulate import check_options, simulate


@dataclass(frozen=True)
class Mated:
    """A binary creature operator made into the engine's pair form, with a light mutation after.

    ``op(a, b, rng) -> child`` (the paper's recombination and grafting make one child) becomes
    ``(a, b, rng) -> (op(a, b), op(b, a))``; each child is then mutated with ``mutate`` at
    ``rate`` (Sims: "mated offspring get mutations at reduced rates"): passed as ``rate=`` when
    ``mutate`` takes one, otherwise each child is mutated with probability ``rate``. Picklable, so
    it runs in process pools and checkpoints.
    """

    op: object
    mutate: object = operators.mutate
    rate: float = 0.25

    def __call__(self, a, b, rng):
        children = (self.op(a, b, rng), self.op(b, a, rng))
        if self.rate > 0:
            if "rate" in inspect.signature(self.mutate).parameters:
                children = tuple(self.mutate(c, rng, rate=self.rate) for c in children)
            else:
                children = tuple(self.mutate(c, rng) if rng.random() < self.rate else c for c in children)
        return children


@dataclass
class SwimmerFitness:
    """Batched evaluation: ``map(fitness, creatures)`` simulates the whole list at once.

    Given to :func:`coursekit.ga.evolve` as ``map`` (the engine's per-genome ``fitness`` is not
    called); every option goes to :func:`~coursekit.creatures.simulate.simulate`.

    With an ``executor`` (a ``concurrent.futures`` pool or a Dask client) the generation is dealt
    into ``chunks`` batches (default: one per worker), every ``chunks``-th creature to the same
    batch so that big and small creatures spread evenly, and the batches swim in the workers.
    A creature's trajectory does not depend on its batch, so the fitness is bit for bit that of
    one serial batch.

    Exploits of the time step are scored out: the ``refine`` fittest creatures of every batch are
    simulated again with the physics in the audit's eightfold sub-steps (the brains tick as before,
    :class:`~coursekit.creatures.physics.world.World`'s ``substeps``), and each keeps the lower
    of its two scores -- or 0 if the finer integration takes more of its score than the audit
    allows (:data:`~coursekit.creatures.audit.FINE_SPEED_SHARE`, beyond a negligible distance). A
    speed that came from integration error -- the one leak an exact simulator still has, and the
    first thing evolution finds (:mod:`coursekit.creatures.audit`) -- does not survive the finer
    integration; a swimmer's does. (Twice the sub-steps let through a champion that swam
    1.21 m/s from one to seven sub-steps and 0.73 m/s from eight on: ``benchmarks/NOTES.md``.)
    A refined creature whose parts stay sunk into each other
    (:func:`~coursekit.creatures.audit.sunk_share` over :data:`~coursekit.creatures.audit.SUNK_SHARE`)
    swims once more in the audit's :data:`~coursekit.creatures.audit.DEEP_REFINE` sub-steps and
    keeps the lowest of its three scores, by the same rule: a limb that sweeps through another part
    within a step is not a stroke.
    """

    seconds: float = 10.0
    options: dict = field(default_factory=dict)
    refine: int = 3
    executor: object = None
    chunks: int | None = None

    def __call__(self, _fitness, creatures):
        creatures = list(creatures)
        if not creatures:
            return []
        if self.executor is None:
            fitness = _swim((creatures, self.seconds, self.options))
        else:
            n = min(len(creatures), self.chunks or ga.evaluation.workers(self.executor))
            parts = ga.evaluation.parallel_map(_swim, [(creatures[k::n], self.seconds, self.options) for k in range(n)], self.executor)
            fitness = np.empty(len(creatures))
            for k, f in enumerate(parts):
                fitness[k::n] = f
        if self.refine > 0:
            top = np.argsort(-fitness, kind="stable")[: self.refine]
            substeps = self.options.get("substeps", 1)
            best = [creatures[i] for i in top]
            fine = simulate(best, self.seconds, **{**self.options, "substeps": audit.REFINE * substeps, "record_every": audit.FRAME})
            refined = fine.fitness
            sunk = np.flatnonzero(audit.sunk_share(best, fine.trajectory) > audit.SUNK_SHARE)
            if len(sunk):  # parts sunk into each other: once more, where held contacts keep them apart
                deep = {**self.options, "substeps": audit.DEEP_REFINE * substeps}
                refined[sunk] = np.minimum(refined[sunk], simulate([best[i] for i in sunk], self.seconds, **deep).fitness)
            floor = np.array([audit.NEGLIGIBLE * audit.body_length(c.expand().body) for c in best]) / self.seconds
            exploit = (refined < audit.FINE_SPEED_SHARE * fitness[top]) & (fitness[top] - refined > floor)
            fitness[top] = np.where(exploit, 0.0, np.minimum(fitness[top], refined))
        return [float(f) for f in fitness]


def _swim(job):
    """Fitness of one batch ``(creatures, seconds, options)``; one thread per worker process."""
    from threadpoolctl import threadpool_limits

    creatures, seconds, options = job
    with threadpool_limits(1):
        return simulate(creatures, seconds, **options).fitness


def _unbatched(creature):  # pragma: no cover - never called: SwimmerFitness evaluates the batch
    raise RuntimeError("swimmer fitness is evaluated in batches by SwimmerFitness")


def evolve_swimmers(
    population: Sequence[Creature] | None = None,
    *,
    generations: int,
    rng: np.random.Generator,
    population_size: int = 300,
    seconds: float = 10.0,
    mutate: Callable = operators.mutate,
    crossover: Callable = operators.crossover,
    graft: Callable = operators.graft,
    ratios: tuple[float, float, float] = (0.4, 0.3, 0.3),
    select: Callable = ga.sims_select,
    elite: int | None = None,
    checkpoint: str | os.PathLike[str] | None = None,
    progress: bool = True,
    callback: Callable | None = None,
    random_options: dict | None = None,
    executor: Any | None = None,
    joint_types: Sequence[str] | None = None,
    **simulate_options: Any,
) -> ga.EvolutionResult:
    """Evolve swimmers for speed.

    Args:
        population: initial creatures; default ``population_size`` random ones
            (``Creature.random(rng, **random_options)``).
        generations: generations to breed after the initial one.
        rng: the only source of randomness.
        population_size: size of a random initial population (Sims used 300).
        seconds: swimming time per evaluation (after the settle phase).
        mutate, crossover, graft: operators ``mutate(c, rng)``, ``crossover(a, b, rng) -> child``,
            ``graft(a, b, rng) -> child``; pass ``None`` for crossover or graft to leave it out.
        ratios: shares of children from mutation, crossover and grafting (Sims: 40/30/30).
        select: parent selector (default Sims' fitness-proportional offspring of the top fifth).
        elite: survivors copied unchanged (default: the top fifth, as Sims kept his survivors).
        checkpoint, progress, callback: as for :func:`coursekit.ga.evolve`.
        random_options: options for ``Creature.random``.
        joint_types: the joint types random creatures, new nodes and joint-type mutations draw
            from (names of :data:`~coursekit.creatures.morphology.JOINT_AXES`, e.g.
            ``["revolute", "universal", "spherical"]``); default the 1-DOF revolute and prismatic
            joints (the same runs as before multi-DOF joints existed). Passed to ``mutate`` when
            it takes ``joint_types``.
        executor: a ``concurrent.futures`` pool or a Dask ``distributed.Client`` the generation
            swims in, a batch per worker (:class:`SwimmerFitness`); the result is bit for bit the
            serial one.
        **simulate_options: options for :func:`~coursekit.creatures.simulate.simulate` (``dt``,
            ``settle``, ``backend``, ``drag_coefficient``, ``fitness`` -- a function
            ``fitness(com, times)`` scoring the paths in place of Sims' -- ...).

    Returns:
        The engine's :class:`~coursekit.ga.EvolutionResult`; ``best`` is the fastest swimmer.
    """
    if population is None:
        if not (is_int(population_size) and population_size >= 2):
            raise ValueError(f"population_size: must be an integer >= 2, got {population_size!r}")
        if random_options is not None and not isinstance(random_options, dict):
            raise TypeError(f"random_options: expected a dict of Creature.random options, got {type(random_options).__name__}")
        options = dict(random_options or {})
        if joint_types is not None:
            options.setdefault("joint_types", joint_types)
        population = [Creature.random(rng, **options) for _ in range(population_size)]
    elif isinstance(population, (str, bytes)) or not hasattr(population, "__iter__"):
        raise TypeError(f"population: expected a list of creatures, got {type(population).__name__}")
    population = list(population)
    vary, evaluate = _breeding(seconds, _with_joint_types(mutate, joint_types), crossover, graft, ratios, executor, simulate_options)
    if elite is None:
        elite = max(1, math.ceil(len(population) / 5))
    return ga.evolve(
        population, _unbatched, vary, generations=generations, rng=rng, select=select, elite=elite,
        map=evaluate, checkpoint=checkpoint, progress=progress, callback=callback,
    )


def resume_swimmers(
    checkpoint: str | os.PathLike[str],
    *,
    generations: int,
    seconds: float = 10.0,
    mutate: Callable = operators.mutate,
    crossover: Callable = operators.crossover,
    graft: Callable = operators.graft,
    ratios: tuple[float, float, float] = (0.4, 0.3, 0.3),
    progress: bool = True,
    callback: Callable | None = None,
    executor: Any | None = None,
    joint_types: Sequence[str] | None = None,
    **simulate_options: Any,
) -> ga.EvolutionResult:
    """Continue a run of :func:`evolve_swimmers` from its checkpoint (:func:`coursekit.ga.resume`).

    Given the settings the run was started with (``seconds``, the operators, ``ratios`` and the
    simulation options, ``joint_types``; selection and elitism come from the checkpoint), the
    result equals, bit for bit, that of the uninterrupted run. ``generations`` is the total the
    run should reach.
    """
    vary, evaluate = _breeding(seconds, _with_joint_types(mutate, joint_types), crossover, graft, ratios, executor, simulate_options)
    return ga.resume(checkpoint, _unbatched, vary, generations=generations, map=evaluate, progress=progress, callback=callback)


def _with_joint_types(mutate, joint_types):
    """``mutate`` drawing from ``joint_types`` when it takes them (a picklable partial)."""
    if joint_types is None or not callable(mutate) or "joint_types" not in inspect.signature(mutate).parameters:
        return mutate
    return functools.partial(mutate, joint_types=list(joint_types))


def _breeding(seconds, mutate, crossover, graft, ratios, executor, simulate_options):
    """The variation (Sims' shares of mutated, recombined and grafted children) and the fitness."""
    if (not isinstance(ratios, (tuple, list)) or len(ratios) != 3
            or any(not (is_real(r) and r >= 0) for r in ratios)):
        raise ValueError(f"ratios: need three shares >= 0 (mutation, crossover, grafting), got {ratios!r}")
    for name, op in (("mutate", mutate), ("crossover", crossover), ("graft", graft)):
        if not (callable(op) or (op is None and name != "mutate")):
            allowed = "a function" if name == "mutate" else "a function or None"
            raise TypeError(f"{name}: must be {allowed}, got {type(op).__name__}")
    check_options(simulate_options, "simulate options")
    parts = [(ratios[0], mutate, 1)]
    if crossover is not None and ratios[1] > 0:
        parts.append((ratios[1], Mated(crossover, mutate), 2))
    if graft is not None and ratios[2] > 0:
        parts.append((ratios[2], Mated(graft, mutate), 2))
    return ga.Variation(parts), SwimmerFitness(seconds, dict(simulate_options), executor=executor)
