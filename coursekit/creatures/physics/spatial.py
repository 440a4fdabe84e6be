"""Batched spatial vector algebra in Featherstone's notation (paper section 2.4).

Spatial motion vectors are ``(angular, linear)`` 6-vectors, spatial forces ``(moment, force)``.
A Plücker transform ``X`` from frame A to frame B is stored as its 3x3 blocks: ``E`` (rotation
taking A-coordinates to B-coordinates) and ``r`` (B's origin in A-coordinates), so that
``X = [[E, 0], [-E rx, E]]``. Every function works on stacks (leading batch axes) and on numpy and
torch arrays alike; ``xp`` is the array namespace.
"""

from __future__ import annotations

import numpy as np

from . import backend as bk


def _split3(a, axis):
    return (a[0], a[1], a[2]) if axis == 0 else (a[..., 0], a[..., 1], a[..., 2])


def cross3(xp, a, b, axis=-1):
    """Cross products of 3-vectors stored along ``axis`` (-1, or 0 for component-major arrays,
    whose contiguous rows numpy multiplies much faster). Written out: torch and numpy agree bit
    for bit."""
    a0, a1, a2 = _split3(a, axis)
    b0, b1, b2 = _split3(b, axis)
    return xp.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=axis)


def _halves(v, axis):
    return (v[:3], v[3:]) if axis == 0 else (v[..., :3], v[..., 3:])


# numpy's stacked ``matvec`` hands small matrices with contiguous rows to BLAS one at a time;
# on views with the summed axis reversed (the same sum, in the opposite order, no copy) numpy's
# own loop runs instead, 1.5-2.5 times faster for 6x6 and 3x3 (benchmarks/NOTES.md).


def mv(A, x, out=None):
    """Stacked matrix-vector product ``A @ x`` for (..., n, m) and (..., m) (into ``out`` if given)."""
    if isinstance(A, np.ndarray):
        return np.matvec(A[..., ::-1], x[..., ::-1], out=out)  # reversed views: see above
    if out is None:
        return (A @ x[..., None])[..., 0]
    out[...] = (A @ x[..., None])[..., 0]
    return out


def mtv(A, x, out=None):
    """Stacked transposed product ``A' @ x`` for (..., m, n) and (..., m), without a transpose
    (into ``out`` if given)."""
    if isinstance(A, np.ndarray):
        return np.matvec(A.mT[..., ::-1], x[..., ::-1], out=out)  # reversed views: see above
    if out is None:
        return (x[..., None, :] @ A)[..., 0, :]
    out[...] = (x[..., None, :] @ A)[..., 0, :]
    return out


def dot(xp, a, b):
    """Row-wise dot products ``sum(a * b, -1)`` of (..., n) stacks (numpy: ``vecdot`` on the
    reversed views, numpy's own loop -- about 2.5 times faster than on contiguous rows, which go
    to BLAS's ``ddot`` row by row; each row is summed on its own, so a creature's result does not
    depend on where its rows sit in the batch)."""
    if bk.is_numpy(xp):
        return np.vecdot(a[..., ::-1], b[..., ::-1])
    return (a * b).sum(-1)  # torch: a third of the time of array_api_compat's vecdot wrapper


def outer(xp, a, b):
    """Stacked outer products ``a b'`` of (..., n) and (..., m)."""
    if bk.is_numpy(xp):
        return np.einsum("...i,...j->...ij", a, b)
    return a[..., :, None] * b[..., None, :]


def cross_motion(xp, v, m, axis=-1):
    """Spatial motion cross product ``v x m`` (Featherstone's crm(v) @ m); 6-vectors along ``axis``."""
    (w, u), (mw, mu) = _halves(v, axis), _halves(m, axis)
    return xp.concat([cross3(xp, w, mw, axis), cross3(xp, w, mu, axis) + cross3(xp, u, mw, axis)], axis=axis)


def cross_force(xp, v, f, axis=-1):
    """Spatial force cross product ``v x* f`` (Featherstone's crf(v) @ f); 6-vectors along ``axis``."""
    (w, u), (n, fl) = _halves(v, axis), _halves(f, axis)
    return xp.concat([cross3(xp, w, n, axis) + cross3(xp, u, fl, axis), cross3(xp, w, fl, axis)], axis=axis)


