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


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_exported_collisions_stay_within_each_creature(seed):
    """With ``contacts=True`` MuJoCo collides the boxes of one creature (never a parent with its
    child, its default filter) and the creatures are spaced so that two never touch, in any pose;
    by default the geoms do not collide at all."""
    from coursekit.creatures.mjcf import reach

    rng = np.random.default_rng(seed)
    creatures = [evolved(seed + k) for k in range(3)]
    bodies = [c.expand().body for c in creatures]
    model = mujoco.MjModel.from_xml_string(to_mjcf(creatures, contacts=True))
    plain = mujoco.MjModel.from_xml_string(to_mjcf(creatures))
    creature_of = np.concatenate([[-1], *[np.full(b.n_bodies, c) for c, b in enumerate(bodies)]])
    for trial in range(5):
        data, data_plain = mujoco.MjData(model), mujoco.MjData(plain)
        quats = rng.normal(size=(3, 4))
        joints = [b.limits[1:, 0] + (b.limits[1:, 1] - b.limits[1:, 0]) * rng.random(b.n_bodies - 1) for b in bodies]
        for d, m in ((data, model), (data_plain, plain)):
            roots = m.jnt_qposadr[m.jnt_type == mujoco.mjtJoint.mjJNT_FREE]  # each at its qpos0 place
            d.qpos[:] = np.concatenate([np.concatenate([m.qpos0[r:r + 3], q / np.linalg.norm(q), j])
                                        for r, q, j in zip(roots, quats, joints)])
            mujoco.mj_forward(m, d)
        assert data_plain.ncon == 0
        for k in range(data.ncon):
            b1, b2 = model.geom_bodyid[data.contact[k].geom1], model.geom_bodyid[data.contact[k].geom2]
            assert creature_of[b1] == creature_of[b2]
            assert model.body_parentid[b1] != b2 and model.body_parentid[b2] != b1
        # every box corner lies within the creature's reach of its root
        start = 1
        for b in bodies:
            ids = np.arange(start, start + b.n_bodies)
            gap = np.linalg.norm(data.xpos[ids] - data.xpos[start], axis=1) + np.linalg.norm(b.half_extents, axis=1)
            assert np.all(gap <= reach(b) + 1e-9)
            start += b.n_bodies
