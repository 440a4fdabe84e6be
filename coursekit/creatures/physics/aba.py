"""Featherstone's articulated-body algorithm, batched over a packed population (paper section 2.4).

The three sweeps of spatial_v2's ``FDab`` with a floating base, in the book's notation (``Xup``,
``S``, ``vJ``, ``c``, ``IA``, ``pA``, ``U``, ``d``, ``u``), looping over tree *depth levels*
instead of bodies: every body of every creature at one depth is processed by one stacked array
operation. All quantities are in body coordinates; bodies sit at their centres of mass with
principal axes, so each rigid-body inertia is diagonal. There is no gravity (neutral buoyancy),
so the world pose of the root never enters the dynamics.

The joint model -- motion subspaces ``S``, joint transforms ``Xup`` and their fast forms, and
kinematics -- is :mod:`~coursekit.creatures.physics.jcalc`; this module keeps only the sweeps. The
same algorithm per creature, one body at a time, in the book's words, is
:mod:`~coursekit.creatures.physics.reference` (lesson 07's text; the tests hold the two equal).

The sweeps are rearranged for speed, and their quantities renamed for what they hold
(:func:`articulated_inertias` and :func:`aba` write each in the book's terms):

- ``W = Xup' U / d`` (per joint) and ``Z = Xup - S W'``: what a child passes to its parent is
  ``Xup' Ia Xup = Yt' Z`` with ``Yt = IA Xup`` (``Ia = IA - U U'/d``), and the bias it passes,
  ``Xup' pa``, is ``Z' pA + h`` with ``h = Yt' c + W (tau - U'c)``, the part that does not depend
  on the sweep; the acceleration sweep ``a = Xup a_parent + c + S qdd`` becomes
  ``a = Z a_parent + c + S ud`` with ``ud = (u - U'c) / d``, and ``qdd = ud - W' a_parent``.
- Leaves (about half the bodies of a random creature) are not swept level by level: their
  articulated inertia is their rigid one, so ``U``, ``d`` and ``Ia`` are constants of the model,
  and ``Xup' Ia Xup`` is a polynomial of degree two in ``q`` with constant matrix coefficients
  (:func:`~coursekit.creatures.physics.jcalc.fit_joint_basis`). All leaves are handled by one
  stacked operation per sweep; the level loops (:func:`_inward`, :func:`_outward`) run over the
  inner bodies only (the model stores leaves after them).

Why each numpy form was chosen, with the measurements: ``benchmarks/NOTES.md``.
"""

from __future__ import annotations

import numpy as np

from . import backend as bk
from . import spatial as sp
from .jcalc import joint_basis, transform_matrices


def _outward(model, X, a):
    """One sweep outwards over the inner levels, in place: every body adds ``X a_parent`` to its
    row of ``a`` (N, 6), the parents' rows complete before their children's."""
    xp, C = model.xp, model.n_creatures
    for s, e, par, _ in model.levels:
        a[s:e] += sp.mv(X[s - C : e - C], xp.take(a, par, axis=0))  # take: several times faster than a[par]
    return a


def _inward(model, Z, f):
    """One sweep inwards over the inner levels, in place: every body adds ``Z' f`` of its row of
    ``f`` (N, 6) to its parent's, the children's rows complete before their parents'."""
    C = model.n_creatures
    for s, e, _, seg in reversed(model.levels):
        seg.add_into(f, sp.mtv(Z[s - C : e - C], f[s:e]))
    return f


def _outward_velocities(model, X, v0, vJ):
    xp, C, L = model.xp, model.n_creatures, model.leaf_start
    v = _outward(model, X, xp.concat([v0, vJ], axis=0))  # each body adds its parent's velocity, transformed
    v[L:] += sp.mv(X[L - C :], xp.take(v, model.leaf_parent, axis=0))
    return v


