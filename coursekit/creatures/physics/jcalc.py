"""The joint model (spatial_v2's ``jcalc``): joint types, motion subspaces, joint transforms, kinematics.

Featherstone's book keeps what a joint *is* apart from the dynamics algorithms that use it: a
joint type gives the joint transform ``XJ(q)`` and the motion subspace ``S``, and the tree gives
the constant transforms on either side. Here bodies sit at their centres of mass, so a joint is

    ``Xup(q) = Xc XJ(q) Xtree``

with ``Xtree`` from the parent frame to the joint frame at ``q = 0`` (origin at the anchor
``joint_pos_parent``, axes the child's, turned by ``joint_rot``), ``XJ(q)`` the joint's own
motion (a rotation by ``q`` about ``joint_axis``, or a slide by ``q`` along it) and ``Xc`` the
shift from the anchor to the child's centre of mass (``joint_pos_child``). The motion subspace
in child coordinates is ``S = Xc S_J``, ``S_J = (a, 0)`` (revolute) or ``(0, a)`` (prismatic),
constant in the child frame, so the joint bias ``cJ`` is zero. :func:`jcalc` is that definition
for one joint, in the book's form; :mod:`~coursekit.creatures.physics.reference` uses it.

The batched simulator uses *fast forms* of the same transforms: every entry of ``Xup(q)`` lies in
``span(1, cos q, sin q)`` (revolute) or ``span(1, q)`` (prismatic), so a model stores constant
coefficients over the polynomial basis of :func:`joint_basis`, fitted once from a few exact
samples (:func:`fit_joint_basis`), and evaluating all joints of a batch is one stacked product
(:func:`transform_matrices`, :func:`joint_transforms`). Forward kinematics
(:func:`poses_rows`, :func:`forward_kinematics`) walks the packed tree level by level on top.

A new joint type is defined here -- its ``S`` (:func:`jcalc`, :func:`motion_subspaces`), its
transform (:func:`jcalc`, :func:`rodrigues_constants`) and the basis its fast forms live in
(:func:`rotational`, :func:`joint_basis`) -- and in :mod:`coursekit.creatures.body` (its type
code and validation); the sweeps do not change. Measurements behind the fast forms:
``benchmarks/NOTES.md``.
"""

from __future__ import annotations

import numpy as np

from coursekit.creatures.body import PRISMATIC, REVOLUTE, rotation_about

from . import backend as bk
from . import spatial as sp

# ---------------------------------------------------------------- one joint, the book's form


def jcalc(joint_type: int, axis: np.ndarray, q: float):
    """``(XJ, S_J)``: the joint transform (6, 6) at ``q`` and the motion subspace (6,), both in
    the joint frame (spatial_v2's ``jcalc``; numpy).

    Revolute: ``XJ = rot(Rot(a, q)')``, ``S_J = (a, 0)``; prismatic: ``XJ = xlt(q a)``,
    ``S_J = (0, a)``, for the unit ``axis`` ``a``.

    >>> XJ, S = jcalc(REVOLUTE, np.array([0.0, 0.0, 1.0]), np.pi / 2)
    >>> S.tolist()
    [0.0, 0.0, 1.0, 0.0, 0.0, 0.0]
    >>> (np.round(XJ[:3, :3], 12) + 0.0).tolist()  # a quarter turn about z: parent x is child -y
    [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    """
    a = np.asarray(axis, dtype=np.float64)
    S = np.zeros(6)
    if joint_type == REVOLUTE:
        S[:3] = a
        return sp.transform_matrix(np, rotation_about(a, q).T, np.zeros(3)), S
    if joint_type == PRISMATIC:
        S[3:] = a
        return sp.transform_matrix(np, np.eye(3), q * a), S
    raise ValueError(f"joint_type: expected REVOLUTE ({REVOLUTE}) or PRISMATIC ({PRISMATIC}), got {joint_type}")


# ---------------------------------------------------------------- constants of a packed model


def rotational(joint_type: np.ndarray) -> np.ndarray:
    """(M,) bool: whether each joint's coordinate is an angle (its fast forms are trigonometric
    in ``q``: :func:`joint_basis`) rather than a length (polynomial)."""
    return np.asarray(joint_type) == REVOLUTE


