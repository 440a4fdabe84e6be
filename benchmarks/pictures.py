"""Benchmark: how fast can a generation of genetic pictures be rendered?

Prints, in one run and on the same genomes (a population of random genomes of about 40
coding nodes, fixed seed), images per second at 128^2 and 256^2 for:

- per-pixel Python (:func:`coursekit.pictures.render_reference`, Sims-style; measured on a
  sample of the population because it is slow),
- whole-image, one genome per call (the numpy-style loop: every primitive a whole-image
  array operation, genomes one after the other, one thread),
- tensorised (:func:`coursekit.pictures.render`: the whole population in one call, a subtree
  that appears anywhere in it computed once) in this process, the same with same-shaped genomes
  stacked (``batch=True``), and with the population split over worker processes (one per core; their start-up, paid once
  per session, is printed separately), with the workers' cache of unwarped pixel maps warm (as
  in a gallery, which renders every generation at one size and window) and cold (cache emptied
  before each run),
- the same on a generation as Sims' interactive loop makes it (20 children of one parent, each
  one mutation away: they share most subtrees, which the evaluator computes once),
- what a gallery shows first: 20 random genomes at the library's defaults
  (:func:`coursekit.pictures.variety.random_population`, about 10 coding nodes each, smaller
  than the population above), over the worker processes,
- tensorised in waves (``group=True``: one operation per primitive for the whole population,
  :mod:`coursekit.pictures.grouped`), in this process,
- tensorised on CUDA, and a population of 256 on CUDA (genome by genome and in waves), when a
  GPU is present.

Measured on an NVIDIA H200 (2026-12-04, before the parameters were read on the host; see
``benchmarks/gpu.py``): 256 genomes at 256^2, 120 pictures/s genome by genome, 353/s in waves.

It also counts the tensor operations that compute (not views) for a population of 256, genome
by genome and in waves: on a GPU each is a kernel launch, which bounds the speed there, so the
count tells on any machine what a GPU will pay.

Times are wall-clock seconds, the best and the median of ``--repeats`` runs (the best is the
better guide on a machine shared with other work).

Usage: ``python benchmarks/pictures.py [--population 20] [--repeats 3] [--reference-sample 2]``
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from coursekit.cli import number
from coursekit.operations import CountOperations
from coursekit.pictures import Genome, render, render_reference
from coursekit.pictures import operators as O
from coursekit.pictures.variety import random_population


def population(n: int, seed: int = 1991, nodes=(35, 45)) -> list[Genome]:
    """``n`` random genomes with a coding size in ``nodes`` (fixed seed)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        g = Genome.random(rng, n_strings=4, head_length=8)
        if nodes[0] <= g.size() <= nodes[1]:
            out.append(g)
    return out


def children(parent: Genome, n: int, seed: int = 5) -> list[Genome]:
    """``n`` children of ``parent``, each made by one random mutation operator (fixed seed)."""
    rng = np.random.default_rng(seed)
    ops = [O.substitution, O.transposition, O.root_transposition, O.head_tail_rotation]
    return [ops[rng.integers(len(ops))](parent, rng) for _ in range(n)]


def best_of(fn, repeats: int) -> tuple[float, float]:
    """Best and median wall-clock seconds of ``repeats`` runs."""
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times))


_fresh = iter(range(1, 1 << 30))


def cold_window():
    """A window not rendered before (shifted by a hair): every worker's cache of unwarped pixel
    maps misses, as on a generation's first look."""
    return (0.0, 0.0, 1.0, 1.0 + 1e-7 * next(_fresh))


def operations_per_image(genomes, group: bool) -> float:
    """Computing tensor operations per picture (64^2, in this process; numpy's kernels, which a
    GPU does not use, are not counted, so the CPU count is a lower bound there)."""
    with CountOperations() as ops:
        render(genomes, 64, workers=1, group=group)
    return ops.count / len(genomes)


