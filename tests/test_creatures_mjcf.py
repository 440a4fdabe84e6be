"""Genotype -> expansion -> MJCF: every exported creature loads in MuJoCo with the same bodies,
masses, inertias and joint kinematics as our own expansion (issue #4, "Must show")."""

import mujoco  # in the [test] extra: the cross-check must run, never skip
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, operators, to_mjcf
from coursekit.creatures.render import world_poses


def evolved(seed):
    """A random creature after a random chain of the paper's operators."""
    rng = np.random.default_rng(seed)
    a, b = Creature.random(rng), Creature.random(rng)
    for _ in range(int(rng.integers(0, 6))):
        op = rng.integers(3)
        a = operators.mutate(a, rng) if op == 0 else operators.crossover(a, b, rng) if op == 1 else operators.graft(a, b, rng)
    return a


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_exported_creatures_match_mujoco(seed):
    creature = evolved(seed)
    body = creature.expand().body
    model = mujoco.MjModel.from_xml_string(to_mjcf(creature))
    B = body.n_bodies
    assert model.nbody == B + 1  # + MuJoCo's world body
    assert model.njnt == B  # free root joint + one 1-DOF joint per other part
    np.testing.assert_allclose(model.body_mass[1:], body.mass, rtol=1e-12)
    # principal axes are the box axes, so MuJoCo's diagonal inertia equals the cuboid formula
    np.testing.assert_allclose(model.body_inertia[1:], body.inertia, rtol=1e-10, atol=1e-15)
    np.testing.assert_array_equal(model.body_parentid[1:], body.parent + 1)  # world is MuJoCo body 0

    # kinematics: MuJoCo's forward kinematics at a random root pose and random joint coordinates
    # (within limits) puts every part where our own expansion says it is
    rng = np.random.default_rng(seed)
    lo, hi = body.limits[1:, 0], body.limits[1:, 1]
    quat = rng.normal(size=4)
    qpos = np.concatenate([rng.normal(size=3), quat / np.linalg.norm(quat), lo + (hi - lo) * rng.random(B - 1)])
    data = mujoco.MjData(model)
    data.qpos[:] = qpos
    mujoco.mj_kinematics(model, data)
    R, t = world_poses(body, qpos)
    np.testing.assert_allclose(data.xpos[1:], t, atol=1e-9)
    np.testing.assert_allclose(data.xmat[1:].reshape(-1, 3, 3), R, atol=1e-9)


def test_figure1_snake_exports():
    snake = Creature.figure1_snake()
    assert len(snake.nodes) == 2  # the paper's "only two real object instantiations"
    model = mujoco.MjModel.from_xml_string(to_mjcf(snake))
    assert model.nbody - 1 == snake.expand().body.n_bodies == 6  # 4 segments + 2 mirrored legs