def _velocities_and_bias(model, X, v0, qd, v=None):
    """``v`` (N, 6) (swept outwards unless given), the joints' bias accelerations ``c = v x vJ``
    (M, 6) and the bodies' rigid bias forces ``v x* I v`` (N, 6).

    Cross products are written with rolled copies ``v1``, ``v2`` of ``v`` (components ``(1, 2, 0)``
    of each half, and ``(2, 0, 1)``), since ``(a x b)_i = a_{i+1} b_{i+2} - a_{i+2} b_{i+1}``:
    a handful of whole-array products instead of one per component. The rigid bias force of a
    body at its centre of mass with principal axes is Euler's ``(w1 w2 (I2 - I1), m (w1 u2 - w2 u1))``.
    """
    xp = model.xp
    C, N = model.n_creatures, model.n_bodies
    if v is None:
        v = body_velocities(model, X, v0, qd)
    vt = bk.contiguous(xp, v.T)  # component-major: whole rows per component
    v1, v2 = xp.reshape(xp.take(vt, model.roll1, axis=0), (2, 3, N)), xp.reshape(xp.take(vt, model.roll2, axis=0), (2, 3, N))
    # v x* I v: rows (w1 w2, w1 u2) - (0, w2 u1), times (I2 - I1, m)
    pA = v1[0] * v2
    pA[1] -= v2[0] * v1[1]
    pA *= model.euler_factor
    # v x S (times qd): (w x s_w, w x s_u + u x s_w), with S1, S2 the rolled copies of S
    w1, w2, u1, u2 = v1[0, :, C:], v2[0, :, C:], v1[1, :, C:], v2[1, :, C:]
    c = w1 * model.S_roll2 - w2 * model.S_roll1
    c[1] += u1 * model.S_roll2[0] - u2 * model.S_roll1[0]
    c *= qd
    return v, bk.contiguous(xp, xp.reshape(c, (6, -1)).T), bk.contiguous(xp, xp.reshape(pA, (6, N)).T)


def body_velocities(model, X, v0, qd):
    """Outward sweep: spatial velocities ``v`` (N, 6) of every body, in body coordinates.

    ``X`` is the (M, 6, 6) stack of joint transforms ``Xup`` (:func:`spatial.transform_matrix`).
    """
    return _outward_velocities(model, X, v0, model.S * qd[:, None])


def articulated_inertias(model, q, lock=None, static=False):
    """The velocity-independent half of the ABA: ``(Xup, IA, U, d, W, Z, Yt, V)`` at ``q``.

    ``Xup`` (M, 6, 6) are the joint transforms; ``IA`` (L, 6, 6) the articulated inertias of the
    roots and inner bodies (a leaf's is its rigid inertia), ``U = IA S`` and ``d = S' U`` (M,)
    per joint, ``W = Xup' U / d`` (M, 6) and, for the inner joints, ``Z = Xup - S W'`` and
    ``Yt = IA Xup`` (L - C, 6, 6). Each child passes ``Xup' (IA - U U' / d) Xup = Yt' Z`` to its
    parent. (``IA`` is symmetric, so ``U = IA S`` is computed as ``S' IA``.) In the book's terms:
    ``W`` is the joint's ``U / d`` carried into the parent's coordinates (``qdd = ud - W'
    a_parent``), ``Z`` is ``Xup`` less the motion the joint itself absorbs (``Z a_parent`` is
    what the parent's acceleration imposes on the child, ``Z'`` carries the child's ``pA`` to the
    parent) and ``Yt`` is half of the congruence ``Xup' Ia Xup``.
    They depend on the positions only, so the Nyström stages 2 and 3, which share positions,
    share them.

    ``lock`` (M,) bool, optional: joints whose acceleration is *prescribed* (hybrid dynamics,
    Featherstone 2008 section 9.3; the joint limits of :mod:`limits`). A locked joint passes its
    whole articulated inertia to its parent (``Xup' IA Xup``: ``W = 0``, ``Z = Xup``), and
    ``V = Xup' U`` (M, 6) is returned for the bias sweep (``None`` without ``lock``).

    ``static``: the graph-ready formulation (:class:`~coursekit.creatures.physics.world.World`
    with ``graph=True``): every leaf's locked share is added, zero for the free ones, instead of
    picking the locked leaves out (an output size that depends on the data, read on the host).
    The sums are the same bit for bit: the added zeros are exact.
    """
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    b = joint_basis(xp, model.revolute, q)
    Xup = transform_matrices(model, b)
    jl, bl = slice(L - C, None), b[L - C :]
    IA = model.inner_inertia + 0.0  # a fresh copy: rigid inertias plus the leaves' constant terms
    model.leaf_segments.add_weighted(IA, bl[:, 1:], model.leaf_P_varying)
    IA = xp.reshape(xp.take(IA, model.sym_expand, axis=1), (-1, 6, 6))  # 21 upper entries -> 6x6
    S = model.S
    U, d = model.U_leaf + 0.0, model.d_leaf + 0.0  # leaf rows are constant; inner rows follow
    W = xp.empty_like(U)
    W[jl] = model.leaf_W[0] + bl[:, 1:2] * model.leaf_W[1] + bl[:, 2:3] * model.leaf_W[2]
    V = free = None
    if lock is not None:
        free = xp.astype(~lock, U.dtype)[:, None]
        V = xp.empty_like(U)
        Wl, dl = W[jl], d[jl]
        V[jl] = Wl * dl[:, None]
        # a locked leaf passes Xup' I Xup = (its free share) + d W W': a few leaves, added one by one
        if static:
            share = xp.where(lock[jl][:, None, None], sp.outer(xp, Wl * dl[:, None], Wl), 0.0)
            bk.add_at(xp, IA, model.leaf_parent, share)
            W[jl] = xp.where(lock[jl][:, None], 0.0, Wl)
        elif (k := bk.nonzero(xp, lock[jl])).shape[0]:
            Wk = Wl[k]
            bk.add_at(xp, IA, xp.take(model.leaf_parent, k, axis=0), sp.outer(xp, Wk * dl[k][:, None], Wk))
            Wl[k] = 0.0  # a view of W
    Z = xp.empty((L - C, 6, 6), dtype=Xup.dtype, device=model.device)
    Yt = xp.empty_like(Z)
    for s, e, _, seg in reversed(model.levels):
        j = slice(s - C, e - C)
        IAj, X, Sj = IA[s:e], Xup[j], S[j]
        Uj = sp.mtv(IAj, Sj, out=U[j])
        dj = sp.dot(xp, Sj, Uj)
        d[j] = dj
        Wj = sp.mtv(X, Uj, out=W[j])
        if lock is not None:
            V[j] = Wj
            Wj *= free[j]
        Wj /= dj[:, None]
        Zj = xp.subtract(X, sp.outer(xp, Sj, Wj), out=Z[j])
        seg.add_into(IA, xp.matmul(xp.matmul(IAj, X, out=Yt[j]).mT, Zj))
    return Xup, IA, U, d, W, Z, Yt, V


