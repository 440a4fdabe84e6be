"""Genetic pictures (paper section 3, after Sims 1991).

Genomes of chromosome strings linked by a PreHeader (:mod:`.genome`), a primitive set and its
registry (:mod:`.primitives`), a tensorised whole-image evaluator (:mod:`.evaluate`, one descent
through :mod:`.local` or :mod:`.workers`, :mod:`.grouped`, :mod:`.tree` and :mod:`.kernels` on
:mod:`.context`) with a per-pixel reference (:mod:`.reference`), the paper's four mutations and
three recombinations
(:mod:`.operators`), image files carrying their genome (:mod:`.files`), previews that keep
flat pictures and copies out of the gallery (:mod:`.variety`) and an interactive gallery where
the user is the fitness function (:mod:`.gallery`).
"""

from . import primitives
from .genome import Chromosome, ChromosomeString, Genome
from . import operators
from .evaluate import render
from .files import load_genome, save_image
from .gallery import Gallery, GalleryState
from . import variety
from .variety import random_population
from .reference import render_reference

__all__ = ["primitives", "operators", "Chromosome", "ChromosomeString", "Genome", "render",
           "render_reference", "save_image", "load_genome", "Gallery", "GalleryState", "variety",
           "random_population"]
