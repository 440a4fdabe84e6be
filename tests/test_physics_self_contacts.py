"""Self-contacts are internal: whatever holds a creature's parts apart must not be a motor.

Two ways a contact model can swim that the water and the muscles do not pay for, both found while
building contacts as constraints (benchmarks/NOTES.md, "Self-contacts as constraints"): forces that
are not internal at the poses they act at (a creature then drifts in a vacuum), and position
corrections the water does not see (a muscle pushes a part into another through the water, the
correction puts it back for free: a reciprocal stroke becomes a stroke that swims). Randomly wired
creatures (``rhythm=0``) press their parts together without a rhythm, so they are where both show.
"""

import numpy as np
import pytest

from coursekit.creatures import Creature, simulate
from coursekit.creatures.audit import body_length


def _randomly_wired(seed: int, n: int = 150):
    rng = np.random.default_rng(seed)
    return [Creature.random(rng, max_parts=12, rhythm=0.0) for _ in range(n)]


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_creatures_pressing_their_parts_together_go_nowhere_in_a_vacuum(seed):
    # Without water nothing outside a creature pushes it: its centre of mass stays where it is, up to
    # the step's truncation error, which 4 sub-steps make small (in one step some violent creatures
    # drift up to 0.27 m in 6 s, contacts or not: the audit's refine is for them). Measured with the
    # springs (seeds 0-2, 150 creatures, 6 s, 4 sub-steps): 99th percentile 0.0001 m, largest
    # 0.0017 m; contact forces applied away from the poses they were made for: 0.27-0.37 m, 0.35-2.3 m.
    creatures = _randomly_wired(seed)
    swim = simulate(creatures, 6.0, drag_coefficient=0.0, substeps=4)
    alive = ~swim.diverged
    drift = np.linalg.norm(swim.com[alive, -1] - swim.com[alive, 0], axis=1)
    assert alive.sum() >= 0.95 * len(creatures)
    assert np.percentile(drift, 99) < 0.005 and drift.max() < 0.02, (np.percentile(drift, 99), drift.max())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_contacts_do_not_make_randomly_wired_creatures_swim(seed):
    # The fastest tenth of 150 randomly wired creatures, body lengths per second over 6 s, with
    # self-contacts against without: 0.91x, 0.99x, 1.05x with the springs (seeds 0-2); a step-end
    # projection made it 4-5x, contact forces not internal at the stage's poses 5.6x (seed 2).
    creatures = _randomly_wired(seed)
    lengths = np.array([body_length(c.expand().body) for c in creatures])
    fastest = []
    for contacts in (False, True):
        swim = simulate(creatures, 6.0, contacts=contacts)
        speed = np.linalg.norm(swim.com[:, -1] - swim.com[:, 0], axis=1) / 6.0 / lengths
        fastest.append(np.sort(speed)[-len(creatures) // 10:].mean())
    assert fastest[1] < 1.5 * fastest[0], fastest
