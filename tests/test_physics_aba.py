"""The fast ABA's building blocks against independent references (issue #5, performance work).

The end-to-end MuJoCo agreement lives in test_physics_mujoco.py; here each shortcut the batched
simulator takes is checked on its own: the packed layout, the constant-coefficient joint
transforms and leaf inertias (against Rodrigues' formula and the textbook congruence), forward
kinematics (against the phenotype's per-creature poses), the vectorised separating-axis test
(against a plain per-pair implementation) and the segment and scatter sums.
"""


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures.body import REVOLUTE, rotation_about
from coursekit.creatures.phenotype import part_poses
from coursekit.creatures.physics import jcalc, random_body_tree
from coursekit.creatures.physics import backend as bk
from coursekit.creatures.physics import spatial as sp
from coursekit.creatures.physics.model import Model
from coursekit.creatures.physics.world import World


def _population(seed, n=6, sizes=(2, 16)):
    rng = np.random.default_rng(seed)
    return rng, [random_body_tree(rng, sizes, prismatic_fraction=0.4) for _ in range(n)]


def _reference_joint(tree, i, q):
    """Parent-to-child rotation E and child origin r (parent coordinates) of body i, as in the
    phenotype's kinematics (Rodrigues about the joint axis, then the fixed joint rotation)."""
    if tree.joint_type[i] == REVOLUTE:
        R = tree.joint_rot[i] @ rotation_about(tree.joint_axis[i], q)
        r = tree.joint_pos_parent[i] - R @ tree.joint_pos_child[i]
    else:
        R = tree.joint_rot[i]
        r = tree.joint_pos_parent[i] + R @ (q * tree.joint_axis[i] - tree.joint_pos_child[i])
    return R.T, r


@given(st.integers(0, 2**32 - 1))
@settings(max_examples=15, deadline=None)
def test_packed_layout_roots_inner_levels_then_leaves(seed):
    _, trees = _population(seed)
    m = Model(trees)
    C, L, N = m.n_creatures, m.leaf_start, m.n_bodies
    par = m.parent
    assert np.all(par[:C] == -1) and np.all(par[C:] >= 0)
    assert np.all(par[C:] < np.arange(C, N)), "every parent is stored before its children"
    has_child = np.zeros(N, bool)
    has_child[par[C:]] = True
    assert not has_child[L:].any() and has_child[C:L].all(), "inner bodies first, leaves last"
    prev = (0, C)
    for s, e, p, seg in m.levels:  # each level's parents are exactly the previous level's bodies
        assert prev[0] <= par[s:e].min() and par[s:e].max() < prev[1] and seg.start == prev[0]
        prev = (s, e)
    assert prev[1] == L
    # same multiset of bodies per creature as the trees
    np.testing.assert_array_equal(np.bincount(m.creature), [t.n_bodies for t in trees])
    np.testing.assert_array_equal(np.sort(m.order), np.arange(N))


@given(st.integers(0, 2**32 - 1), st.floats(-7.0, 7.0))
@settings(max_examples=25, deadline=None)
def test_joint_transforms_from_constant_coefficients_equal_rodrigues(seed, scale):
    rng, trees = _population(seed)
    m = Model(trees)
    C = m.n_creatures
    q = rng.uniform(-1, 1, m.n_joints) * scale  # angles of several turns, slides of metres
    E, r = jcalc.joint_transforms(m, q)
    X = jcalc.joint_transform_matrices(m, q)
    tree_of = np.repeat(np.arange(C), [t.n_bodies for t in trees])[m.order]
    local = m.order - np.r_[0, np.cumsum([t.n_bodies for t in trees])][tree_of]
    for j in range(m.n_joints):
        t, i = trees[tree_of[C + j]], local[C + j]
        E_ref, r_ref = _reference_joint(t, i, q[j])
        np.testing.assert_allclose(E[j], E_ref, rtol=0, atol=1e-13)
        np.testing.assert_allclose(r[j], r_ref, rtol=0, atol=1e-13 * max(1.0, abs(q[j])))
        np.testing.assert_allclose(X[j], sp.transform_matrix(np, E_ref, r_ref), rtol=0, atol=1e-13 * max(1.0, abs(q[j])))