def skew(a) -> np.ndarray:
    """The 3x3 matrix ``[a]x`` with ``[a]x b = a x b`` (one 3-vector, numpy)."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def crm(v) -> np.ndarray:
    """Featherstone's ``crm(v)`` (6, 6) for one motion vector ``v``: ``crm(v) @ m = v x m``
    (:func:`cross_motion` as a matrix; numpy).

    >>> spin = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0])  # turning about z at 1 rad/s
    >>> (crm(spin) @ np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])).tolist()  # a velocity along x turns towards y
    [0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
    """
    w, u = skew(v[:3]), skew(v[3:])
    return np.block([[w, np.zeros((3, 3))], [u, w]])


def crf(v) -> np.ndarray:
    """Featherstone's ``crf(v) = -crm(v)'`` (6, 6): ``crf(v) @ f = v x* f`` for a force ``f``
    (:func:`cross_force` as a matrix; numpy)."""
    return -crm(v).T


def transform_motion(xp, E, r, m):
    """``X @ m`` for the transform ``X = (E, r)``."""
    mw, mu = m[..., :3], m[..., 3:]
    return xp.concat([mv(E, mw), mv(E, mu - cross3(xp, r, mw))], axis=-1)


def transform_matrix(xp, E, r):
    """The 6x6 matrix of ``X = (E, r)``."""
    X = xp.zeros(tuple(E.shape[:-2]) + (6, 6), dtype=E.dtype, device=getattr(E, "device", None))
    X[..., :3, :3] = E
    X[..., 3:, 3:] = E
    X[..., 3:, :3] = cross3(xp, r[..., None, :], E)  # rows of -E rx are r x (rows of E)
    return X


# ---------------------------------------------------------------- quaternions (w, x, y, z)


def quat_to_mat(xp, q):
    """Unit quaternions (..., 4) (w, x, y, z) -> rotation matrices (..., 3, 3)."""
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    x2, y2, z2 = x + x, y + y, z + z
    xx, yy, zz, xy, xz, yz = x * x2, y * y2, z * z2, x * y2, x * z2, y * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    m = xp.stack([1 - (yy + zz), xy - wz, xz + wy, xy + wz, 1 - (xx + zz), yz - wx, xz - wy, yz + wx, 1 - (xx + yy)], axis=-1)
    return xp.reshape(m, tuple(q.shape[:-1]) + (3, 3))


def quat_mul(xp, a, b):
    """Hamilton product ``a * b`` of (..., 4) quaternions."""
    aw, av = a[..., :1], a[..., 1:]
    bw, bv = b[..., :1], b[..., 1:]
    w = aw * bw - xp.vecdot(av, bv)[..., None]
    v = aw * bv + bw * av + cross3(xp, av, bv)
    return xp.concat([w, v], axis=-1)


def quat_exp(xp, theta):
    """Unit quaternion of the rotation vector ``theta`` (..., 3) (exponential map of SO(3))."""
    phi2 = xp.vecdot(theta, theta)[..., None]
    phi = xp.sqrt(phi2)
    small = phi < 1e-4
    safe = xp.where(small, xp.ones_like(phi), phi)
    # sin(phi/2)/phi, with its Taylor series near 0
    k = xp.where(small, 0.5 - phi2 / 48.0 + phi2 * phi2 / 3840.0, xp.sin(0.5 * safe) / safe)
    return xp.concat([xp.cos(0.5 * phi), k * theta], axis=-1)


def quat_canonical(xp, q):
    """Normalise quaternions and pick the sign with ``w >= 0``."""
    q = q / xp.sqrt(xp.vecdot(q, q))[..., None]
    return xp.where(q[..., :1] < 0, -q, q)


def mat_to_quat(R: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) -> unit quaternions (w, x, y, z), ``w >= 0`` (numpy)."""
    R = np.asarray(R, dtype=np.float64)
    m = R.reshape(-1, 3, 3)
    t = np.trace(m, axis1=1, axis2=2)
    # Shepperd: candidate 4*component^2 values; build from the largest for accuracy
    cand = np.stack([1 + t, 1 + 2 * m[:, 0, 0] - t, 1 + 2 * m[:, 1, 1] - t, 1 + 2 * m[:, 2, 2] - t], axis=1)
    k = np.argmax(cand, axis=1)
    out = np.empty((len(m), 4))
    for i, kk in enumerate(k):
        a = m[i]
        s = 2.0 * np.sqrt(cand[i, kk])
        if kk == 0:
            q = [s / 4, (a[2, 1] - a[1, 2]) / s, (a[0, 2] - a[2, 0]) / s, (a[1, 0] - a[0, 1]) / s]
        elif kk == 1:
            q = [(a[2, 1] - a[1, 2]) / s, s / 4, (a[0, 1] + a[1, 0]) / s, (a[0, 2] + a[2, 0]) / s]
        elif kk == 2:
            q = [(a[0, 2] - a[2, 0]) / s, (a[0, 1] + a[1, 0]) / s, s / 4, (a[1, 2] + a[2, 1]) / s]
        else:
            q = [(a[1, 0] - a[0, 1]) / s, (a[0, 2] + a[2, 0]) / s, (a[1, 2] + a[2, 1]) / s, s / 4]
        out[i] = q
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    out[out[:, 0] < 0] *= -1
    return out.reshape(R.shape[:-2] + (4,))


# ---------------------------------------------------------------- SO(3) chart for the integrator


def chart_coefficients(xp, theta, derivatives=True):
    """The coefficients of ``dexp`` and its companions at ``theta`` (for :func:`chart_maps`):
    alpha = (1 - cos p)/p^2, beta = (p - sin p)/p^3 and (with ``derivatives``) their
    derivatives over p, divided by p, and gamma = (1 - (p/2) cot(p/2)) / p^2 (of ``dexp_inv``);
    each (..., 1)."""
    p2 = xp.vecdot(theta, theta)[..., None]
    p = xp.sqrt(p2)
    small = p < 1e-3
    ps = xp.where(small, xp.ones_like(p), p)
    s, c = xp.sin(ps), xp.cos(ps)
    inv2 = 1.0 / (ps * ps)
    p4 = p2 * p2
    alpha = xp.where(small, 0.5 - p2 / 24.0 + p4 / 720.0, (1 - c) * inv2)
    beta = xp.where(small, 1.0 / 6.0 - p2 / 120.0 + p4 / 5040.0, (ps - s) * inv2 / ps)
    if not derivatives:
        return alpha, beta
    # d(alpha)/dp / p and d(beta)/dp / p
    dalpha = xp.where(small, -1.0 / 12.0 + p2 / 180.0 - p4 / 6720.0, (ps * s - 2 * (1 - c)) * inv2 * inv2)
    dbeta = xp.where(small, -1.0 / 60.0 + p2 / 1260.0 - p4 / 60480.0, (3 * s - ps * c - 2 * ps) * inv2 * inv2 / ps)
    half = 0.5 * ps
    gamma = xp.where(small, 1.0 / 12.0 + p2 / 720.0 + p4 / 30240.0, (1 - half * xp.cos(half) / xp.sin(half)) * inv2)
    return alpha, beta, dalpha, dbeta, gamma


def dexp(xp, theta, theta_dot):
    """Body angular velocity of ``R0 @ exp(theta)`` when ``theta`` moves at ``theta_dot``.

    ``omega = theta_dot - alpha theta x theta_dot + beta theta x (theta x theta_dot)``.
    """
    alpha, beta = chart_coefficients(xp, theta, derivatives=False)
    t1 = cross3(xp, theta, theta_dot)
    return theta_dot - alpha * t1 + beta * cross3(xp, theta, t1)


def dexp_dot(xp, theta, theta_dot):
    """Time derivative of ``dexp(theta)`` applied to ``theta_dot`` (the chart's curvature term)."""
    return chart_rates_at(xp, theta, theta_dot, chart_maps(xp, theta))[1]


def chart_maps(xp, theta):
    """What the integrator's stages at one ``theta`` share, as matrices: ``(expm, KK, dinv, coefficients)``.

    ``expm = exp([theta]x) = 1 + (sin p / p) K + alpha K^2`` (``K = [theta]x``, ``K^2 = theta
    theta' - p^2``, ``sin p / p = 1 - p^2 beta``), ``KK`` (..., 6, 3) stacks ``K`` over ``K^2``,
    ``dinv = 1 + K / 2 + gamma K^2`` is :func:`dexp_inv` as a matrix, and ``coefficients`` are
    ``(alpha, beta, dalpha, dbeta)`` of :func:`chart_coefficients`. With them a stage's
    :func:`chart_rates_at` and ``dexp_inv`` are a handful of operations (the cross products
    become one stacked product), which matters for a batch of small (C, 3) arrays, where every
    operation costs its call overhead.
    """
    alpha, beta, dalpha, dbeta, gamma = chart_coefficients(xp, theta)
    t0, t1, t2 = theta[..., 0], theta[..., 1], theta[..., 2]
    z = xp.zeros_like(t0)
    K = xp.reshape(xp.stack([z, -t2, t1, t2, z, -t0, -t1, t0, z], axis=-1), tuple(theta.shape[:-1]) + (3, 3))
    p2 = xp.vecdot(theta, theta)[..., None, None]
    eye = xp.eye(3, dtype=theta.dtype, device=getattr(theta, "device", None))
    K2 = theta[..., :, None] * theta[..., None, :] - p2 * eye
    a, b = alpha[..., None], beta[..., None]
    expm = eye + (1.0 - p2 * b) * K + a * K2
    dinv = eye + 0.5 * K + gamma[..., None] * K2
    return expm, xp.concat([K, K2], axis=-2), dinv, (alpha, beta, dalpha, dbeta)


def chart_rates_at(xp, theta, theta_dot, maps):
    """``dexp(theta) theta_dot`` and ``dexp_dot(theta, theta_dot)`` from the :func:`chart_maps`
    ``maps`` at ``theta``; ``theta_dot x (theta x theta_dot)`` is written
    ``theta |theta_dot|^2 - theta_dot (theta . theta_dot)``."""
    _, KK, _, (alpha, beta, dalpha, dbeta) = maps
    t = mv(KK, theta_dot)
    t1, t2 = t[..., :3], t[..., 3:]  # theta x theta_dot, theta x (theta x theta_dot)
    pdot = xp.sum(theta * theta_dot, axis=-1, keepdims=True)
    n2 = xp.sum(theta_dot * theta_dot, axis=-1, keepdims=True)
    omega = theta_dot - alpha * t1 + beta * t2
    curvature = (dbeta * pdot) * t2 - (dalpha * pdot) * t1 + beta * (theta * n2 - theta_dot * pdot)
    return omega, curvature


def dexp_inv(xp, theta, omega):
    """Solve ``dexp(theta) @ x = omega`` for ``x`` (exactly, by the closed-form inverse)."""
    gamma = chart_coefficients(xp, theta)[4]
    t1 = cross3(xp, theta, omega)
    return omega + 0.5 * t1 + gamma * cross3(xp, theta, t1)
