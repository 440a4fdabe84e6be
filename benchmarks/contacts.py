"""Benchmark: how far do a creature's parts sink into each other while it swims?

Self-collisions are penalty springs (:mod:`coursekit.creatures.physics.contact`) and, by default,
constraint forces that hold each creature's nearest pairs apart
(:mod:`coursekit.creatures.physics.contact_forces`). This measures what each model holds, side by
side in one run (``springs``: ``hold_contacts=False``; ``held``: the default), on the workload evolution runs: ``--creatures`` random creatures
(``Creature.random(default_rng(seed))``, the first generation of ``evolve_swimmers``) and the
shipped champions, each swimming ``--seconds`` s with its own brain after the usual 0.5 s settle.
After every step, every candidate pair (parts of one creature, not joined directly, not fused in
the rest pose) is tested with the separating-axis test; a pair's *penetration* is its overlap
divided by the thinner part's thickness (100 %: the thinner part is wholly inside the other).

Per row: the swim's wall time; the creatures with at least one candidate pair; the worst penetration per creature
(median, 90th percentile, largest); how many creatures ever exceed 25 %; the mean number of
steps per creature in which some pair exceeds 10 %; the creatures the step flagged as diverged.
Champions: the worst penetration in mm and in %, and the steps over 10 %.

Run: ``python benchmarks/contacts.py [--creatures 200] [--seeds 1 2] [--seconds 10]``.
"""

from __future__ import annotations

import argparse
import importlib
import time

import numpy as np

from coursekit.creatures import Creature, simulate
from coursekit.creatures.audit import overlaps
from coursekit.creatures.simulate import DT
from coursekit.creatures.physics.world import World


def swim(creatures, seconds: float, hold: bool = True):
    """``(worst, worst_m, deep_steps, diverged, world, seconds)``: each creature's worst penetration (share of the
    thinner part's thickness, and in metres; 0 without contact), its steps with a pair over 10 %,
    whether the step flagged it, a world holding the creatures (its contacts name the candidate pairs)
    and the swim's wall time (recording included). The swim is
    :func:`~coursekit.creatures.simulate`'s, every step recorded and measured with
    :func:`~coursekit.creatures.audit.overlaps`."""
    start = time.perf_counter()
    swum = simulate(creatures, seconds, record_every=1, hold_contacts=hold)
    elapsed = time.perf_counter() - start
    share, metres = overlaps(creatures, [f[1:] for f in swum.trajectory])  # the steps after the start
    world = World([c.expand().body for c in creatures], dt=swum.dt)
    return share.max(axis=0), metres.max(axis=0), (share > 0.1).sum(axis=0), swum.diverged, world, elapsed


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--creatures", type=int, default=200)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--seconds", type=float, default=10.0)
    args = parser.parse_args(argv)
    steps = int(round(args.seconds / DT))  # simulate's step
    models = {"springs": False, "held": True}
    print(f"| random creatures (seed) | model | time (s) | with pairs | worst p50 / p90 / max | ever > 25 % | steps > 10 % (of {steps}) | diverged |")
    print("|---|---|---:|---:|---:|---:|---:|---:|")
    simulate([Creature.random(np.random.default_rng(0))], 0.5)  # numba compiles before the timings
    for seed in args.seeds:
        rng = np.random.default_rng(seed)
        creatures = [Creature.random(rng) for _ in range(args.creatures)]
        for name, hold in models.items():
            worst, _, deep, diverged, world, elapsed = swim(creatures, args.seconds, hold)
            m = world.model
            paired = np.zeros(m.n_creatures, dtype=bool)
            paired[m.creature[np.asarray(world.contacts.a, dtype=np.int64)]] = True
            ok = paired & ~diverged
            p50, p90, top = (100 * v for v in (np.percentile(worst[ok], 50), np.percentile(worst[ok], 90), worst[ok].max()))
            print(f"| {args.creatures} ({seed}) | {name} | {elapsed:.1f} | {paired.sum()} | {p50:.0f} / {p90:.0f} / {top:.0f} % "
                  f"| {(worst[ok] > 0.25).sum()} | {deep[ok].mean():.0f} | {diverged.sum()} |", flush=True)
    print()
    print(f"| champion | model | worst (mm) | worst (% of the thinner part) | steps > 10 % (of {steps}) |")
    print("|---|---|---:|---:|---:|")
    for champion in importlib.import_module("coursekit.creatures.champions").hall_of_fame():
        for name, hold in models.items():
            worst, worst_m, deep, _, _, _ = swim([champion.creature], args.seconds, hold)
            print(f"| {champion.name} | {name} | {1000 * worst_m[0]:.0f} | {100 * worst[0]:.0f} % | {deep[0]:.0f} |")


if __name__ == "__main__":
    main()
