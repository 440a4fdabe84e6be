"""The evolution engine shared by both labs (paper section 1; Sims 1994 section 6).

A genetic algorithm keeps a population of genotypes, judges each by a fitness function, lets
the fittest reproduce -- mutation of singles, recombination of pairs -- and repeats. Genomes are
opaque to this package (bit strings, picture chromosomes and creature graphs all plug in); it
only needs ``fitness(genome) -> float`` and the variation operators.

- selection: :func:`truncation`, :func:`tournament`, :func:`roulette`, :func:`sims_offspring`,
  :func:`sims_select`; elitism is ``evolve(..., elite=k)``;
- variation: :class:`Variation` mixes operators by ratio; reference operators
  :func:`point_mutation` and :func:`one_point_crossover`;
- the loop: :func:`evolve`, :func:`resume`, :class:`EvolutionResult`, :class:`History`;
- evaluation back ends: serial, any ``map``, ``concurrent.futures`` executors, Dask clients.

Example::

    import numpy as np
    from coursekit import ga
    rng = np.random.default_rng(0)
    pop = ga.problems.random_bits(rng, 50, 64)
    vary = ga.Variation([(0.5, ga.point_mutation), (0.5, ga.one_point_crossover)])
    result = ga.evolve(pop, ga.problems.onemax, vary, generations=30, rng=rng)
    result.history.plot()
"""

from . import diversity, problems
from .checkpoint import load_checkpoint, save_checkpoint
from .diversity import distinct_fraction, mean_pairwise
from .evaluation import evaluate
from .evolve import EvolutionResult, evolve, resume
from .history import History
from .operators import one_point_crossover, point_mutation
from .selection import ranking, roulette, sims_offspring, sims_select, tournament, truncation
from .variation import Variation, infer_arity

__all__ = [
    "EvolutionResult", "History", "Variation", "distinct_fraction", "diversity", "evaluate", "evolve",
    "infer_arity", "load_checkpoint", "mean_pairwise", "one_point_crossover", "point_mutation", "problems",
    "ranking", "resume", "roulette", "save_checkpoint", "sims_offspring", "sims_select", "tournament", "truncation",
]