def motion_subspaces(joint_type: np.ndarray, axis: np.ndarray, pos_child: np.ndarray) -> np.ndarray:
    """(M, 6) motion subspaces ``S = Xc S_J`` in child coordinates: revolute ``(a, c x a)`` for
    the axis ``a`` through the anchor ``c``, prismatic ``(0, a)`` (numpy)."""
    S = np.zeros((len(joint_type), 6))
    rev = joint_type == REVOLUTE
    S[rev, :3] = axis[rev]
    S[rev, 3:] = np.cross(pos_child[rev], axis[rev])
    S[joint_type == PRISMATIC, 3:] = axis[joint_type == PRISMATIC]
    return S


def rodrigues_constants(axis, pos_parent, pos_child, joint_rot) -> dict:
    """The constant factors of every joint's pose ``(E(q), r(q))`` (numpy).

    Rodrigues: ``Rot(a, q) = 1 + sin q K + (1 - cos q) K^2``, ``K = [a]x``, so ``E(q) = Rot(a,
    -q) J'`` and ``r(q) = jpp + J (slide a - Rot(a, q) c)`` are sums of constants: ``E = E0 +
    sin q E1 + (1 - cos q) E2`` and ``r = r0 + sin q r1 + (1 - cos q) r2 + slide r3``.
    """
    K = np.cross(axis[:, None, :], -np.eye(3)[None])  # K @ x == cross(axis, x)
    K2 = K @ K
    J = joint_rot
    JT = np.swapaxes(J, 1, 2)
    Jc = np.einsum("mij,mj->mi", J, pos_child)
    return {
        "E0": np.ascontiguousarray(JT), "E1": -K @ JT, "E2": K2 @ JT,
        "r0": pos_parent - Jc, "r1": -np.einsum("mij,mj->mi", J @ K, pos_child),
        "r2": -np.einsum("mij,mj->mi", J @ K2, pos_child), "r3": np.einsum("mij,mj->mi", J, axis),
    }  # fmt: skip


def _transforms(xp, revolute, q, E0, E1, E2, r0, r1, r2, r3):
    """``(E, r)`` at ``q`` from the :func:`rodrigues_constants` (revolute ``E = E0 + sin q E1 +
    (1 - cos q) E2``; prismatic ``E = E0`` and ``r`` moves along ``r3``), the samples
    :func:`fit_joint_basis` fits."""
    zero = xp.zeros_like(q)
    angle = xp.where(revolute, q, zero)
    s, c1 = xp.sin(angle), 1.0 - xp.cos(angle)
    E = E0 + s[:, None, None] * E1 + c1[:, None, None] * E2
    slide = xp.where(revolute, zero, q)
    r = r0 + s[:, None] * r1 + c1[:, None] * r2 + slide[:, None] * r3
    return E, r


# ---------------------------------------------------------------- the fast forms


def joint_basis(xp, revolute, q):
    """(n, 5) polynomial basis in ``q``: revolute ``(1, cos q, sin q, cos 2q, sin 2q)``, prismatic
    ``(1, q, q^2, 0, 0)``. The first three span the entries of ``Xup(q)``."""
    rev = xp.astype(revolute, q.dtype)  # 1 for revolute joints, 0 for prismatic ones
    angle, slide = q * rev, q - q * rev  # a prismatic joint has angle 0: cos 1, sin 0
    # cos and sin from the tangent of the half angle: one transcendental call, not two
    t = xp.tan(0.5 * angle)
    t2 = t * t
    k = 1.0 / (1.0 + t2)
    c, s = (1.0 - t2) * k, (t + t) * k
    return xp.stack([xp.ones_like(q), xp.where(revolute, c, slide), s + slide * slide, (c * c - s * s) * rev, 2.0 * s * c], axis=-1)


def fit_joint_basis(revolute: np.ndarray, consts: dict, sample, k: int = 3) -> np.ndarray:
    """Constant coefficients ``P`` (n, k, w) with ``sample(E(q), r(q)) = joint_basis(q)[:, :k] @ P``
    for every ``q`` (numpy).

    ``Xup(q) = Xc XJ(q) Xtree`` has entries in ``span(1, cos q, sin q)`` (revolute) or
    ``span(1, q)`` (prismatic): so ``E``, ``r`` and ``Xup`` are of degree one (``k = 3``) in the
    basis and congruences ``Xup' I Xup`` of degree two (``k = 5``). Fitted exactly from ``k``
    samples per joint (equally spaced angles; slides centred on 0), with Rodrigues' formula at
    the samples.

    Args:
        revolute: (n,) joint kinds; consts: the :func:`rodrigues_constants` of these joints;
            sample: ``(E, r) -> (n, w)``.
    """
    ks = np.arange(float(k))
    qs = np.where(revolute[:, None], 2 * np.pi * ks / k, ks - (k - 1) / 2)  # (n, k) sample points
    samples = np.stack([sample(*_transforms(np, revolute, qs[:, i], *(consts[c] for c in ("E0", "E1", "E2", "r0", "r1", "r2", "r3")))) for i in range(k)], axis=1)
    B = joint_basis(np, revolute[:, None], qs)[..., :k]  # (n, k samples, k functions)
    return np.linalg.pinv(B) @ samples


