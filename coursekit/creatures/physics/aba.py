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


def joint_transforms(model, q):
    """Joint transforms ``Xup = (E, r)`` at ``q``: ``E`` (M, 3, 3) rotates parent coordinates into
    child coordinates, ``r`` (M, 3) is the child's origin in parent coordinates.

    Rodrigues' formula with the constant factors precomputed by the model: for revolute joints
    ``E = J' + sin q (-K J') + (1 - cos q) K^2 J'`` (``K = [axis]x``, ``J`` = joint_rot); for
    prismatic joints ``E = J'`` and ``r`` moves along ``J axis``.
    """
    xp = model.xp
    zero = xp.zeros_like(q)
    angle = xp.where(model.revolute, q, zero)
    s, c1 = xp.sin(angle), 1.0 - xp.cos(angle)
    E = model.E0 + s[:, None, None] * model.E1 + c1[:, None, None] * model.E2
    slide = xp.where(model.revolute, zero, q)
    r = model.r0 + s[:, None] * model.r1 + c1[:, None] * model.r2 + slide[:, None] * model.r3
    return E, r


def joint_rotations(model, q):
    """(M, 3, 3) child-to-parent rotations ``Rq = E.T`` at ``q``."""
    xp = model.xp
    angle = xp.where(model.revolute, q, xp.zeros_like(q))
    s, c1 = xp.sin(angle), 1.0 - xp.cos(angle)
    return model.joint_rot + s[:, None, None] * model.Rq1 + c1[:, None, None] * model.Rq2


def body_velocities(model, X, v0, qd):
    """Outward sweep: spatial velocities ``v`` (N, 6) and bias accelerations ``c`` (N, 6).

    ``X`` is the (M, 6, 6) stack of joint transforms ``Xup`` (:func:`spatial.transform_matrix`).
    """
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    vJ = model.S * qd[:, None]
    v = xp.zeros((N, 6), dtype=v0.dtype, device=model.device)
    v[:C] = v0
    for s, e, par, _ in model.levels:
        j = slice(s - C, e - C)
        v[s:e] = sp.mv(X[j], v[par]) + vJ[j]
    c = xp.concat([xp.zeros_like(v0), sp.cross_motion(xp, v[C:], vJ)], axis=0)
    return v, c


def articulated_inertias(model, q):
    """The velocity-independent half of the inward sweep: ``(Xup, IA, U, d)`` at ``q``.

    ``IA`` (N, 6, 6) are the articulated inertias (roots' included), ``U = IA S`` and
    ``d = S' U`` per joint. Each child passes ``Xup' (IA - U U' / d) Xup`` to its parent. They
    depend on the positions only, so the Nyström stages 2 and 3, which share positions, share
    them.
    """
    xp = model.xp
    C = model.n_creatures
    E, r = joint_transforms(model, q)
    Xup = sp.transform_matrix(xp, E, r)
    IA = model.inertia_matrix + 0.0  # a fresh (N, 6, 6) copy of the rigid-body inertias
    S = model.S
    U = xp.zeros_like(S)
    d = xp.zeros_like(S[:, 0])
    for s, e, _, seg in reversed(model.levels):
        j = slice(s - C, e - C)
        Uj = sp.mv(IA[s:e], S[j])
        dj = xp.sum(S[j] * Uj, axis=-1)
        U[j], d[j] = Uj, dj
        X = Xup[j]
        w = sp.mv(X.mT, Uj)  # Xup' U
        seg.add_into(IA, X.mT @ (IA[s:e] @ X) - w[:, :, None] * (w / dj[:, None])[:, None, :])
    return Xup, IA, U, d


def aba(model, q, qd, v0, tau, f_ext=None, damping=None, inertias=None):
    """Forward dynamics of the whole batch.

    Args:
        model: packed :class:`~coursekit.creatures.physics.model.Model`.
        q, qd: (M,) joint coordinates and rates (internal joint order).
        v0: (C, 6) root spatial velocity in root coordinates, ``(omega, v)``.
        tau: (M,) joint forces.
        f_ext: optional (N, 6) external spatial force on every body, body coordinates.
        damping: optional (N, 6) diagonal of a body-frame damping matrix ``D``; adds ``-D v``.
        inertias: optional result of :func:`articulated_inertias` at this ``q`` (reused).

    Returns:
        ``(a0, qdd, v)``: root spatial acceleration (C, 6) in root coordinates, joint
        accelerations (M,) and body velocities (N, 6).
    """
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    Xup, IA, U, d = articulated_inertias(model, q) if inertias is None else inertias
    v, c = body_velocities(model, Xup, v0, qd)

    I = model.inertia_diag
    pA = sp.cross_force(xp, v, I * v)
    if damping is not None:
        pA = pA + damping * v
    if f_ext is not None:
        pA = pA - f_ext
    S = model.S
    u = xp.zeros_like(tau)
    for s, e, _, seg in reversed(model.levels):
        j = slice(s - C, e - C)
        uj = tau[j] - xp.sum(S[j] * pA[s:e], axis=-1)
        u[j] = uj
        # pa = pA + Ia c + U u / d with Ia = IA - U U' / d
        pa = pA[s:e] + sp.mv(IA[s:e], c[s:e]) + U[j] * ((uj - xp.sum(U[j] * c[s:e], axis=-1)) / d[j])[:, None]
        seg.add_into(pA, sp.mv(Xup[j].mT, pa))

    a0 = -xp.linalg.solve(IA[:C], pA[:C][:, :, None])[:, :, 0]
    a = xp.zeros((N, 6), dtype=v.dtype, device=model.device)
    a[:C] = a0
    qdd = xp.zeros_like(tau)
    for s, e, par, _ in model.levels:
        j = slice(s - C, e - C)
        ai = sp.mv(Xup[j], a[par]) + c[s:e]
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
