"""The textbook ABA (physics/reference.py) against the batched one and against MuJoCo (issue #15).

Two independent routes to the same accelerations: the batched simulator (depth levels, constant
coefficients, leaves at once) and the book's per-body loops; MuJoCo's ``mj_forward`` is a third.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures.physics import forward_dynamics, random_body_tree, random_state, reference
from coursekit.creatures.physics import spatial as sp
from coursekit.creatures.physics.aba import aba, articulated_inertias
from coursekit.creatures.physics.jcalc import jcalc
from coursekit.creatures.physics.model import Model
from coursekit.creatures.physics.water import drag_matrix
from mujoco_oracle import mujoco_qacc


def _inputs(rng, trees, with_lock):
    """Random states, forces, external wrenches, drag and locks per creature (BodyTree order)."""
    out = []
    for t in trees:
        J, B = t.n_joints, t.n_bodies
        lock = rng.random(J) < 0.3 if with_lock else None
        out.append(dict(q=rng.uniform(-1.5, 1.5, J), qd=rng.normal(size=J) * 2, v0=rng.normal(size=6), tau=rng.normal(size=J) * 3,
                        f_ext=rng.normal(size=(B, 6)), lock=lock, prescribed=rng.normal(size=J) if with_lock else None))
    return out


def _batched(trees, inputs, damping_of):
    """The batched ABA on all creatures at once, results split back per creature (BodyTree order)."""
    m = Model(trees)
    internal = lambda key: np.concatenate([x[key] for x in inputs])[np.argsort(m.joint_order)]  # noqa: E731
    f_ext = np.concatenate([x["f_ext"] for x in inputs])[m.order]  # packed pre-order -> sorted positions
    damping = damping_of(m)
    v0 = np.stack([x["v0"] for x in inputs])
    lock = None if inputs[0]["lock"] is None else internal("lock")
    prescribed = None if lock is None else internal("prescribed")
    inertias = articulated_inertias(m, internal("q"), lock)
    out = aba(m, internal("q"), internal("qd"), v0, internal("tau"), f_ext=f_ext, damping=damping, inertias=inertias,
              lock=lock, prescribed=prescribed)
    a0, qdd = out[0], out[1][m.joint_order]
    force = out[3]()[m.joint_order] if lock is not None else np.concatenate([x["tau"] for x in inputs])
    offs = np.r_[0, np.cumsum(m.joints_per_creature)]
    first = np.r_[0, np.cumsum(m.bodies_per_creature)]
    D = damping[m.position] if damping is not None else None  # back to packed pre-order
    return [(a0[c], qdd[offs[c] : offs[c + 1]], force[offs[c] : offs[c + 1]], None if D is None else D[first[c] : first[c + 1]])
            for c in range(len(trees))]


def _close(got, want, what):
    scale = max(1.0, np.max(np.abs(want)))
    err = np.max(np.abs(got - want)) / scale if np.size(want) else 0.0
    assert err < 1e-10, f"{what}: relative error {err:.2e}"


@given(st.integers(0, 2**32 - 1), st.booleans(), st.booleans())
@settings(max_examples=30, deadline=None)
def test_textbook_aba_equals_the_batched_aba(seed, with_drag, with_lock):
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (2, 14), prismatic_fraction=0.4) for _ in range(5)]
    inputs = _inputs(rng, trees, with_lock)
    batched = _batched(trees, inputs, (lambda m: drag_matrix(m)) if with_drag else (lambda m: None))
    for c, (t, x, (a0, qdd, force, D)) in enumerate(zip(trees, inputs, batched)):
        ra0, rqdd, rforce = reference.aba(t, x["q"], x["qd"], x["v0"], x["tau"], f_ext=x["f_ext"], damping=D,
                                                       lock=x["lock"], prescribed=x["prescribed"])
        _close(ra0, a0, f"creature {c} root acceleration")
        _close(rqdd, qdd, f"creature {c} joint accelerations")
        _close(rforce, force, f"creature {c} joint forces")
        if with_lock:
            np.testing.assert_array_equal(rqdd[x["lock"]], x["prescribed"][x["lock"]])


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=20, deadline=None)
def test_a_locked_joint_needs_the_force_that_makes_the_free_tree_move_as_prescribed(seed):
    # hybrid dynamics is consistent with plain forward dynamics: apply the locked joints' needed
    # forces to the free tree and it moves exactly as the hybrid one did
    rng = np.random.default_rng(seed)
    t = random_body_tree(rng, (2, 12), prismatic_fraction=0.4)
    x = _inputs(rng, [t], with_lock=True)[0]
    a0, qdd, force = reference.aba(t, x["q"], x["qd"], x["v0"], x["tau"], f_ext=x["f_ext"], lock=x["lock"], prescribed=x["prescribed"])
    b0, bqdd, same = reference.aba(t, x["q"], x["qd"], x["v0"], force, f_ext=x["f_ext"])
    _close(b0, a0, "root acceleration")
    _close(bqdd, qdd, "joint accelerations")
    np.testing.assert_array_equal(same, force)


def _mujoco_population(seed, n):
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (2, 16), prismatic_fraction=0.4) for _ in range(n)]
    states = [random_state(rng, t, speed=2.0) for t in trees]
    tau = [np.r_[rng.normal(size=6) * 5.0, rng.normal(size=t.n_joints) * 10.0] for t in trees]
    return trees, states, tau


def test_textbook_aba_equals_mujoco():
    trees, states, tau = _mujoco_population(7, 20)
    qacc = mujoco_qacc(trees, states, tau)
    ours = reference.forward_dynamics(trees, [s[0] for s in states], [s[1] for s in states], tau)
    offs = np.r_[0, np.cumsum([6 + t.n_joints for t in trees])]
    for c, t in enumerate(trees):
        want = qacc[offs[c] : offs[c + 1]]
        err = np.max(np.abs(ours[c] - want)) / np.max(np.abs(want))
        assert err < 1e-8, f"creature {c} ({t.n_bodies} bodies): relative error {err:.2e}"


def test_textbook_forward_dynamics_has_the_batched_signature_and_layouts():
    trees, states, tau = _mujoco_population(8, 6)
    qpos, qvel = [s[0] for s in states], [s[1] for s in states]
    for kwargs in ({}, {"drag": True}, {"drag": True, "drag_coefficient": 5.0}):
        want = forward_dynamics(trees, qpos, qvel, tau, **kwargs)
        got = reference.forward_dynamics(trees, qpos, qvel, tau, **kwargs)
        for c in range(len(trees)):
            _close(got[c], want[c], f"creature {c} with {kwargs}")
    joint_tau = np.concatenate([t[6:] for t in tau])  # joint forces only, one flat vector
    flat = reference.forward_dynamics(trees, np.concatenate(qpos), np.concatenate(qvel), joint_tau, drag=True)
    _close(flat, forward_dynamics(trees, np.concatenate(qpos), np.concatenate(qvel), joint_tau, drag=True), "flat layout")
    with pytest.raises(ValueError, match="backend"):
        reference.forward_dynamics(trees, qpos, qvel, backend="torch")
    with pytest.raises(ValueError, match="qvel"):
        reference.forward_dynamics(trees, qpos, [v[:-1] for v in qvel])


def test_crm_and_crf_are_the_cross_products_as_matrices():
    rng = np.random.default_rng(3)
    v, m, f = rng.normal(size=(3, 6))
    np.testing.assert_allclose(sp.crm(v) @ m, sp.cross_motion(np, v, m), rtol=0, atol=1e-14)
    np.testing.assert_allclose(sp.crf(v) @ f, sp.cross_force(np, v, f), rtol=0, atol=1e-14)
    # the power of a force is invariant: (v x m) . f + m . (v x* f) = 0
    assert abs((sp.crm(v) @ m) @ f + m @ (sp.crf(v) @ f)) < 1e-12


def test_jcalc_refuses_an_unknown_joint_type():
    with pytest.raises(ValueError, match="joint_type"):
        jcalc(7, np.array([1.0, 0.0, 0.0]), 0.3)