def transform_matrices(model, b):
    """(M, 6, 6) ``Xup`` from the (M, 5) :func:`joint_basis` ``b`` and the model's coefficients:
    numpy takes one stacked (1 x 3) @ (3 x 19) product per joint for the distinct entries (``E``,
    ``-E rx``, 0) and gathers the 36 from them; torch, whose small stacked products are slow on
    the CPU, two ``addcmul`` over the rows of the full coefficients."""
    P = model.X_basis
    if bk.is_numpy(model.xp):
        return np.take((b[:, None, :3] @ P)[:, 0], model.X_expand, axis=1).reshape(-1, 6, 6)
    return P[0].addcmul(b[:, 1:2], P[1]).addcmul_(b[:, 2:3], P[2]).reshape(-1, 6, 6)


def joint_transform_matrices(model, q):
    """(M, 6, 6) joint transforms ``Xup`` at ``q`` from the model's constant coefficients."""
    return transform_matrices(model, joint_basis(model.xp, model.revolute, q))


def _pose_rows(model, q):
    """(12, M) component-major ``Rq = E'`` (rows ``3 r + c``) and ``r`` (rows 9..11) at ``q``."""
    b = bk.contiguous(model.xp, joint_basis(model.xp, model.revolute, q)[:, 1:3].T)  # (2, M)
    P = model.pose_rows_basis  # (3, 12, M); the first basis function is 1
    return P[0] + b[0] * P[1] + b[1] * P[2]


def joint_transforms(model, q):
    """Joint transforms ``Xup = (E, r)`` at ``q``: ``E`` (M, 3, 3) rotates parent coordinates into
    child coordinates, ``r`` (M, 3) is the child's origin in parent coordinates.

    Both are of degree one in :func:`joint_basis` (see :func:`fit_joint_basis`): a few stacked
    operations with the model's constant coefficients.
    """
    xp = model.xp
    G = _pose_rows(model, q)
    return bk.contiguous(xp, xp.reshape(G[:9].T, (-1, 3, 3)).mT), G[9:].T


# ---------------------------------------------------------------- kinematics


def poses_rows(model, R0, p0, q):
    """World rotations (3, 3, N) and positions (3, N) of every body, component-major.

    Each level is a handful of operations on contiguous rows (``R = R_parent Rq``,
    ``p = p_parent + R_parent r``), which numpy does much faster than stacks of 3x3 products.
    """
    xp = model.xp
    C, N, L = model.n_creatures, model.n_bodies, model.leaf_start
    G = _pose_rows(model, q)
    Rq, t = xp.reshape(G[:9], (3, 3, -1)), G[9:]
    R = xp.zeros((3, 3, N), dtype=R0.dtype, device=model.device)
    p = xp.zeros((3, N), dtype=R0.dtype, device=model.device)
    R[:, :, :C] = xp.permute_dims(R0, (1, 2, 0))
    p[:, :C] = p0.T
    for s, e, par, _ in model.levels + [(L, N, model.leaf_parent, None)]:
        j = slice(s - C, e - C)
        Rp = xp.take(R, par, axis=2)  # (3, 3, n)
        R[:, :, s:e] = xp.sum(Rp[:, :, None] * Rq[None, :, :, j], axis=1)
        p[:, s:e] = xp.take(p, par, axis=1) + xp.sum(Rp * t[None, :, j], axis=1)
    return R, p


def forward_kinematics(model, R0, p0, q):
    """World rotation (N, 3, 3) and position (N, 3) of every body."""
    return pose_stacks(model.xp, poses_rows(model, R0, p0, q))


def pose_stacks(xp, rows):
    """The component-major poses ``rows`` of :func:`poses_rows` as (N, 3, 3) and (N, 3) stacks."""
    R, p = rows
    return bk.contiguous(xp, xp.permute_dims(R, (2, 0, 1))), bk.contiguous(xp, p.T)
