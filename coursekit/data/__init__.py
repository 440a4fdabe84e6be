"""Data files the lessons and tests share, installed with the package (not read from ``tests/``).

- ``limit_exploit_creature.json`` -- the 3-box swimmer that evolution bred to push its prismatic
  joints far past their limits before joint limits were constraints (lesson 08's exploit);
- ``step_exploit_creature.json`` -- a Sims-scale champion that swam on the time step: 1.31 m/s in
  one sub-step, 0.73 from eight on, when evolution's refinement was two sub-steps. Since stops at
  the joint limits only take energy it swims 1.26 m/s at the step, 1.19 in eight sub-steps and
  0.13 from 24 on: at the step and in eight a flipper sits sunk half its thickness into the body,
  at 24 never over 4 %. The audit and evolution's refinement run such sunk creatures in 24 sub-steps
  and score it 0;
- ``time_step_creature.json`` -- a randomly wired creature (``Creature.random(default_rng(1),
  max_parts=12)``, the tenth of 300) that swims 0.028 m/s at the step, 0.0003 in eight sub-steps
  and 0.00003 in 32: the test that evolution's refinement scores such a speed 0;
- ``paper_experiments.json`` -- the paper's section 4.1 experiments, run per setting and seed
  (``benchmarks/data/paper_experiments.py``; read with :func:`coursekit.creatures.experiments.paper_experiments`).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from coursekit.creatures import Creature


def path(name: str) -> Path:
    """The installed data file ``name``.

    Raises:
        FileNotFoundError: no such file, naming the files there are.
    """
    folder = resources.files(__name__)
    found = folder / name
    if not found.is_file():
        have = sorted(p.name for p in folder.iterdir() if p.name.endswith(".json"))
        raise FileNotFoundError(f"coursekit.data: no file {name!r}; have {', '.join(have)}")
    return Path(str(found))


def creature(name: str) -> Creature:
    """The :class:`~coursekit.creatures.Creature` stored in ``<name>.json`` (e.g. ``"limit_exploit_creature"``).

    >>> creature("limit_exploit_creature").expand().body.n_bodies
    3
    """
    from coursekit.creatures import Creature

    return Creature.from_json(path(f"{name}.json").read_text())
