"""Featherstone's articulated-body algorithm, batched over a packed population (paper section 2.4).

The three sweeps of spatial_v2's ``FDab`` with a floating base, in the book's notation (``Xup``,
``S``, ``vJ``, ``c``, ``IA``, ``pA``, ``U``, ``d``, ``u``), looping over tree *depth levels*
instead of bodies: every body of every creature at one depth is processed by one stacked array
operation. All quantities are in body coordinates; bodies sit at their centres of mass with
principal axes, so each rigid-body inertia is diagonal. There is no gravity (neutral buoyancy),
so the world pose of the root never enters the dynamics.

Joint motion subspaces are constant in the child frame (revolute: ``(a, c x a)`` for axis ``a``
through the anchor ``c``; prismatic: ``(0, a)``), so the joint bias ``cJ`` is zero.

Leaves (about half the bodies of a random creature) are not swept level by level: their
articulated inertia is their rigid one, so ``U``, ``d`` and ``Ia = I - U U'/d`` are constants of
the model, and what a leaf passes to its parent, ``Xup' Ia Xup``, is a trigonometric (revolute)
or quadratic (prismatic) polynomial of degree two in ``q`` with constant matrix coefficients
(:func:`fit_joint_basis`). All leaves are handled by one stacked operation per sweep; the
level loops run over the inner bodies only (the model stores leaves after them).

numpy notes (measured at 300 creatures, about 4,500 bodies; the step is bound by memory traffic
and by per-call overhead, not by arithmetic): stacked 6x6 (and 3x3) ``A x``, ``A' x`` and row dot
products go through numpy's own ``matvec`` loop on reversed views (:func:`spatial.mv`,
:func:`spatial.mtv`, :func:`spatial.dot`): contiguous operands are handed to BLAS one small matrix
at a time, which is 1.5 to 2.5 times slower (2,232 6x6 products: 73 -> 39 us; 4,184 row dots:
34 -> 13 us) -- the products took the step from 8.67 to 8.30 ms, the dots 7.84 -> 7.55 ms (A/B in
one process; the machine's speed drifts between runs). Row gathers use ``take`` (three times
faster than fancy indexing); sums into parents go through scipy's CSR kernel in place (:class:`~coursekit.creatures.physics.backend.Segments`); symmetric
sums stream 21 entries, not 36; the transforms ``Xup`` are formed from the coefficients of their
18 distinct entries and one ``take`` along the rows (half the basis to stream: 234 -> 188 us per
build, the step 7.47 -> 7.23 ms); cross products use whole component-major rows. The two stacked
6x6 ``matmul`` per inner body of :func:`articulated_inertias` stay with BLAS, whose per-matrix
cost depends on the machine's ``OPENBLAS_CORETYPE`` (658 products: 40-46 us with the forced
``Haswell``, 16.5 us without; numpy's own loop 53 us either way).

Tried and not kept: a Cholesky root solve (neutral: the factor costs what the solves save; numpy's
raw ``solve1`` gufunc is no faster than ``linalg.solve``, 75 vs 78 us, and an inverse shared by
RKN stages 2 and 3 costs 150 us, more than the two solves); the 18 distinct entries written
into the 6x6 stack by three block copies (the copies alone take 180-310 us; the ``take`` above is
what paid off); ``Xup`` as ``P0 + cos P1 + sin P2`` by broadcasting (230 vs 250 us:
within noise, one broadcast product costs 81 us); each level's ``Xup`` formed just before the level
(to find it in cache: 7.40 vs 7.33 ms); the 6x6 ``matmul`` as one broadcast ``matvec`` (153 vs
75 us) or through reversed views (numpy's loop, slower than BLAS, above); component-major 6x6
products (two to three times slower than the stacked ones); and, in the contact path, one
``bincount`` over (row, column) bins for the wrench scatter (74 vs 70 us) and forward kinematics
with the three terms of each product written out (363 vs 300 us).
"""

from __future__ import annotations

import numpy as np

from . import backend as bk
from . import spatial as sp


def _transforms(xp, revolute, q, E0, E1, E2, r0, r1, r2, r3):
    """Rodrigues' formula with constant factors (``K = [axis]x``, ``J`` the joint rotation):
    revolute ``E = J' + sin q (-K J') + (1 - cos q) K^2 J'``; prismatic ``E = J'`` and ``r`` moves
    along ``J axis`` (used to fit :func:`fit_joint_basis`)."""
    zero = xp.zeros_like(q)
    angle = xp.where(revolute, q, zero)
    s, c1 = xp.sin(angle), 1.0 - xp.cos(angle)
    E = E0 + s[:, None, None] * E1 + c1[:, None, None] * E2
    slide = xp.where(revolute, zero, q)
    r = r0 + s[:, None] * r1 + c1[:, None] * r2 + slide[:, None] * r3
    return E, r


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


