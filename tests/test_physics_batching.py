"""The simulator is batched over the population (issue #5, item 1): no Python loop over creatures
or bodies in a step.

The evidence is the number of tensor operations a step dispatches: it depends on the depth
levels of the packed trees, never on how many creatures share them. Counted on the torch
backend (the same code path as numpy, through ``backend``) with
:class:`coursekit.operations.CountOperations`, which sees every operation torch runs, so one
creature more per level would show up as more operations. On a GPU this count is the number of
kernel launches per step.
"""

import numpy as np
import pytest

from coursekit.creatures.physics import random_body_tree, random_state
from coursekit.creatures.physics.world import World
from coursekit.operations import CountOperations


def _ops_per_step(trees, states, contacts):
    world = World(trees, backend="torch", device="cpu", contacts=contacts)
    world.set_state([s[0] for s in states], [s[1] for s in states])
    world.step()  # first step: lazily built constants are not part of a step
    with CountOperations() as ops:
        world.step()
    assert not world.diverged.any()
    return ops.count


@pytest.mark.parametrize("contacts", [False, True])
def test_operations_per_step_do_not_grow_with_the_number_of_creatures(contacts):
    rng = np.random.default_rng(7)
    trees = [random_body_tree(rng, (6, 14)) for _ in range(4)]
    states = [random_state(rng, t, speed=0.5, inside=0.5) for t in trees]
    one = _ops_per_step(trees, states, contacts)
    five = _ops_per_step(trees * 5, states * 5, contacts)  # the same depth levels, 5x the bodies
    assert one == five
    assert one > 100  # the count sees the step's operations
