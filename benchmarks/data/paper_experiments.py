"""Regenerate ``coursekit/data/paper_experiments.json``: the paper's section 4.1 experiments, run.

The paper reports three findings about its swimmers' GA: the ratio of crossover to mutation is "a
vital parameter"; modifying many elements in a mutation "can stop evolution"; and joints with more
than one degree of freedom were the most important missing feature. This script runs
:func:`coursekit.creatures.evolve_swimmers` for each of these settings, with several seeds:

- child ratios (mutation / crossover / grafting): mutation only 1/0/0, Sims' 40/30/30, mostly
  mating 10/45/45 (``ratios=``);
- mutation rate scale 0.3 / 1 / 4 (``mutate=functools.partial(operators.mutate, rate=r)``; it
  scales the mutated children's probabilities; mated children keep the engine's reduced rate);
- joint types: 1-DOF revolute only against multi-DOF (revolute, prismatic, universal, spherical)
  (``joint_types=``; random creatures, new nodes and joint-type mutations draw from them).

The Sims 40/30/30 run with rate 1 and the default joints (revolute and prismatic) is the baseline of
the first two groups; it is run once. Seed ``k`` starts every setting from the same generator seed, so
the ratio and rate settings of one seed start from the same random population. For every setting
and seed it records the best fitness of every generation (m/s, and body lengths per second of that
creature) and the final champion's straight-line speed over Sims' 10 s test (m/s and body lengths/s).
Elitism (the best fifth copied unchanged, not re-evaluated) makes each best-fitness curve
non-decreasing. ``max_parts`` bounds the random first generation (``random_options``); grafting and
mutation grow bodies beyond it. The first generation is wired at random, with no rhythm
(``rhythm=0``, :func:`coursekit.creatures.generation.add_rhythm`), as when the shipped runs were made. The file holds the command, the coursekit commit (``+dirty`` when
tracked files differed from it) and the settings.

    python benchmarks/data/paper_experiments.py [--out coursekit/data/paper_experiments.json]
        [--workers 2] [--seeds 3] [--generations 6] [--population 16] [--seconds 2] [--quick]

``--quick`` is a smoke test (population 6, 1 generation, 0.5 s, 1 seed, 6 parts at most).
(It lives here, not beside the benchmarks, so that ``coursekit bench`` does not run it.)
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import shlex
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from coursekit.atomic import atomic_write
from coursekit.creatures import evolve_swimmers, operators, simulate
from coursekit.creatures.audit import body_length

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "coursekit" / "data" / "paper_experiments.json"
FORMAT = "coursekit.paper_experiments/1"
#: Sims' test length: the final champions swim again this long for their speed.
CHAMPION_SECONDS = 10.0
MULTI_DOF = ["revolute", "prismatic", "universal", "spherical"]

#: name -> the evolve_swimmers settings that differ from Sims' baseline.
SETTINGS = {
    "mutation only 1/0/0": dict(ratios=[1.0, 0.0, 0.0]),
    "Sims 40/30/30": dict(ratios=[0.4, 0.3, 0.3]),
    "mostly mating 10/45/45": dict(ratios=[0.1, 0.45, 0.45]),
    "mutation rate x0.3": dict(mutation_rate=0.3),
    "mutation rate x4": dict(mutation_rate=4.0),
    "1-DOF revolute only": dict(joint_types=["revolute"]),
    "multi-DOF joints": dict(joint_types=MULTI_DOF),
}
#: The experiments: which settings each compares (the baseline serves the first two).
GROUPS = {
    "child ratios (mutation / crossover / grafting)": ["mutation only 1/0/0", "Sims 40/30/30", "mostly mating 10/45/45"],
    "mutation rate scale": ["mutation rate x0.3", "Sims 40/30/30", "mutation rate x4"],
    "joint types": ["1-DOF revolute only", "multi-DOF joints"],
}
FULL = dict(population=16, generations=6, seconds=2.0, seeds=3, max_parts=12)
QUICK = dict(population=6, generations=1, seconds=0.5, seeds=1, max_parts=6)


def _commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                               text=True, check=True).stdout.strip()
        return out + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def run_one(setting: dict, seed: int, sizes: dict, executor=None) -> dict:
    """One evolution; returns the best of every generation and the champion."""
    s = {"ratios": [0.4, 0.3, 0.3], "mutation_rate": 1.0, "joint_types": None, **setting}
    rate = s["mutation_rate"]
    mutate = operators.mutate if rate == 1.0 else functools.partial(operators.mutate, rate=rate)
    best_bl = []

    def keep(snapshot):
        best_bl.append(snapshot.best_fitness / body_length(snapshot.best.expand().body))

    result = evolve_swimmers(generations=sizes["generations"], rng=np.random.default_rng(seed),
                             population_size=sizes["population"], seconds=sizes["seconds"], mutate=mutate,
                             ratios=tuple(s["ratios"]), joint_types=s["joint_types"], progress=False,
                             random_options=dict(max_parts=sizes["max_parts"], rhythm=0.0), callback=keep, executor=executor)
    return {"seed": seed, "best_ms": [float(b) for b in result.history.best], "best_bl": [float(b) for b in best_bl],
            "champion": result.best}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DATA)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quick", action="store_true", help="a smoke test at tiny sizes")
    for k, v in FULL.items():
        ap.add_argument(f"--{k.replace('_', '-')}", type=type(v), default=None, help=f"default {v} ({QUICK[k]} with --quick)")
    ap.add_argument("--only", nargs="*", default=None, help="run only these settings (names of SETTINGS)")
    args = ap.parse_args(argv)
    sizes = dict(QUICK if args.quick else FULL)
    for k in FULL:
        if getattr(args, k) is not None:
            sizes[k] = getattr(args, k)
    for k in ("population", "generations", "seeds", "max_parts"):
        if not sizes[k] >= 1:
            raise ValueError(f"--{k.replace('_', '-')}: must be >= 1, got {sizes[k]}")
    if not (math.isfinite(sizes["seconds"]) and sizes["seconds"] > 0):
        raise ValueError(f"--seconds: must be a positive number, got {sizes['seconds']}")
    names = list(SETTINGS) if args.only is None else args.only
    bad = [n for n in names if n not in SETTINGS]
    if bad:
        raise ValueError(f"--only: unknown setting(s) {bad}; allowed: {list(SETTINGS)}")

    commit = _commit()  # the code the runs use, before anything can change under them
    t0 = time.perf_counter()
    pool = ProcessPoolExecutor(args.workers) if args.workers > 1 else None
    runs = {}
    try:
        for name in names:
            runs[name] = []
            for seed in range(sizes["seeds"]):
                t = time.perf_counter()
                runs[name].append(run_one(SETTINGS[name], seed, sizes, pool))
                r = runs[name][-1]
                print(f"{name}, seed {seed}: best {r['best_ms'][0]:.4f} -> {r['best_ms'][-1]:.4f} m/s "
                      f"({time.perf_counter() - t:.0f} s)", flush=True)
    finally:
        if pool is not None:
            pool.shutdown()
    # the final champions swim Sims' 10 s test again, all in one batch
    flat = [(name, r) for name in names for r in runs[name]]
    champ_seconds = CHAMPION_SECONDS if not args.quick else sizes["seconds"]
    swim = simulate([r["champion"] for _, r in flat], champ_seconds)
    results = {name: [] for name in names}
    for (name, r), com in zip(flat, swim.com):
        body = r["champion"].expand().body
        speed = float(np.linalg.norm(com[-1] - com[0]) / champ_seconds)
        length = body_length(body)
        results[name].append({
            "seed": r["seed"], "best_ms": r["best_ms"], "best_bl": r["best_bl"],
            "champion": {"speed_ms": speed, "speed_bl": speed / length, "body_length": length,
                         "parts": int(body.n_parts), "creature": r["champion"].to_dict()},
        })
    wall = time.perf_counter() - t0
    argv_used = sys.argv[1:] if argv is None else list(argv)
    doc = {
        "format": FORMAT,
        "command": "python benchmarks/data/paper_experiments.py" + "".join(" " + shlex.quote(a) for a in argv_used),
        "coursekit_commit": commit,
        "description": "the paper's section 4.1 experiments: evolve_swimmers per setting and seed; best fitness of "
                       "every generation (m/s and body lengths/s) and the final champion's straight-line speed",
        "sizes": sizes,
        "champion_seconds": champ_seconds,
        "settings": {n: {"ratios": [0.4, 0.3, 0.3], "mutation_rate": 1.0, "joint_types": None, **SETTINGS[n]} for n in names},
        "groups": {g: members for g, members in GROUPS.items() if all(m in names for m in members)},
        "wall_seconds": wall,
        "workers": args.workers,
        "results": results,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(args.out, json.dumps(doc, separators=(",", ":")))
    print(f"{len(flat)} runs in {wall:.0f} s wall; wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
