"""Genetic pictures (paper section 3, after Sims 1991).

Genomes of chromosome strings linked by a PreHeader (:mod:`.genome`), a primitive set
(:mod:`.primitives`), a tensorised whole-image evaluator (:mod:`.evaluate`) with a per-pixel
reference (:mod:`.reference`), the paper's four mutations and three recombinations
(:mod:`.operators`), image files carrying their genome (:mod:`.files`) and an interactive
gallery where the user is the fitness function (:mod:`.gallery`).
"""

from . import primitives
from .genome import Chromosome, ChromosomeString, Genome
from .evaluate import render

__all__ = ["primitives", "Chromosome", "ChromosomeString", "Genome", "render"]
