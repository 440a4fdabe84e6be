"""The paper's section 4.1 experiments with the swimmers, as data that ships with the kit.

The paper reports that the ratio of crossover to mutation is "a vital parameter", that modifying
many elements in a mutation "can stop evolution", and that joints with more than one degree of
freedom were the most important thing missing. ``coursekit/data/paper_experiments.json`` holds
real runs of :func:`~coursekit.creatures.evolve_swimmers` for each setting and several seeds,
made by ``benchmarks/data/paper_experiments.py`` (the file records the command, the coursekit
commit and the sizes): the best fitness of every generation, in m/s and in body lengths per second,
and each run's final champion with its straight-line speed over Sims' 10 s test. Lesson 08 plots it.

>>> data = paper_experiments()
>>> sorted(data.groups)[:1]
['child ratios (mutation / crossover / grafting)']
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np

#: The format tag of ``paper_experiments.json``.
FORMAT = "coursekit.paper_experiments/1"
_SIZES = ("population", "generations", "seconds", "seeds", "max_parts")


@dataclass(frozen=True)
class Run:
    """One evolution: a setting and a seed."""

    seed: int
    best_ms: np.ndarray  #: best fitness of generations 0..G (m/s)
    best_bl: np.ndarray  #: the same creatures' fitness in body lengths per second
    champion_ms: float  #: the final champion's straight-line speed over ``champion_seconds`` (m/s)
    champion_bl: float  #: the same in body lengths per second
    champion_parts: int
    creature: dict  #: the champion's genotype (``Creature.from_dict``)

    def champion(self):
        """The final champion as a :class:`~coursekit.creatures.Creature`."""
        from .genotype import Creature

        return Creature.from_dict(self.creature)


@dataclass(frozen=True)
class PaperExperiments:
    """The whole file: provenance, the settings, which settings each experiment compares, the runs."""

    command: str
    coursekit_commit: str
    sizes: dict
    champion_seconds: float
    settings: dict  #: name -> {"ratios", "mutation_rate", "joint_types"}
    groups: dict  #: experiment -> the names of the settings it compares
    runs: dict  #: setting name -> list of :class:`Run`, one per seed
    wall_seconds: float

    def curves(self, name: str, unit: str = "ms") -> np.ndarray:
        """Best fitness per generation of setting ``name``, one row per seed (``unit`` "ms" or "bl")."""
        if name not in self.runs:
            raise KeyError(f"name: no setting {name!r}; have {list(self.runs)}")
        if unit not in ("ms", "bl"):
            raise ValueError(f"unit: must be 'ms' or 'bl', got {unit!r}")
        return np.stack([getattr(r, f"best_{unit}") for r in self.runs[name]])

    def final(self, name: str, unit: str = "ms") -> np.ndarray:
        """The last generation's best fitness of setting ``name``, one per seed."""
        return self.curves(name, unit)[:, -1]


def _fail(where: str, field: str, want: str, got) -> ValueError:
    return ValueError(f"paper_experiments.json: {where}field {field!r} must be {want}, got {got!r}")


def _curve(values, where: str, field: str, n: int) -> np.ndarray:
    if not isinstance(values, list) or len(values) != n or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise _fail(where, field, f"a list of {n} numbers", values)
    a = np.asarray(values, dtype=float)
    if not (np.all(np.isfinite(a)) and np.all(a >= 0)):
        raise _fail(where, field, "finite and >= 0", values)
    return a


def paper_experiments(path: str | Path | None = None) -> PaperExperiments:
    """Load the shipped experiments (or the file at ``path``, e.g. a fresh run of the script).

    Raises:
        ValueError: the file is not such a file, naming the setting, seed and field at fault.
    """
    if path is None:
        text = (resources.files("coursekit.data") / "paper_experiments.json").read_text(encoding="utf-8")
    else:
        text = Path(path).read_text(encoding="utf-8")
    doc = json.loads(text)
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise ValueError(f"paper_experiments.json: format must be {FORMAT!r}")
    for field in ("command", "coursekit_commit"):
        if not isinstance(doc.get(field), str):
            raise _fail("", field, "a string", doc.get(field))
    sizes = doc.get("sizes")
    if not isinstance(sizes, dict) or any(not isinstance(sizes.get(k), (int, float)) or not sizes[k] > 0 for k in _SIZES):
        raise _fail("", "sizes", f"an object with positive {', '.join(_SIZES)}", sizes)
    for field in ("champion_seconds", "wall_seconds"):
        v = doc.get(field)
        if not isinstance(v, (int, float)) or not (math.isfinite(v) and v > 0):
            raise _fail("", field, "a positive number", v)
    settings, groups, results = doc.get("settings"), doc.get("groups"), doc.get("results")
    if not isinstance(settings, dict) or not settings:
        raise _fail("", "settings", "a non-empty object", settings)
    if not isinstance(results, dict) or set(results) != set(settings):
        raise _fail("", "results", f"an object with one entry per setting {sorted(settings)}", None if results is None else sorted(results))
    if not isinstance(groups, dict) or any(not isinstance(m, list) or not set(m) <= set(settings) for m in groups.values()):
        raise _fail("", "groups", "an object of lists of setting names", groups)
    n = int(sizes["generations"]) + 1
    runs = {}
    for name, entries in results.items():
        if not isinstance(entries, list) or [e.get("seed") if isinstance(e, dict) else None for e in entries] != list(range(int(sizes["seeds"]))):
            raise _fail(f"setting {name!r}: ", "results", f"one run per seed 0..{int(sizes['seeds']) - 1} in order", entries)
        runs[name] = []
        for e in entries:
            where = f"setting {name!r}, seed {e['seed']}: "
            champ = e.get("champion")
            if not isinstance(champ, dict):
                raise _fail(where, "champion", "an object", champ)
            for field in ("speed_ms", "speed_bl"):
                v = champ.get(field)
                if not isinstance(v, (int, float)) or not (math.isfinite(v) and v >= 0):
                    raise _fail(where, f"champion.{field}", "a finite number >= 0", v)
            if not isinstance(champ.get("parts"), int) or not isinstance(champ.get("creature"), dict):
                raise _fail(where, "champion", "an object with 'parts' (int) and 'creature'", sorted(champ))
            runs[name].append(Run(e["seed"], _curve(e.get("best_ms"), where, "best_ms", n), _curve(e.get("best_bl"), where, "best_bl", n),
                                  float(champ["speed_ms"]), float(champ["speed_bl"]), champ["parts"], champ["creature"]))
    return PaperExperiments(doc["command"], doc["coursekit_commit"], dict(sizes), float(doc["champion_seconds"]), settings,
                            groups, runs, float(doc["wall_seconds"]))