def per_image(times, n):
    return times[0] / n, times[1] / n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--population", type=number(int, 1), default=20)
    ap.add_argument("--repeats", type=number(int, 1), default=3)
    ap.add_argument("--reference-sample", type=number(int, 1), default=2,
                    help="genomes timed with the (slow) per-pixel evaluator (at least 1: the last column is against it)")
    ap.add_argument("--sizes", type=number(int, 1), nargs="+", default=[128, 256])
    args = ap.parse_args(argv)

    pop = population(args.population)
    cuda = torch.cuda.is_available()
    print(f"population {len(pop)} genomes, coding nodes mean {np.mean([g.size() for g in pop]):.1f} "
          f"(min {min(g.size() for g in pop)}, max {max(g.size() for g in pop)}); "
          f"CPU cores {os.cpu_count()}, torch {torch.__version__}"
          + (f", GPU {torch.cuda.get_device_name()}" if cuda else ", no GPU"))
    t = time.perf_counter()
    render(pop, max(args.sizes))  # warm-up: worker processes, pixel maps, noise lattice
    print(f"worker processes: {os.cpu_count()}, started (with the first render) in {time.perf_counter() - t:.2f} s")
    render(pop, max(args.sizes), workers=1)
    big = population(256, seed=7)
    print("computing tensor operations per picture, population 256 (kernel launches on a GPU): "
          f"genome by genome {operations_per_image(big, False):.0f}, in waves {operations_per_image(big, True):.0f}")
    rows = []
    for size in args.sizes:
        sample = pop[: args.reference_sample]
        t_ref = per_image(best_of(lambda: [render_reference(g, size) for g in sample], 1), len(sample))
        t_loop = per_image(best_of(lambda: [render(g, size, workers=1) for g in pop], args.repeats), len(pop))
        t_one = per_image(best_of(lambda: render(pop, size, workers=1), args.repeats), len(pop))
        t_stacked = per_image(best_of(lambda: render(pop, size, workers=1, batch=True), args.repeats), len(pop))
        t_waves = per_image(best_of(lambda: render(pop, size, workers=1, group=True), args.repeats), len(pop))
        t_tensor = per_image(best_of(lambda: render(pop, size), args.repeats), len(pop))
        t_cold = per_image(best_of(lambda: render(pop, size, window=cold_window()), args.repeats), len(pop))
        rows += [(size, "per-pixel Python (reference)", len(sample), t_ref),
                 (size, "whole-image, one genome per call", len(pop), t_loop),
                 (size, "tensorised render, this process", len(pop), t_one),
                 (size, "tensorised, same shapes stacked, this process", len(pop), t_stacked),
                 (size, "tensorised in waves, this process", len(pop), t_waves),
                 (size, "tensorised render, worker processes", len(pop), t_tensor),
                 (size, "tensorised render, workers, cold cache", len(pop), t_cold)]
        kids = children(pop[0], len(pop))
        rows += [(size, "children of one parent, one per call", len(kids),
                  per_image(best_of(lambda: [render(g, size, workers=1) for g in kids], args.repeats), len(kids))),
                 (size, "children of one parent, tensorised", len(kids),
                  per_image(best_of(lambda: render(kids, size), args.repeats), len(kids)))]
        first = random_population(np.random.default_rng(2026), len(pop))
        render(first, size)
        rows.append((size, "a gallery's first generation, workers", len(first),
                     per_image(best_of(lambda: render(first, size), args.repeats), len(first))))
        if cuda:
            def on_gpu(genomes, group):
                render(genomes, size, device="cuda", group=group, as_tensor=True)
                torch.cuda.synchronize()
            for genomes, group, name in ((pop, True, "tensorised in waves (CUDA)"),
                                         (big, False, "CUDA, population 256, genome by genome"),
                                         (big, True, "CUDA, population 256, in waves")):
                on_gpu(genomes, group)
                rows.append((size, name, len(genomes),
                             per_image(best_of(lambda: on_gpu(genomes, group), args.repeats), len(genomes))))
        ref = t_ref[0]
        print()
        print(f"{'size':>5} | {'evaluator':46} | {'images':>6} | {'images/s':>9} | "
              f"{'s per 20 images':>15} | {'median':>7} | {'vs per-pixel':>12}")
        for s, name, n, (t, med) in [r for r in rows if r[0] == size]:
            print(f"{s:>4}² | {name:46} | {n:>6} | {1 / t:>9.3g} | {20 * t:>15.3f} | {20 * med:>7.3f} | "
                  f"{ref / t:>11.0f}×")
    return rows


if __name__ == "__main__":
    main()