@given(st.integers(0, 2**32 - 1), st.floats(-7.0, 7.0))
@settings(max_examples=25, deadline=None)
def test_leaf_inertia_polynomial_equals_the_congruence(seed, scale):
    rng, trees = _population(seed, sizes=(3, 12))
    m = Model(trees)
    C, L = m.n_creatures, m.leaf_start
    q = rng.uniform(-1, 1, m.n_joints) * scale
    X = jcalc.joint_transform_matrices(m, q)[L - C :]
    Il, Sl = m.inertia_diag_np[L:], m.S_np[L - C :]
    U = Il * Sl
    Ia = np.einsum("ni,ij->nij", Il, np.eye(6)) - U[:, :, None] * U[:, None, :] / np.sum(Sl * U, axis=1)[:, None, None]
    want = X.mT @ Ia @ X
    got = (jcalc.joint_basis(np, m.revolute, q)[L - C :, None, :] @ m.leaf_P).reshape(-1, 6, 6)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * max(1.0, scale * scale) * np.abs(want).max())


def test_forward_kinematics_matches_the_phenotype_poses():
    rng, trees = _population(11, n=8)
    m = Model(trees)
    q = rng.uniform(-2, 2, m.n_joints)
    R, p = jcalc.forward_kinematics(m, np.tile(np.eye(3), (m.n_creatures, 1, 1)), np.zeros((m.n_creatures, 3)), q)
    q_user = q[m.joint_order]
    offs = np.r_[0, np.cumsum(m.joints_per_creature)]
    first = np.r_[0, np.cumsum([t.n_bodies for t in trees])]
    for c, t in enumerate(trees):
        Rw, tw = part_poses(t, q_user[offs[c] : offs[c + 1]])
        pos = m.position[first[c] : first[c] + t.n_bodies]
        np.testing.assert_allclose(R[pos], Rw, rtol=0, atol=1e-12)
        np.testing.assert_allclose(p[pos], tw, rtol=0, atol=1e-12)


def _sat_one_pair(Ra, pa, ha, Rb, pb, hb):
    """Textbook separating-axis test of two boxes, one pair at a time: (depth, unit normal A->B)."""
    axes = [Ra[:, i] for i in range(3)] + [Rb[:, j] for j in range(3)]
    axes += [np.cross(Ra[:, i], Rb[:, j]) for i in range(3) for j in range(3)]
    d = pb - pa
    best = (np.inf, None)
    for k, n in enumerate(axes):
        length = np.linalg.norm(n)
        if k >= 6 and length <= 1e-6:
            continue
        n = n / length
        ra = np.sum(ha * np.abs(Ra.T @ n))
        rb = np.sum(hb * np.abs(Rb.T @ n))
        overlap = ra + rb - abs(d @ n)
        if overlap < best[0]:
            best = (overlap, n if d @ n >= 0 else -n)
    return best


def test_vectorised_separating_axis_test_equals_a_per_pair_reference():
    rng, trees = _population(5, n=12, sizes=(6, 14))
    w = World(trees, contacts=True)
    m = w.model
    q = rng.uniform(-1.5, 1.5, m.n_joints)
    R, p = jcalc.forward_kinematics(m, np.tile(np.eye(3), (m.n_creatures, 1, 1)), np.zeros((m.n_creatures, 3)), q)
    c = w.contacts
    pair, a, b, n, depth, x = c.detect(R, p)
    assert 10 < len(pair) < c.n_pairs, "the population must have both touching and separate pairs"
    h = m.half_extents_np
    found = dict(zip(pair.tolist(), range(len(pair))))
    for k in range(c.n_pairs):
        i, j = int(c.a[k]), int(c.b[k])
        ov, nrm = _sat_one_pair(R[i], p[i], h[i], R[j], p[j], h[j])
        if ov > 1e-9:
            assert k in found, f"pair {k} overlaps by {ov} but was not reported"
            r = found[k]
            assert depth[r] == pytest.approx(ov, rel=1e-9, abs=1e-12)
            assert abs(n[r] @ nrm) == pytest.approx(1.0, abs=1e-9)
            assert n[r] @ (p[j] - p[i]) >= -1e-12
        elif ov < -1e-9:
            assert k not in found
    # contact point: midpoint of A's deepest vertex along n and B's along -n
    for r in range(len(pair)):
        i, j = int(a[r]), int(b[r])
        vA = p[i] + R[i] @ (h[i] * np.where(np.abs(R[i].T @ n[r]) < 1e-9, 0, np.sign(R[i].T @ n[r])))
        vB = p[j] - R[j] @ (h[j] * np.where(np.abs(R[j].T @ n[r]) < 1e-9, 0, np.sign(R[j].T @ n[r])))
        np.testing.assert_allclose(x[r], 0.5 * (vA + vB), rtol=0, atol=1e-12)


