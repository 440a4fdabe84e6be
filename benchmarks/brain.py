"""Brain ticks per second: one vectorised BrainBatch vs a Python loop of per-creature batches.

Run: ``coursekit bench brain`` (or ``PYTHONPATH=. python benchmarks/brain.py [n_creatures ...]``). Prints a side-by-side table
measured in the same run (the loop is the reference a naive implementation would use).
"""

import sys
import time

import numpy as np

from coursekit.creatures import BrainBatch, Creature


def _time(fn, repeat):
    fn()
    t = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t) / repeat


def main(sizes=(30, 300, 1000)):
    rng = np.random.default_rng(0)
    print(f"{'creatures':>9} {'neurons':>8} {'batched ms/tick':>16} {'loop ms/tick':>13} {'speed-up':>9}")
    for n in sizes:
        phs = [Creature.random(rng, n_nodes=(2, 6), neurons=(1, 4), brain_neurons=(1, 4)).expand() for _ in range(n)]
        batch = BrainBatch(phs)
        alone = [BrainBatch([p]) for p in phs]
        ja = rng.normal(size=batch.total_joints)
        ct = rng.choice([-1.0, 1.0], size=(batch.total_bodies, 6))
        cuts_j = np.cumsum([a.total_joints for a in alone])[:-1]
        cuts_b = np.cumsum([a.total_bodies for a in alone])[:-1]
        parts = list(zip(np.split(ja, cuts_j), np.split(ct, cuts_b)))

        def loop():
            for a, (j, c) in zip(alone, parts):
                a.step(j, j, c, 0.01)

        tb = _time(lambda: batch.step(ja, ja, ct, 0.01), 50)
        tl = _time(loop, 3 if n > 300 else 10)
        print(f"{n:>9} {batch.total_neurons:>8} {tb * 1e3:>16.3f} {tl * 1e3:>13.3f} {tl / tb:>8.1f}x")


if __name__ == "__main__":
    main(tuple(int(a) for a in sys.argv[1:]) or (30, 300, 1000))
