"""Cross-check: our batched ABA equals MuJoCo's mj_forward on the exported MJCF (issue #5)."""

import numpy as np
import pytest

import mujoco  # in the [test] extra: the cross-check must run, never skip

from coursekit.creatures.mjcf import to_mjcf
from mujoco_oracle import mujoco_qacc
from coursekit.creatures.physics import Model, forward_dynamics, random_body_tree, random_state

N_CREATURES = 60


def _population(seed, n=N_CREATURES):
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (2, 20)) for _ in range(n)]
    states = [random_state(rng, t, speed=2.0) for t in trees]
    tau = [np.r_[rng.normal(size=6) * 5.0, rng.normal(size=t.n_joints) * 10.0] for t in trees]
    return trees, states, tau


@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_forward_dynamics_matches_mujoco(backend):
    trees, states, tau = _population(0)
    ref = mujoco_qacc(trees, states, tau)
    ours = forward_dynamics(trees, [s[0] for s in states], [s[1] for s in states], tau, backend=backend)
    offs = np.r_[0, np.cumsum([6 + t.n_joints for t in trees])]
    assert len(ours) == len(trees)
    for c, t in enumerate(trees):
        want = ref[offs[c] : offs[c + 1]]
        err = np.max(np.abs(ours[c] - want)) / np.max(np.abs(want))
        assert err < 1e-8, f"creature {c} ({t.n_bodies} bodies): relative error {err:.2e}"


def test_joint_only_forces_and_flat_layout_agree_with_list_layout():
    trees, states, tau = _population(1, n=5)
    joint_tau = [t[6:] for t in tau]
    full = [np.r_[np.zeros(6), t] for t in joint_tau]
    a = forward_dynamics(trees, [s[0] for s in states], [s[1] for s in states], joint_tau)
    b = forward_dynamics(trees, np.concatenate([s[0] for s in states]), np.concatenate([s[1] for s in states]), np.concatenate(full))
    np.testing.assert_array_equal(np.concatenate(a), b)
    np.testing.assert_allclose(b, mujoco_qacc(trees, states, full), rtol=1e-9, atol=1e-9 * np.abs(b).max())


def test_mjcf_has_exact_mass_inertia_limits_and_motors():
    rng = np.random.default_rng(2)
    tree = random_body_tree(rng, 8)
    model = mujoco.MjModel.from_xml_string(to_mjcf(tree))
    assert model.nq == 7 + 7 and model.nv == 6 + 7 and model.nu == 7
    np.testing.assert_allclose(model.body_mass[1:], tree.mass, rtol=1e-15)
    np.testing.assert_allclose(model.body_inertia[1:], tree.inertia, rtol=1e-15)
    np.testing.assert_allclose(model.jnt_range[1:], tree.limits[1:], rtol=1e-15)
    np.testing.assert_allclose(model.actuator_gear[:, 0], tree.gain[1:], rtol=1e-15)
    np.testing.assert_allclose(model.actuator_forcerange[:, 1], tree.strength[1:], rtol=1e-15)
    assert np.all(model.opt.gravity == 0)
    assert model.jnt_type[0] == mujoco.mjtJoint.mjJNT_FREE


def test_bad_layout_is_refused_with_named_field():
    trees, states, _ = _population(3, n=2)
    with pytest.raises(ValueError, match="qvel"):
        forward_dynamics(trees, [s[0] for s in states], [s[1][:-1] for s in states])
    with pytest.raises(TypeError, match="creatures"):
        Model([object()])


def test_non_depth_first_tree_is_refused_by_mjcf():
    from coursekit.creatures.body import BodyTree

    t = random_body_tree(np.random.default_rng(4), 4)
    bad = BodyTree([-1, 0, 0, 1], t.half_extents, t.joint_type, t.joint_axis, t.joint_pos_parent, t.joint_pos_child, t.joint_rot, t.limits, t.gain, t.strength)
    with pytest.raises(ValueError, match="depth-first"):
        to_mjcf(bad)
