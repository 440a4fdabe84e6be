"""Sims' 1994 experiment on this machine: 300 swimmers x 100 generations x 10 simulated seconds.

Karl Sims ran it on a 32-processor CM-5 in about three hours. This runs it with his operators
and rates (:func:`coursekit.creatures.evolve_swimmers` at its defaults: the best fifth survive,
offspring proportional to fitness, children 40 % mutated, 30 % recombined, 30 % grafted) on every
core (one batch per worker process, :class:`~coursekit.creatures.evolution.SwimmerFitness`),
and reports per generation the wall time and the best and mean fitness in m/s, with the best in
body lengths per second; then the champion of each seed: its speed over 10 s, its pace (the
second half's distance over the first half's) and its audit (:mod:`coursekit.creatures.audit`).

Throughput is creature-seconds simulated per wall-second, counting the generation's evaluations
(the re-scoring of the top three at an eighth of the step is extra work, not counted).

The creatures swim with the simulator's default step, compiled with numba
(:mod:`~coursekit.creatures.physics.compiled`); ``--numpy-step`` runs the numpy step instead: the
same physics up to rounding, so another run (``benchmarks/NOTES.md`` times the two).

    python benchmarks/sims_scale.py [--seeds 0 1 2] [--workers N] [--out DIR] [--numpy-step] [--rhythm P]
    python benchmarks/sims_scale.py --quick          # 24 creatures x 3 generations x 2 s (CI)
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
from coursekit.cli import number, probability
from coursekit.creatures import evolve_swimmers, resume_swimmers, simulate
from coursekit.creatures.audit import audit, body_length
from coursekit.creatures.generation import RHYTHM


def run(seed: int, population: int, generations: int, seconds: float, workers: int, checkpoint: Path | None = None,
        torch_device: str | None = None, numpy_step: bool = False, rhythm: float = RHYTHM):
    """One seed's run; with ``checkpoint`` it saves every generation and resumes a killed run; with
    ``torch_device`` the generation swims in this process on torch there, with the graph-ready step
    (a CUDA graph on a GPU); with ``numpy_step`` the workers run the numpy step instead of the
    compiled one (``World(compiled=False)``); ``rhythm``: ``Creature.random``'s, for the first
    generation (0: random wiring only, as the shipped Sims-scale champions were bred)."""
    options = dict(compiled=False) if numpy_step else {}
    if torch_device is not None:
        options, workers = dict(backend="torch", device=torch_device, graph=True), 1
    rows, start = [], time.perf_counter()

    def record(result):
        best = result.best
        length = body_length(best.expand().body)
        rows.append(dict(generation=result.generation, wall=time.perf_counter() - start, best=result.best_fitness,
                         best_per_length=result.best_fitness / length, mean=float(np.mean(result.fitness))))
        print(_row(rows[-1]), flush=True)

    print(f"\nseed {seed}\n{HEADER}", flush=True)
    pool = ProcessPoolExecutor(workers) if workers > 1 else None
    try:
        if checkpoint is not None and checkpoint.exists():
            print(f"resuming {checkpoint}", flush=True)
            result = resume_swimmers(checkpoint, generations=generations, seconds=seconds, progress=False,
                                     callback=record, executor=pool, **options)
        else:
            result = evolve_swimmers(generations=generations, rng=np.random.default_rng(seed), population_size=population,
                                     seconds=seconds, progress=False, callback=record, executor=pool,
                                     checkpoint=checkpoint, random_options=dict(rhythm=rhythm), **options)
    finally:
        if pool is not None:
            pool.shutdown()
    return result, rows, time.perf_counter() - start


HEADER = "gen   wall s   best m/s  best BL/s   mean m/s"


def _row(r: dict) -> str:
    return f"{r['generation']:3d} {r['wall']:8.1f} {r['best']:10.4f} {r['best_per_length']:10.4f} {r['mean']:10.4f}"


def champion(creature, seconds: float = 10.0, **options) -> dict:
    """Speed, pace and audit of a champion over ``seconds`` (``options``: the simulator's)."""
    r = simulate([creature], seconds, **options)
    com = r.com[0]
    half = len(com) // 2
    first, second = (np.linalg.norm(com[b] - com[a]) for a, b in ((0, half), (half, -1)))
    report = audit([creature], seconds, **options)[0]
    return dict(speed=report.speed, body_lengths_per_second=report.body_lengths_per_second, pace=second / max(first, 1e-12),
                audit=str(report), passed=report.passed)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=number(int, 0), nargs="+", default=[0])
    parser.add_argument("--population", type=number(int, 2), default=300)
    parser.add_argument("--generations", type=number(int, 0), default=100)
    parser.add_argument("--seconds", type=number(float, 0, above=True), default=10.0)
    parser.add_argument("--workers", type=number(int, 1), default=os.cpu_count() or 1)
    parser.add_argument("--quick", action="store_true", help="24 creatures x 3 generations x 2 s")
    parser.add_argument("--torch-device", help="swim on torch on this device (e.g. cuda), in this process, "
                                               "with the graph-ready step (World(graph=True)), instead of numpy in worker processes")
    parser.add_argument("--numpy-step", action="store_true", help="the numpy step (World(compiled=False)) instead of the "
                                                                   "compiled one: the same physics up to rounding, so another run")
    parser.add_argument("--rhythm", type=probability, default=RHYTHM, help="share of the first generation's effectors driven "
                        f"by oscillators of one frequency (default {RHYTHM}; 0: random wiring only, as the shipped champions were bred)")
    parser.add_argument("--out", type=Path, help="folder for each seed's champion (JSON) and table")
    args = parser.parse_args(argv)
    if args.quick:
        args.population, args.generations, args.seconds = 24, 3, 2.0
    print(f"Sims' experiment: {args.population} creatures x {args.generations} generations x {args.seconds:g} s, "
          + (f"torch on {args.torch_device} (graph-ready step)" if args.torch_device else f"{args.workers} worker process(es)")
          + f", seeds {args.seeds}")
    summary = []
    for seed in args.seeds:
        checkpoint = args.out / f"checkpoint-seed{seed}.ckpt" if args.out else None
        if args.out:
            args.out.mkdir(parents=True, exist_ok=True)
        result, rows, wall = run(seed, args.population, args.generations, args.seconds, args.workers, checkpoint,
                                 args.torch_device, args.numpy_step, args.rhythm)
        evaluations = sum(result.history.evaluations[len(result.history.evaluations) - len(rows):])  # this process's
        champ = champion(result.best, max(args.seconds, 10.0), **(dict(compiled=False) if args.numpy_step else {}))
        g0, gN = result.history.best[0], result.history.best[-1]
        print(f"wall {wall:.0f} s; {evaluations * args.seconds / wall:.1f} creature-seconds per wall-second; "
              f"best fitness {g0:.4f} -> {gN:.4f} m/s ({gN / max(g0, 1e-12):.1f}x)")
        print(f"champion over 10 s: {champ['speed']:.4f} m/s = {champ['body_lengths_per_second']:.3f} body lengths/s, "
              f"pace {champ['pace']:.2f}; audit: {champ['audit']}")
        entry = dict(seed=seed, wall=wall, evaluations=evaluations, generations=rows, champion=champ,
                     command=f"coursekit bench sims_scale --seeds {seed} --population {args.population} "
                             f"--generations {args.generations} --seconds {args.seconds:g} --rhythm {args.rhythm:g}"
                             + (" --numpy-step" if args.numpy_step else ""))
        summary.append(entry)
        if args.out:
            atomic_write(args.out / f"champion-seed{seed}.json", result.best.to_json())
    if args.out:
        atomic_write(args.out / "sims_scale.json", json.dumps(summary, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
