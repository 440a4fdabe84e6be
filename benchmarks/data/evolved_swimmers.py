"""Regenerate ``evolved_swimmers.json`` (next to this script): the last generation of a real run.

The realistic workload of ``benchmarks/swimmers.py`` is a population that evolution actually
produced, not random bodies: this runs :func:`coursekit.creatures.evolve_swimmers` at the settings
of ``coursekit demo swimmers`` in the classroom profile (60 creatures x 10 generations x 5 s,
random creatures of at most 16 parts, seed 0) and saves its final population, elites first, with
each creature's fitness, the settings and the command. The run is bit for bit the same on any
number of worker processes.

    python benchmarks/data/evolved_swimmers.py [--out benchmarks/data/evolved_swimmers.json] [--workers N]

(It lives here, not beside the benchmarks, so that ``coursekit bench`` does not run it.)
"""

from __future__ import annotations

import argparse
import json
import os
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from coursekit.atomic import atomic_write
from coursekit.creatures import Creature, evolve_swimmers

#: Where the benchmark reads the population, and its file format.
DATA = Path(__file__).with_suffix(".json")
FORMAT = "coursekit.population/1"
#: The run: ``coursekit demo swimmers`` (classroom profile, as it was then), seed 0; its first
#: generation wired at random, with no rhythm (``rhythm=0``), as when the shipped file was made.
SETTINGS = dict(population_size=60, generations=10, seconds=5.0, seed=0, random_options=dict(max_parts=16, rhythm=0.0))


def load(path=DATA) -> tuple[list, dict]:
    """The saved creatures (elites first) and the file's header (settings, command, fitness)."""
    d = json.loads(Path(path).read_text(encoding="utf-8"))
    if d.get("format") != FORMAT:
        raise ValueError(f"{path}: format must be {FORMAT!r}, got {d.get('format')!r}")
    return [Creature.from_dict(c) for c in d["creatures"]], {k: v for k, v in d.items() if k != "creatures"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DATA)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    args = ap.parse_args(argv)
    s = SETTINGS
    t0 = time.perf_counter()
    pool = ProcessPoolExecutor(args.workers) if args.workers > 1 else None
    try:
        result = evolve_swimmers(generations=s["generations"], rng=np.random.default_rng(s["seed"]),
                                 population_size=s["population_size"], seconds=s["seconds"], progress=False,
                                 random_options=s["random_options"], executor=pool)
    finally:
        if pool is not None:
            pool.shutdown()
    wall = time.perf_counter() - t0
    parts = [c.expand().body.n_bodies for c in result.population]
    doc = {
        "format": FORMAT,
        "command": "python benchmarks/data/evolved_swimmers.py",
        "description": "the last generation (elites first) of evolve_swimmers at the settings of `coursekit demo swimmers` "
                       "(classroom profile)",
        "settings": s,
        "fitness": [float(f) for f in result.fitness],
        "history_best": [float(b) for b in result.history.best],
        "creatures": [c.to_dict() for c in result.population],
    }
    text = json.dumps(doc, separators=(",", ":"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out, text)
    back, _ = load(args.out)
    if [c.to_dict() for c in back] != doc["creatures"]:
        raise RuntimeError(f"{args.out}: the creatures read back differ from those written")
    print(f"{len(parts)} creatures, {min(parts)}-{max(parts)} parts (mean {np.mean(parts):.1f}); best fitness "
          f"{result.history.best[0]:.4f} -> {result.best_fitness:.4f} m/s; {wall:.0f} s wall; wrote {args.out} "
          f"({len(text) / 1024:.0f} KiB)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