def joint_basis(xp, revolute, q):
    """(n, 5) polynomial basis in ``q``: revolute ``(1, cos q, sin q, cos 2q, sin 2q)``, prismatic
    ``(1, q, q^2, 0, 0)``. The first three span the entries of ``Xup(q)``."""
    rev = xp.astype(revolute, q.dtype)  # 1 for revolute joints, 0 for prismatic ones
    angle, slide = q * rev, q - q * rev  # a prismatic joint has angle 0: cos 1, sin 0
    # cos and sin from the tangent of the half angle: one transcendental call, not two (numpy's
    # float64 tan is several times faster than its sin or cos)
    t = xp.tan(0.5 * angle)
    t2 = t * t
    k = 1.0 / (1.0 + t2)
    c, s = (1.0 - t2) * k, (t + t) * k
    return xp.stack([xp.ones_like(q), xp.where(revolute, c, slide), s + slide * slide, (c * c - s * s) * rev, 2.0 * s * c], axis=-1)


def fit_joint_basis(revolute: np.ndarray, consts: dict, sample, k: int = 3) -> np.ndarray:
    """Constant coefficients ``P`` (n, k, w) with ``sample(E(q), r(q)) = joint_basis(q)[:, :k] @ P``
    for every ``q`` (numpy).

    ``Xup(q) = X_c Rot(q) X_p`` (constant transforms on either side of the joint's rotation or
    slide) has entries in ``span(1, cos q, sin q)`` (revolute) or ``span(1, q)`` (prismatic): so
    ``E``, ``r`` and ``Xup`` are of degree one (``k = 3``) in the basis and congruences
    ``Xup' I Xup`` of degree two (``k = 5``). Fitted exactly from ``k`` samples per joint (equally
    spaced angles; slides centred on 0), with Rodrigues' formula at the samples.

    Args:
        revolute: (n,) joint kinds; consts: the Rodrigues constants ``E0, E1, E2`` (rotation
            ``E = E0 + sin q E1 + (1 - cos q) E2``) and ``r0, r1, r2, r3`` (origin, plus
            ``slide r3`` for prismatic joints) of these joints; sample: ``(E, r) -> (n, w)``.
    """
    ks = np.arange(float(k))
    qs = np.where(revolute[:, None], 2 * np.pi * ks / k, ks - (k - 1) / 2)  # (n, k) sample points
    samples = np.stack([sample(*_transforms(np, revolute, qs[:, i], *(consts[c] for c in ("E0", "E1", "E2", "r0", "r1", "r2", "r3")))) for i in range(k)], axis=1)
    B = joint_basis(np, revolute[:, None], qs)[..., :k]  # (n, k samples, k functions)
    return np.linalg.pinv(B) @ samples


def joint_transform_matrices(model, q):
    """(M, 6, 6) joint transforms ``Xup`` at ``q`` from the model's constant coefficients."""
    return _transform_matrices(model, joint_basis(model.xp, model.revolute, q))


def _transform_matrices(model, b):
    """(M, 6, 6) ``Xup`` from the (M, 5) :func:`joint_basis` ``b``: numpy takes one stacked
    (1 x 3) @ (3 x 19) product per joint for the distinct entries (``E``, ``-E rx``, 0) and
    gathers the 36 from them; torch, whose small stacked products are slow on the CPU, two
    ``addcmul`` over the rows of the full coefficients."""
    P = model.X_basis
    if model.xp is np:
        return np.take((b[:, None, :3] @ P)[:, 0], model.X_expand, axis=1).reshape(-1, 6, 6)
    return P[0].addcmul(b[:, 1:2], P[1]).addcmul_(b[:, 2:3], P[2]).reshape(-1, 6, 6)


def _outward_velocities(model, X, v0, vJ):
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    v = xp.concat([v0, vJ], axis=0)  # each body then adds its parent's velocity, transformed
    for s, e, par, _ in model.levels:
        v[s:e] += sp.mv(X[s - C : e - C], xp.take(v, par, axis=0))  # take: several times faster than v[par]
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
        v = _outward_velocities(model, X, v0, model.S * qd[:, None])
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


