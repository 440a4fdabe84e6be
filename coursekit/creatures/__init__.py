"""Swimming creatures (paper section 2, after Sims 1994).

- :mod:`.genotype` — :class:`Creature`, the genotype (section 2.1): the morphology graph of
  :mod:`.morphology` (2.1.1) and a brain, made at random or by hand in :mod:`.generation` (2.2.2);
- :mod:`.neural` — the nested neural genotype and Sims' 23 neuron functions (2.1.2);
- :mod:`.operators` — recombination, grafting and mutation (2.2);
- :mod:`.phenotype` — expansion into a :class:`~.body.BodyTree` (2.3);
- :mod:`.brain` — the expanded networks, evaluated in batches (2.3);
- :mod:`.render` — pyvista pictures of creatures;
- :mod:`.mjcf`, :mod:`.physics`, :mod:`.simulate`, :mod:`.fitness` — MuJoCo export and the
  swimming simulation (2.4);
- :mod:`.evolution` — :func:`evolve_swimmers`, the GA of 2.2 driven by swimming speed;
- :mod:`.champions` — :func:`champions`, the pre-evolved swimmers that ship with the kit;
- :mod:`.experiments` — the paper's section 4.1 experiments (child ratios, mutation rate, joint
  types), as shipped runs of :func:`evolve_swimmers`.
"""

from typing import Any

from . import operators
from .body import BodyTree
from .brain import Brain, BrainBatch
from .genotype import FORMAT, ChildLink, Creature, Node, Recursion, Symmetry
from .neural import FUNCTION_NAMES, SENSORS, Input, Neuron
from .phenotype import MAX_PARTS, Phenotype, expand, part_poses
from .simulate import SimulationResult, simulate
from .render import animate, render  # noqa: E402  (the function shadows the submodule's name on purpose)
from .evolution import evolve_swimmers, resume_swimmers
from .champions import champions


def to_mjcf(creature: Any, **options: Any) -> str:
    """MuJoCo MJCF of ``creature``'s expanded body (see :mod:`coursekit.creatures.mjcf`)."""
    from .mjcf import to_mjcf as _to_mjcf

    return _to_mjcf(creature, **options)


__all__ = [
    "BodyTree", "animate", "Brain", "BrainBatch", "ChildLink", "champions", "Creature", "FORMAT", "FUNCTION_NAMES", "Input", "MAX_PARTS",
    "Neuron", "Node", "Phenotype", "Recursion", "SENSORS", "SimulationResult", "Symmetry", "evolve_swimmers", "expand", "resume_swimmers",
    "operators", "part_poses", "render", "simulate", "to_mjcf",
]
