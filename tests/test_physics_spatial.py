"""Spatial algebra and the SO(3) chart used by the integrator: identities that must hold exactly."""

import numpy as np
import torch
from hypothesis import given, settings, strategies as st

from coursekit.creatures.body import rotation_about
from coursekit.creatures.physics import spatial as sp

seeds = st.integers(0, 2**32 - 1)


def _random(seed, n=16):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    E = rotation_about(axis, rng.uniform(-np.pi, np.pi, n))
    return rng, E, rng.normal(size=(n, 3))


@given(seeds)
@settings(max_examples=25, deadline=None)
def test_transform_matrix_moves_motion_and_preserves_power(seed):
    rng, E, r = _random(seed)
    m, f = rng.normal(size=(16, 6)), rng.normal(size=(16, 6))
    X = sp.transform_matrix(np, E, r)
    np.testing.assert_allclose(sp.mv(X, m), sp.transform_motion(np, E, r, m), atol=1e-12)
    # power is frame-independent: (X m) . (X^-T f) == m . f
    f_b = np.linalg.solve(X.mT, f[..., None])[..., 0]
    np.testing.assert_allclose(np.sum(sp.mv(X, m) * f_b, axis=1), np.sum(m * f, axis=1), atol=1e-10)
    # the velocity of the new origin is v + w x r, in new coordinates
    np.testing.assert_allclose(sp.mv(X, m)[:, 3:], sp.mv(E, m[:, 3:] + np.cross(m[:, :3], r)), atol=1e-12)


@given(seeds)
@settings(max_examples=25, deadline=None)
def test_cross_products_match_their_matrix_forms(seed):
    rng = np.random.default_rng(seed)
    v, m, f = rng.normal(size=(3, 8, 6))

    def crm(v):
        w, u = v[:3], v[3:]
        W, U = np.cross(w, -np.eye(3)), np.cross(u, -np.eye(3))  # W @ x == w x x
        return np.block([[W, np.zeros((3, 3))], [U, W]])

    for k in range(8):
        np.testing.assert_allclose(sp.cross_motion(np, v[k], m[k]), crm(v[k]) @ m[k], atol=1e-12)
        np.testing.assert_allclose(sp.cross_force(np, v[k], f[k]), -crm(v[k]).T @ f[k], atol=1e-12)


@given(seeds, st.floats(1e-7, 3.0))
@settings(max_examples=40, deadline=None)
def test_quaternion_exponential_and_matrix_round_trip(seed, angle):
    rng = np.random.default_rng(seed)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    q = sp.quat_exp(np, angle * axis)
    np.testing.assert_allclose(np.linalg.norm(q), 1.0, atol=1e-15)
    R = sp.quat_to_mat(np, q)
    np.testing.assert_allclose(R, rotation_about(axis, angle), atol=1e-14)
    np.testing.assert_allclose(sp.mat_to_quat(R), sp.quat_canonical(np, q), atol=1e-14)
    # composing two rotations: quaternion product == matrix product
    q2 = sp.quat_exp(np, rng.normal(size=3))
    np.testing.assert_allclose(sp.quat_to_mat(np, sp.quat_mul(np, q, q2)), R @ sp.quat_to_mat(np, q2), atol=1e-14)


@given(seeds, st.sampled_from([1e-6, 1e-4, 1e-2, 0.5, 2.0]))
@settings(max_examples=40, deadline=None)
def test_chart_derivatives_are_consistent(seed, scale):
    rng = np.random.default_rng(seed)
    theta, theta_dot, x = scale * rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)
    # dexp_inv inverts dexp
    np.testing.assert_allclose(sp.dexp_inv(np, theta, sp.dexp(np, theta, x)), x, atol=1e-12)
    # dexp is the body angular velocity of R0 exp(theta(t)): compare with a finite difference
    h = 1e-6
    R = lambda t: sp.quat_to_mat(np, sp.quat_exp(np, theta + t * theta_dot))  # noqa: E731
    Rdot = (R(h) - R(-h)) / (2 * h)
    W = R(0).T @ Rdot
    omega_fd = np.array([W[2, 1], W[0, 2], W[1, 0]])
    np.testing.assert_allclose(sp.dexp(np, theta, theta_dot), omega_fd, atol=1e-8)
    # dexp_dot is the time derivative of dexp(theta(t)) theta_dot along the same path
    d = lambda t: sp.dexp(np, theta + t * theta_dot, theta_dot)  # noqa: E731
    np.testing.assert_allclose(sp.dexp_dot(np, theta, theta_dot), (d(h) - d(-h)) / (2 * h), atol=1e-7)
    # the integrator's matrices at theta: exp([theta]x) and dexp^-1
    expm, _, dinv, _ = sp.chart_maps(np, theta)
    np.testing.assert_allclose(expm, R(0), atol=1e-12)
    np.testing.assert_allclose(dinv @ x, sp.dexp_inv(np, theta, x), atol=1e-12)
    np.testing.assert_allclose(sp.chart_rates_at(np, theta, theta_dot, sp.chart_maps(np, theta))[0],
                               sp.dexp(np, theta, theta_dot), atol=1e-12)


def test_numpy_and_torch_give_identical_spatial_products():
    rng, E, r = _random(0)
    m = rng.normal(size=(16, 6))
    a = sp.mv(sp.transform_matrix(np, E, r), m)
    import array_api_compat.torch as xt

    b = sp.mv(sp.transform_matrix(xt, torch.as_tensor(E), torch.as_tensor(r)), torch.as_tensor(m)).numpy()
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-15)
