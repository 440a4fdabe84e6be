"""The held self-contacts' building blocks (:mod:`coursekit.creatures.physics.contact_forces`): a
force swept through the articulated inertia is the ABA's response to it, the projected Gauss-Seidel
solve is a solution of the contact problem. The whole-creature outcomes (parts kept apart, no
motor, no drift in a vacuum, no creature spun apart) are in ``tests/test_physics_self_contacts.py``."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures.physics import compiled, random_body_tree
from coursekit.creatures.physics.aba import aba, articulated_inertias, impulse
from coursekit.creatures.physics.contact_forces import pgs
from coursekit.creatures.physics.model import Model


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), locked=st.floats(0.0, 0.7))
def test_a_wrench_swept_from_rest_is_the_abas_response_to_that_force(seed, locked):
    # impulse(wrench=) is the response the stages add for the contact forces: the ABA's accelerations
    # under f_ext for a body at rest with no joint forces (no velocity terms, no drag), the locked
    # joints keeping their rates
    rng = np.random.default_rng(seed)
    m = Model([random_body_tree(rng, (2, 10)) for _ in range(3)])
    q = rng.uniform(m.limits_np[:, 0], m.limits_np[:, 1])
    wrench = rng.normal(size=(m.n_bodies, 6))
    lock = rng.random(m.n_joints) < locked
    zero = np.zeros(m.n_joints)
    a0, qdd, _, _ = aba(m, q, zero, np.zeros((m.n_creatures, 6)), zero, f_ext=wrench, inertias=articulated_inertias(m, q, lock), lock=lock)
    dv0, dqd = impulse(m, articulated_inertias(m, q, lock), lock, zero, wrench=wrench)
    np.testing.assert_allclose(dv0, a0, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(dqd, qdd, rtol=1e-9, atol=1e-9)
    assert np.all(dqd[lock] == 0.0)
    if compiled.available():  # the compiled sweep, joint by joint in the packed order
        fast = compiled.Dynamics(m)
        cv0, cqd = fast.impulse(fast.inertias(q, lock), lock, zero, wrench)
        np.testing.assert_allclose(cv0, a0, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(cqd, qdd, rtol=1e-9, atol=1e-9)


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), K=st.integers(1, 6))
def test_the_projected_gauss_seidel_solve_solves_the_contact_problem(seed, K):
    # 0 <= f <= hi, w = D f + b >= 0 where f is below its bound, f w = 0 (to the convergence of
    # enough sweeps); a slot that cannot open (diagonal at its floor) takes nothing
    rng = np.random.default_rng(seed)
    C = 4
    J = rng.normal(size=(C, K, K + 2))
    D = J @ np.swapaxes(J, 1, 2) + 1e-3 * np.eye(K)
    b = rng.normal(size=(C, K))
    hi = np.where(rng.random((C, K)) < 0.3, rng.uniform(0.0, 1.0, (C, K)), np.inf)
    floor = np.zeros((C, K))
    floor[:, -1] = np.where(rng.random(C) < 0.5, D[:, -1, -1], 0.0)  # some creatures' last slot cannot open
    f = pgs(np, D, b, floor, hi, iterations=2000)
    w = np.einsum("cjk,ck->cj", D, f) + b
    shut = floor >= np.stack([D[:, k, k] for k in range(K)], axis=1)
    assert np.all(f[shut] == 0.0)
    free = ~shut
    assert np.all(f >= 0.0) and np.all(f <= hi)
    scale = 1.0 + np.abs(b).max()
    # the open slots are solved (the shut ones are left out of the problem, whatever their w)
    below = free & (f < hi)
    assert np.all(w[below] >= -1e-6 * scale)
    assert np.all(np.abs(f[below] * w[below]) <= 1e-6 * scale * (1.0 + f[below]))