def articulated_inertias(model, q, lock=None):
    """The velocity-independent half of the ABA: ``(Xup, IA, U, d, W, Z, Yt, V)`` at ``q``.

    ``Xup`` (M, 6, 6) are the joint transforms; ``IA`` (L, 6, 6) the articulated inertias of the
    roots and inner bodies (a leaf's is its rigid inertia), ``U = IA S`` and ``d = S' U`` (M,)
    per joint, ``W = Xup' U / d`` (M, 6) and, for the inner joints, ``Z = Xup - S W'`` and
    ``Yt = IA Xup`` (L - C, 6, 6). Each child passes ``Xup' (IA - U U' / d) Xup = Yt' Z`` to its
    parent. (``IA`` is symmetric, so ``U = IA S`` is computed as ``S' IA``.)
    They depend on the positions only, so the Nyström stages 2 and 3, which share positions,
    share them.

    ``lock`` (M,) bool, optional: joints whose acceleration is *prescribed* (hybrid dynamics,
    Featherstone 2008 section 9.3; the joint limits of :mod:`limits`). A locked joint passes its
    whole articulated inertia to its parent (``Xup' IA Xup``: ``W = 0``, ``Z = Xup``), and
    ``V = Xup' U`` (M, 6) is returned for the bias sweep (``None`` without ``lock``).
    """
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    b = joint_basis(xp, model.revolute, q)
    Xup = _transform_matrices(model, b)
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
        k = bk.nonzero(xp, lock[jl])
        if k.shape[0]:
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


def aba(model, q, qd, v0, tau, f_ext=None, damping=None, inertias=None, v=None, lock=None, prescribed=None):
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

    Returns:
        ``(a0, qdd, v)``: root spatial acceleration (C, 6) in root coordinates, joint
        accelerations (M,) and body velocities (N, 6); with ``lock``, also a function that
        returns the joint forces (M,) the locked joints need (``tau`` for the free ones).
    """
    with np.errstate(over="ignore", invalid="ignore"):  # a diverging creature is the guard's business
        return _aba(model, q, qd, v0, tau, f_ext, damping, inertias, v, lock, prescribed)


def _aba(model, q, qd, v0, tau, f_ext, damping, inertias, v, lock, prescribed):
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    Xup, IA, U, d, W, Z, Yt, V = articulated_inertias(model, q, lock) if inertias is None else inertias
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
    for s, e, _, seg in reversed(model.levels):
        seg.add_into(pA, sp.mtv(Z[s - C : e - C], pA[s:e]))
    SpA = sp.dot(xp, S, pA[C:])
    ud = (tau - SpA - Uc) / d  # (u - U'c) / d
    if lock is not None:
        ud = xp.where(lock, 0.0 if ap is None else ap, ud)

    a0 = -xp.linalg.solve(IA[:C], pA[:C][:, :, None])[:, :, 0]
    a = xp.concat([a0, c[ji] + S[ji] * ud[ji][:, None]], axis=0)  # each body then adds Z a_parent
    for s, e, par, _ in model.levels:
        a[s:e] += sp.mv(Z[s - C : e - C], xp.take(a, par, axis=0))
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


def impulse(model, inertias, lock, change):
    """The hybrid system's response to a change of the locked joints' rates, from rest.

    The sweeps of :func:`aba` with no velocities and no forces (no bias terms: ``c = 0``,
    ``pA = 0`` at first): the locked joints' rates change by ``change`` (M,) and the root and the
    free joints respond as the articulated inertia makes them -- an impulse through the body,
    which conserves momentum exactly (the joint limits, :mod:`limits`).

    Args:
        inertias: :func:`articulated_inertias` at the state's ``q`` with this ``lock``.
    Returns:
        ``(dv0, dqd)``: the root's velocity change (C, 6) in root coordinates and the joints' (M,).
    """
    xp = model.xp
    C, L = model.n_creatures, model.leaf_start
    Xup, IA, U, d, W, Z, Yt, V = inertias
    S = model.S
    ap = xp.where(lock, change, xp.zeros_like(change))
    ji = slice(0, L - C)
    pA = xp.zeros((model.n_bodies, 6), dtype=ap.dtype, device=model.device)
    model.joint_segments.add_into(pA, V * ap[:, None])  # what each joint passes to its parent: Xup' U ap (locked), 0 (free)
    for s, e, _, seg in reversed(model.levels):
        seg.add_into(pA, sp.mtv(Z[s - C : e - C], pA[s:e]))
    ud = xp.where(lock, ap, -sp.dot(xp, S, pA[C:]) / d)
    a0 = -xp.linalg.solve(IA[:C], pA[:C][:, :, None])[:, :, 0]
    a = xp.concat([a0, S[ji] * ud[ji][:, None]], axis=0)
    for s, e, par, _ in model.levels:
        a[s:e] += sp.mv(Z[s - C : e - C], xp.take(a, par, axis=0))
    return a0, ud - sp.dot(xp, W, xp.take(a, model.joint_parent, axis=0))


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
