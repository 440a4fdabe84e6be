"""Featherstone's articulated-body algorithm, batched over a packed population (paper section 2.4).

The three sweeps of spatial_v2's ``FDab`` with a floating base, in the book's notation (``Xup``,
``S``, ``vJ``, ``c``, ``IA``, ``pA``, ``U``, ``d``, ``u``), looping over tree *depth levels*
instead of bodies: every body of every creature at one depth is processed by one stacked array
operation. All quantities are in body coordinates; bodies sit at their centres of mass with
principal axes, so each rigid-body inertia is diagonal. There is no gravity (neutral buoyancy),
so the world pose of the root never enters the dynamics.

Joint motion subspaces are constant in the child frame (revolute: ``(a, c x a)`` for axis ``a``
through the anchor ``c``; prismatic: ``(0, a)``), so the joint bias ``cJ`` is zero.
"""

from __future__ import annotations

from . import spatial as sp


def _rotate(xp, axis, angle, v):
    """Rodrigues on vectors: ``Rot(axis, angle) @ v`` for (M, 3) stacks."""
    c, s = xp.cos(angle)[:, None], xp.sin(angle)[:, None]
    return v * c + sp.cross3(xp, axis, v) * s + axis * (xp.sum(axis * v, axis=-1, keepdims=True) * (1.0 - c))


def joint_transforms(model, q):
    """Joint transforms ``Xup = (E, r)`` at ``q``: ``E`` (M, 3, 3) rotates parent coordinates into
    child coordinates, ``r`` (M, 3) is the child's origin in parent coordinates (contiguous arrays)."""
    xp = model.xp
    zero = xp.zeros_like(q)
    angle = xp.where(model.revolute, q, zero)
    E = sp.rotation_about(xp, model.axis, -angle) @ model.joint_rot_T
    slide = xp.where(model.revolute, zero, q)
    r = model.jpp + sp.mv(model.joint_rot, slide[:, None] * model.axis - _rotate(xp, model.axis, angle, model.jpc))
    return E, r


def joint_rotations(model, q):
    """(M, 3, 3) child-to-parent rotations ``Rq = E.T`` at ``q`` (contiguous)."""
    xp = model.xp
    return model.joint_rot @ sp.rotation_about(xp, model.axis, xp.where(model.revolute, q, xp.zeros_like(q)))


def body_velocities(model, E, r, v0, qd):
    """Outward sweep: spatial velocities ``v`` (N, 6) and bias accelerations ``c`` (N, 6)."""
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    vJ = model.S * qd[:, None]
    v = xp.zeros((N, 6), dtype=v0.dtype, device=model.device)
    c = xp.zeros((N, 6), dtype=v0.dtype, device=model.device)
    v[:C] = v0
    for s, e, par, _ in model.levels:
        j = slice(s - C, e - C)
        vi = sp.transform_motion(xp, E[j], r[j], v[par]) + vJ[j]
        v[s:e] = vi
        c[s:e] = sp.cross_motion(xp, vi, vJ[j])
    return v, c


def aba(model, q, qd, v0, tau, f_ext=None, damping=None):
    """Forward dynamics of the whole batch.

    Args:
        model: packed :class:`~coursekit.creatures.physics.model.Model`.
        q, qd: (M,) joint coordinates and rates (internal joint order).
        v0: (C, 6) root spatial velocity in root coordinates, ``(omega, v)``.
        tau: (M,) joint forces.
        f_ext: optional (N, 6) external spatial force on every body, body coordinates.
        damping: optional (N, 6) diagonal of a body-frame damping matrix ``D``; adds ``-D v``.

    Returns:
        ``(a0, qdd, v)``: root spatial acceleration (C, 6) in root coordinates, joint
        accelerations (M,) and body velocities (N, 6).
    """
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    E, r = joint_transforms(model, q)
    v, c = body_velocities(model, E, r, v0, qd)

    I = model.inertia_diag
    pA = sp.cross_force(xp, v, I * v)
    if damping is not None:
        pA = pA + damping * v
    if f_ext is not None:
        pA = pA - f_ext
    IA = xp.zeros((N, 6, 6), dtype=v.dtype, device=model.device)
    k = xp.arange(6, device=model.device) if model.backend == "torch" else xp.arange(6)
    IA[:, k, k] = I
    Xup = sp.transform_matrix(xp, E, r)
    S = model.S
    U = xp.zeros((N - C, 6), dtype=v.dtype, device=model.device)
    d = xp.zeros((N - C,), dtype=v.dtype, device=model.device)
    u = xp.zeros((N - C,), dtype=v.dtype, device=model.device)

    for s, e, _, seg in reversed(model.levels):
        j = slice(s - C, e - C)
        Uj = sp.mv(IA[s:e], S[j])
        dj = xp.sum(S[j] * Uj, axis=-1)
        uj = tau[j] - xp.sum(S[j] * pA[s:e], axis=-1)
        U[j], d[j], u[j] = Uj, dj, uj
        Ia = IA[s:e] - Uj[:, :, None] * (Uj / dj[:, None])[:, None, :]
        pa = pA[s:e] + sp.mv(Ia, c[s:e]) + Uj * (uj / dj)[:, None]
        X = Xup[j]
        seg.add_into(IA, X.mT @ Ia @ X)
        seg.add_into(pA, sp.transform_force_back(xp, E[j], r[j], pa))

    a0 = -xp.linalg.solve(IA[:C], pA[:C][:, :, None])[:, :, 0]
    a = xp.zeros((N, 6), dtype=v.dtype, device=model.device)
    a[:C] = a0
    qdd = xp.zeros((N - C,), dtype=v.dtype, device=model.device)
    for s, e, par, _ in model.levels:
        j = slice(s - C, e - C)
        ai = sp.transform_motion(xp, E[j], r[j], a[par]) + c[s:e]
        qddj = (u[j] - xp.sum(U[j] * ai, axis=-1)) / d[j]
        qdd[j] = qddj
        a[s:e] = ai + S[j] * qddj[:, None]
    return a0, qdd, v


def forward_kinematics(model, R0, p0, q):
    """World rotation (N, 3, 3) and position (N, 3) of every body."""
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    _, t = joint_transforms(model, q)
    Rq = joint_rotations(model, q)
    R = xp.zeros((N, 3, 3), dtype=R0.dtype, device=model.device)
    p = xp.zeros((N, 3), dtype=R0.dtype, device=model.device)
    R[:C], p[:C] = R0, p0
    for s, e, par, _ in model.levels:
        j = slice(s - C, e - C)
        Rp = R[par]
        R[s:e] = Rp @ Rq[j]
        p[s:e] = p[par] + sp.mv(Rp, t[j])
    return R, p
