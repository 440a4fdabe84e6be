"""Benchmark: how fast can a generation of genetic pictures be rendered?

Prints, in one run and on the same genomes (a population of random genomes of about 40
coding nodes, fixed seed), images per second at 128^2 and 256^2 for:

- per-pixel Python (:func:`coursekit.pictures.render_reference`, Sims-style; measured on a
  sample of the population because it is slow),
- whole-image, one genome per call (the numpy-style loop: every primitive a whole-image
  array operation, genomes one after the other, one thread),
- tensorised (:func:`coursekit.pictures.render`: same-shaped genomes batched, genomes spread
  over the CPU cores),
- tensorised on CUDA, and a population of 256 on CUDA, when a GPU is present.

Wall-clock times drive the images/s column; the CPU column (process time, all threads) is
the better guide on a machine shared with other work.

Usage: ``python benchmarks/pictures.py [--population 20] [--repeats 3] [--reference-sample 2]``
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
import torch

from coursekit.pictures import Genome, render, render_reference


def population(n: int, seed: int = 1991, nodes=(35, 45)) -> list[Genome]:
    """``n`` random genomes with a coding size in ``nodes`` (fixed seed)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n:
        g = Genome.random(rng, n_strings=4, head_length=8)
        if nodes[0] <= g.size() <= nodes[1]:
            out.append(g)
    return out


def best_of(fn, repeats: int) -> tuple[float, float]:
    """Best wall-clock and best process CPU time (all threads) over ``repeats`` runs."""
    wall = cpu = float("inf")
    for _ in range(repeats):
        t, c = time.perf_counter(), time.process_time()
        fn()
        wall, cpu = min(wall, time.perf_counter() - t), min(cpu, time.process_time() - c)
    return wall, cpu


def per_image(times, n):
    return times[0] / n, times[1] / n


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--population", type=int, default=20)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--reference-sample", type=int, default=2,
                    help="genomes timed with the (slow) per-pixel evaluator")
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    args = ap.parse_args(argv)

    pop = population(args.population)
    cuda = torch.cuda.is_available()
    print(f"population {len(pop)} genomes, coding nodes mean {np.mean([g.size() for g in pop]):.1f} "
          f"(min {min(g.size() for g in pop)}, max {max(g.size() for g in pop)}); "
          f"CPU cores {os.cpu_count()}, torch {torch.__version__}"
          + (f", GPU {torch.cuda.get_device_name()}" if cuda else ", no GPU"))
    render(pop, 32)  # warm-up: load pixel maps, noise lattice
    rows = []
    for size in args.sizes:
        sample = pop[: args.reference_sample]
        t_ref = per_image(best_of(lambda: [render_reference(g, size) for g in sample], 1), len(sample))
        t_loop = per_image(best_of(lambda: [render(g, size, workers=1) for g in pop], args.repeats), len(pop))
        t_tensor = per_image(best_of(lambda: render(pop, size), args.repeats), len(pop))
        rows += [(size, "per-pixel Python (reference)", len(sample), t_ref),
                 (size, "whole-image, one genome per call", len(pop), t_loop),
                 (size, "tensorised render (CPU)", len(pop), t_tensor)]
        if cuda:
            def on_gpu(genomes):
                render(genomes, size, device="cuda", as_tensor=True)
                torch.cuda.synchronize()
            on_gpu(pop)
            rows.append((size, "tensorised render (CUDA)", len(pop),
                         per_image(best_of(lambda: on_gpu(pop), args.repeats), len(pop))))
            big = population(256, seed=7)
            on_gpu(big)
            rows.append((size, "tensorised render (CUDA), population 256", 256,
                         per_image(best_of(lambda: on_gpu(big), args.repeats), 256)))
        ref = t_ref[0]
        print()
        print(f"{'size':>5} | {'evaluator':42} | {'images':>6} | {'images/s':>9} | "
              f"{'s per 20 images':>15} | {'CPU s per 20':>12} | {'vs per-pixel':>12}")
        for s, name, n, (t, c) in [r for r in rows if r[0] == size]:
            print(f"{s:>4}² | {name:42} | {n:>6} | {1 / t:>9.3g} | {20 * t:>15.3f} | {20 * c:>12.3f} | "
                  f"{ref / t:>11.0f}×")
    return rows


if __name__ == "__main__":
    main()