@given(st.integers(0, 2**32 - 1), st.integers(1, 40), st.sampled_from([(), (6,), (6, 6)]))
@settings(max_examples=30, deadline=None)
def test_segment_and_scatter_sums_equal_add_at(seed, n, shape):
    rng = np.random.default_rng(seed)
    parent = np.sort(rng.integers(3, 10, n))
    values = rng.normal(size=(n,) + shape)
    start = rng.normal(size=(12,) + shape)
    want, got, got2 = (start.copy() for _ in range(3))
    np.add.at(want, parent, values)
    flat = values.reshape(n, -1) if shape else values
    bk.Segments(np, parent, (3, 10)).add_into(got, flat)
    bk.scatter_add(np, got2, parent, values)
    for result in (got, got2):
        np.testing.assert_allclose(result, want, rtol=0, atol=1e-12)


@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.integers(1, 4), st.sampled_from([(), (1,), (6,), (6, 6)]))
@settings(max_examples=40, deadline=None)
def test_segment_sums_are_scipy_sparse_products_bit_for_bit(seed, n, k, shape):
    """Segments multiplies by scipy's kernels directly: the result is bit for bit the public product's."""
    import scipy.sparse

    rng = np.random.default_rng(seed)
    parent = np.sort(rng.integers(3, 10, n))
    start = rng.normal(size=(12,) + shape)
    values, weights = rng.normal(size=(n, k) + shape), rng.normal(size=(n, k))
    rows = np.repeat(parent - 3, k)
    A = scipy.sparse.csr_matrix((weights.reshape(-1), (rows, np.arange(n * k))), shape=(7, n * k))
    ones = scipy.sparse.csr_matrix((np.ones(n), (parent - 3, np.arange(n))), shape=(7, n))
    want_weighted, want_sum = start.copy(), start.copy()
    want_weighted[3:10] += (A @ values.reshape(n * k, -1)).reshape((7,) + shape)
    want_sum[3:10] += (ones @ values[:, 0].reshape(n, -1)).reshape((7,) + shape)
    segments = bk.Segments(np, parent, (3, 10))
    got_weighted, got_sum = start.copy(), start.copy()
    segments.add_weighted(got_weighted, weights, values)
    segments.add_into(got_sum, values[:, 0].reshape(n, -1))
    assert np.array_equal(got_weighted, want_weighted) and np.array_equal(got_sum, want_sum)


@given(st.integers(0, 2**32 - 1), st.integers(1, 3), st.integers(1, 4))
@settings(max_examples=40, deadline=None)
def test_numpy_namespace_calls_numpy_bit_for_bit(seed, ndim, count):
    """The simulator's numpy namespace (take, reshape, sum and stack on the arrays) gives numpy's results."""
    rng = np.random.default_rng(seed)
    shape = tuple(rng.integers(1, 5, ndim))
    arrays = [rng.normal(size=shape) for _ in range(count)]
    xp, a = bk.namespace("numpy"), arrays[0]
    for axis in range(-ndim - 1, ndim + 1):
        assert np.array_equal(xp.stack(arrays, axis=axis), np.stack(arrays, axis=axis))
    for axis in range(-ndim, ndim):
        idx = rng.integers(0, shape[axis], 5)
        assert np.array_equal(xp.take(a, idx, axis=axis), np.take(a, idx, axis=axis))
        assert np.array_equal(xp.sum(a, axis=axis, keepdims=True), np.sum(a, axis=axis, keepdims=True))
    assert np.array_equal(xp.reshape(a, (-1,)), np.reshape(a, (-1,))) and xp.sum(a) == np.sum(a)
    with pytest.raises(ValueError):
        xp.stack(arrays + [np.zeros(shape + (2,))], axis=0)
    with pytest.raises(np.exceptions.AxisError):  # numpy's own error
        xp.stack(arrays, axis=ndim + 1)
    assert bk.is_numpy(xp) and not bk.is_torch(xp)