def aba(model, q, qd, v0, tau, f_ext=None, damping=None, inertias=None, v=None, lock=None, prescribed=None, static=False):
    """Forward dynamics of the whole batch.

    The bias sweep uses ``u = tau - S'pA`` and ``pa = pA + Ia c + U u / d`` (``Ia = IA - U U'/d``),
    so a child passes ``Xup' pa = Z' pA + Yt' c + W (tau - U'c)`` to its parent; the
    acceleration sweep ``a = Xup a_parent + c + S qdd`` with ``qdd = (u - U'(Xup a_parent + c))/d``
    is ``a = Z a_parent + c + S (u - U'c) / d`` (``W``, ``Z``, ``Yt`` of :func:`articulated_inertias`).
    Leaves need no sweep: their ``pA`` is complete at once and their ``a`` is never needed.

    Args:
        model: packed :class:`~coursekit.creatures.physics.model.Model`.
        q, qd: (M,) joint coordinates and rates (internal joint order).
        v0: (C, 6) root spatial velocity in root coordinates, ``(omega, v)``.
        tau: (M,) joint forces.
        f_ext: optional (N, 6) external spatial force on every body, body coordinates.
        damping: optional (N, 6) diagonal of a body-frame damping matrix ``D``; adds ``-D v``.
        inertias: optional result of :func:`articulated_inertias` at this ``q`` (reused).
        v: optional (N, 6) body velocities at this state (:func:`body_velocities`; reused).
        lock, prescribed: optional (M,) bool and (M,) accelerations: hybrid dynamics -- the
            locked joints move with the ``prescribed`` accelerations (0 if ``None``: they keep
            their rates; their ``tau`` is ignored) and the rest of the tree responds;
            ``inertias`` must then be computed with this ``lock``.
        static: the graph-ready formulation (:func:`articulated_inertias`); the root's 6 x 6
            solve is then :func:`~.backend.solve`'s elimination, which reads nothing on the host.

    Returns:
        ``(a0, qdd, v)``: root spatial acceleration (C, 6) in root coordinates, joint
        accelerations (M,) and body velocities (N, 6); with ``lock``, also a function that
        returns the joint forces (M,) the locked joints need (``tau`` for the free ones).
    """
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging creature is the guard's business
        return _aba(model, q, qd, v0, tau, f_ext, damping, inertias, v, lock, prescribed, static)


def _aba(model, q, qd, v0, tau, f_ext, damping, inertias, v, lock, prescribed, static):
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    Xup, IA, U, d, W, Z, Yt, V = articulated_inertias(model, q, lock, static) if inertias is None else inertias
    ap = None  # locked joints' accelerations: qdd = ap where locked, 0 elsewhere; None: all 0
    if lock is not None and prescribed is not None:
        ap = xp.where(lock, prescribed, xp.zeros_like(prescribed))
    S = model.S
    v, c, pA = _velocities_and_bias(model, Xup, v0, qd, v)
    I = model.inertia_diag
    if damping is not None:
        pA += damping * v
    if f_ext is not None:
        pA -= f_ext
    Uc = sp.dot(xp, U, c)
    jl, ji = slice(L - C, None), slice(0, L - C)
    # leaves, all at once (their IA is the diagonal I)
    ul = tau[jl] - sp.dot(xp, S[jl], pA[L:])
    ql = (ul - Uc[jl]) / d[jl]
    if lock is not None:  # a locked joint's acceleration is prescribed: pa = pA + I c + U ap
        ql = xp.where(lock[jl], 0.0 if ap is None else ap[jl], ql)
    pa = pA[L:] + I[L:] * c[jl] + U[jl] * ql[:, None]
    # what does not depend on the sweep -- the leaves' Xup' pa and the inner joints' h -- is
    # summed into the parents at once; the inner levels then pass Z' pA on
    g = xp.empty_like(c)  # h of the inner joints, Xup' pa of the leaves
    h = sp.mtv(Yt, c[ji], out=g[ji])
    h += W[ji] * (tau[ji] - Uc[ji])[:, None]  # W = 0 for locked joints, which pass Xup' U ap
    if ap is not None:
        h += V[ji] * ap[ji][:, None]
    sp.mtv(Xup[jl], pa, out=g[jl])
    model.joint_segments.add_into(pA, g)
    _inward(model, Z, pA)
    SpA = sp.dot(xp, S, pA[C:])
    ud = (tau - SpA - Uc) / d  # (u - U'c) / d
    if lock is not None:
        ud = xp.where(lock, 0.0 if ap is None else ap, ud)

    a0 = -bk.solve(xp, IA[:C], pA[:C], static)
    a = _outward(model, Z, xp.concat([a0, c[ji] + S[ji] * ud[ji][:, None]], axis=0))  # a = Z a_parent + c + S ud
    a_parent = xp.take(a, model.joint_parent, axis=0)
    qdd = ud - sp.dot(xp, W, a_parent)
    if lock is None:
        return a0, qdd, v
    # the force a locked joint needs: the free formula qdd = (tau - S'pA - U'(Xup a_p + c)) / d
    # solved for tau -- returned as a function, since a step needs it from its last evaluation only
    def force():
        need = SpA + Uc + sp.dot(xp, V, a_parent)
        return xp.where(lock, need if ap is None else need + d * ap, tau)

    return a0, qdd, v, force


def impulse(model, inertias, lock, change, static=False, wrench=None, forces=False):
    """The hybrid system's response to a change of the locked joints' rates, from rest.

    The sweeps of :func:`aba` with no velocities and no forces (no bias terms: ``c = 0``,
    ``pA = 0`` at first): the locked joints' rates change by ``change`` (M,) and the root and the
    free joints respond as the articulated inertia makes them -- an impulse through the body,
    which conserves momentum exactly (the joint limits, :mod:`limits`). ``wrench`` (N, 6),
    optional: impulses on the bodies too (body coordinates, like :func:`aba`'s ``f_ext``; the
    held self-contacts of :mod:`contact_forces`, as forces), which the locked joints pass on whole.

    Args:
        inertias: :func:`articulated_inertias` at the state's ``q`` with this ``lock``.
        lock: (M,) bool, or ``None`` (no joint locked; ``change`` is then ignored).
        static: the graph-ready root solve (:func:`aba`).
        forces: also return the impulses the locked joints took to change as prescribed (M,; 0 for
            the free ones) -- :func:`aba`'s locked-joint forces with no velocities.
    Returns:
        ``(dv0, dqd)``: the root's velocity change (C, 6) in root coordinates and the joints' (M,);
        ``(dv0, dqd, force)`` with ``forces``.
    """
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    Xup, IA, U, d, W, Z, Yt, V = inertias
    S = model.S
    ji, jl = slice(0, L - C), slice(L - C, None)
    pA = xp.zeros((model.n_bodies, 6), dtype=change.dtype, device=model.device) if wrench is None else -wrench
    g = xp.zeros_like(U)  # what each joint passes to its parent before the inner sweep
    if lock is not None:
        ap = xp.where(lock, change, xp.zeros_like(change))
        g = g + V * ap[:, None]  # Xup' U ap (locked), 0 (free)
    if wrench is not None:  # a leaf passes Xup' (pA - U S'pA / d), all of it when locked (W = 0)
        pl = pA[L:]
        g[jl] += sp.mtv(Xup[jl], pl) - W[jl] * sp.dot(xp, S[jl], pl)[:, None]
    model.joint_segments.add_into(pA, g)
    _inward(model, Z, pA)
    ud = -sp.dot(xp, S, pA[C:]) / d
    if lock is not None:
        ud = xp.where(lock, ap, ud)
    a0 = -bk.solve(xp, IA[:C], pA[:C], static)
    a = _outward(model, Z, xp.concat([a0, S[ji] * ud[ji][:, None]], axis=0))
    a_parent = xp.take(a, model.joint_parent, axis=0)
    if not forces:
        return a0, ud - sp.dot(xp, W, a_parent)
    force = xp.zeros_like(ud) if lock is None else xp.where(lock, sp.dot(xp, S, pA[C:]) + sp.dot(xp, V, a_parent) + d * ap, xp.zeros_like(ud))
    return a0, ud - sp.dot(xp, W, a_parent), force
