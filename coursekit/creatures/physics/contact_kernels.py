"""The compiled self-contact constraints (:mod:`~coursekit.creatures.physics.contact_forces`, for
``World(compiled=True)``): slots, the responses to the slots' unit forces and the Delassus
matrices, the projected Gauss-Seidel solve and the contact forces of a stage, each a loop compiled
with numba. The same arithmetic as the numpy code, contact by contact, so the two follow each
other to round-off (``tests/test_physics_compiled.py``); the sweeps run over the creatures that
hold a contact only.
"""

from __future__ import annotations

import numpy as np

from .kernels import _jit, _root_solve, _x_apply, _xt_apply


@_jit
def _point_velocity(R, p, v, body, x, out):  # pragma: no cover - compiled
    """``out`` (3,): the world velocity of ``body``'s material point at world ``x`` (body velocities ``v``)."""
    l0, l1, l2 = x[0] - p[body, 0], x[1] - p[body, 1], x[2] - p[body, 2]
    y0 = R[body, 0, 0] * l0 + R[body, 1, 0] * l1 + R[body, 2, 0] * l2  # the point in the body's frame
    y1 = R[body, 0, 1] * l0 + R[body, 1, 1] * l1 + R[body, 2, 1] * l2
    y2 = R[body, 0, 2] * l0 + R[body, 1, 2] * l1 + R[body, 2, 2] * l2
    w0, w1, w2 = v[body, 0], v[body, 1], v[body, 2]
    u0, u1, u2 = v[body, 3] + (w1 * y2 - w2 * y1), v[body, 4] + (w2 * y0 - w0 * y2), v[body, 5] + (w0 * y1 - w1 * y0)
    for c in range(3):
        out[c] = R[body, c, 0] * u0 + R[body, c, 1] * u1 + R[body, c, 2] * u2


@_jit
def _normal_speed(R, p, v, a, b, x, n):  # pragma: no cover - compiled
    """``n . (v_b(x) - v_a(x))``."""
    vb, va = np.empty(3), np.empty(3)
    _point_velocity(R, p, v, b, x, vb)
    _point_velocity(R, p, v, a, x, va)
    return n[0] * (vb[0] - va[0]) + n[1] * (vb[1] - va[1]) + n[2] * (vb[2] - va[2])


@_jit
def _push(R, p, body, x, n, sign, f):  # pragma: no cover - compiled
    """Add to ``f`` (N, 6) the body-frame impulse of ``sign n`` applied to ``body`` at world ``x``."""
    F0, F1, F2 = sign * n[0], sign * n[1], sign * n[2]
    l0, l1, l2 = x[0] - p[body, 0], x[1] - p[body, 1], x[2] - p[body, 2]
    m0, m1, m2 = l1 * F2 - l2 * F1, l2 * F0 - l0 * F2, l0 * F1 - l1 * F0
    for c in range(3):
        f[body, c] += R[body, 0, c] * m0 + R[body, 1, c] * m1 + R[body, 2, c] * m2
        f[body, c + 3] += R[body, 0, c] * F0 + R[body, 1, c] * F1 + R[body, 2, c] * F2


@_jit
def slots(owner, depth, thin, cap, slot, count):  # pragma: no cover - compiled
    """Each creature's ``cap`` deepest contacts (relative to the thinner part ``thin``) take slots, in the contacts'
    order (``owner``: their creatures, grouped): ``slot`` (H,) (-1: none), ``count`` (C,); returns
    the most slots a creature takes."""
    H = owner.shape[0]
    K = 0
    h0 = 0
    while h0 < H:
        h1 = h0
        while h1 < H and owner[h1] == owner[h0]:
            h1 += 1
        key = np.empty(h1 - h0)
        for h in range(h0, h1):
            key[h - h0] = min(max(-depth[h] / thin[h], -1e5), 1e5)
        taken = np.zeros(h1 - h0, np.bool_)
        for i in np.argsort(key, kind="mergesort")[:cap]:
            taken[i] = True
        c = owner[h0]
        for h in range(h0, h1):
            slot[h] = -1
            if taken[h - h0]:
                slot[h] = count[c]
                count[c] += 1
        K = max(K, count[c])
        h0 = h1
    return K


@_jit
def _impulse_sweeps(parent, E, r, S, IA, U, d, chol, lock, creature, active, f, r0, rq, dv):  # pragma: no cover - compiled
    """:func:`~.kernels._sweeps` for impulses ``f`` (N, 6) on bodies at rest, every locked joint's rate
    kept, over the ``active`` creatures' bodies only: the roots' velocity changes ``r0`` (C, 6),
    the joints' ``rq`` (M,) and every body's ``dv`` (N, 6) (the other creatures' are left as they are)."""
    N, C = parent.shape[0], r0.shape[0]
    pA = np.empty((N, 6))
    u = np.empty(N)
    pa, out = np.empty(6), np.empty(6)
    for i in range(N):
        if active[creature[i]]:
            for m in range(6):
                pA[i, m] = -f[i, m]
    for i in range(N - 1, C - 1, -1):  # inwards: pa = pA + U u / d (0 if locked)
        if not active[creature[i]]:
            continue
        j = i - C
        SpA = 0.0
        for m in range(6):
            SpA += S[j, m] * pA[i, m]
        u[i] = -SpA
        gain = 0.0 if lock[j] else u[i] / d[j]
        for m in range(6):
            pa[m] = pA[i, m] + U[j, m] * gain
        _xt_apply(E[j], r[j], pa, out)
        for m in range(6):
            pA[parent[i], m] += out[m]
    for c in range(C):
        if active[c]:
            _root_solve(chol[c], pA[c], r0[c])
            dv[c] = r0[c]
    for i in range(C, N):  # outwards: dv = Xup dv_parent + S qdd
        if not active[creature[i]]:
            continue
        j = i - C
        _x_apply(E[j], r[j], dv[parent[i]], dv[i])
        Ua = 0.0
        for m in range(6):
            Ua += U[j, m] * dv[i, m]
        rq[j] = 0.0 if lock[j] else (u[i] - Ua) / d[j]
        for m in range(6):
            dv[i, m] += S[j, m] * rq[j]


@_jit
def responses(parent, E, r, S, IA, U, d, chol, lock, creature, R, p, owner, a, b, n, x, slot, count, r0, rq, D):  # pragma: no cover - compiled
    """The responses ``r0`` (K, C, 6), ``rq`` (K, M) to every slot's unit forces through the
    articulated inertias ``IA .. chol`` (with ``lock``), and each creature's Delassus matrix ``D``
    (C, K, K): ``D[c, s, k]``, the normal speed at its slot ``s`` per unit impulse in slot ``k``."""
    H, N, K, C = a.shape[0], parent.shape[0], r0.shape[0], count.shape[0]
    f, dv = np.zeros((N, 6)), np.zeros((N, 6))
    active = np.empty(C, np.bool_)
    for k in range(K):
        for c in range(C):
            active[c] = k < count[c]  # only the creatures with a contact in slot k
        for h in range(H):
            if slot[h] == k:
                _push(R, p, b[h], x[h], n[h], 1.0, f)
                _push(R, p, a[h], x[h], n[h], -1.0, f)
        _impulse_sweeps(parent, E, r, S, IA, U, d, chol, lock, creature, active, f, r0[k], rq[k], dv)
        for h in range(H):
            if slot[h] == k:
                for m in range(6):
                    f[b[h], m] = 0.0
                    f[a[h], m] = 0.0
        for h in range(H):
            if slot[h] >= 0 and k < count[owner[h]]:
                D[owner[h], slot[h], k] = _normal_speed(R, p, dv, a[h], b[h], x[h], n[h])


@_jit
def per_slot(owner, slot, values, out):  # pragma: no cover - compiled
    """``out[c, s]`` = the value of creature ``c``'s contact in slot ``s``."""
    for h in range(owner.shape[0]):
        if slot[h] >= 0:
            out[owner[h], slot[h]] = values[h]


@_jit
def speeds(R, p, v, owner, a, b, n, x, slot, out):  # pragma: no cover - compiled
    """``out[c, s]``: the normal speed of creature ``c``'s contact in slot ``s`` at body velocities ``v``."""
    for h in range(owner.shape[0]):
        if slot[h] >= 0:
            out[owner[h], slot[h]] = _normal_speed(R, p, v, a[h], b[h], x[h], n[h])


@_jit
def solve(D, rhs, floor, hi, count, iterations, lam):  # pragma: no cover - compiled
    """:func:`~.contact_forces.pgs`, creature by creature: ``lam`` (C, K) from ``D`` (C, K, K), ``rhs``, ``floor`` and ``hi`` (C, K)."""
    K = rhs.shape[1]
    for c in range(rhs.shape[0]):
        k = count[c]
        w = rhs[c].copy()
        for s in range(K):
            lam[c, s] = 0.0
        for _ in range(iterations):
            for s in range(k):
                inv = 1.0 / D[c, s, s] if D[c, s, s] > floor[c, s] else 0.0
                new = min(max(lam[c, s] - w[s] * inv, 0.0), hi[c, s])
                delta = new - lam[c, s]
                lam[c, s] = new
                for t in range(K):
                    w[t] += D[c, t, s] * delta


@_jit
def rates(rq, r0, joint_creature, out):  # pragma: no cover - compiled
    """``out[c, k]``: the largest change of creature ``c``'s joints' rates (or its root's spin) per unit force in slot ``k``."""
    for k in range(rq.shape[0]):
        for c in range(r0.shape[1]):
            out[c, k] = max(abs(r0[k, c, 0]), abs(r0[k, c, 1]), abs(r0[k, c, 2]))
        for j in range(rq.shape[1]):
            out[joint_creature[j], k] = max(out[joint_creature[j], k], abs(rq[k, j]))


@_jit
def normal_speeds(R, p, v, a, b, n, x, out):  # pragma: no cover - compiled
    """``out`` (H,): every contact's normal speed at body velocities ``v``."""
    for h in range(a.shape[0]):
        out[h] = _normal_speed(R, p, v, a[h], b[h], x[h], n[h])


@_jit
def hold(parent, S, iterations, held, E, r, IA, U, d, chol, lock, R0, a0, qdd, da, dq):  # pragma: no cover - compiled
    """The held contacts' forces' share ``da`` (C, 6), ``dq`` (M,) of a stage's accelerations
    ``a0`` (C, 6), ``qdd`` (M,) (:meth:`~.contact_forces.ContactForces.force`): ``0 <= f <= hi`` keeping each
    held pair's normal acceleration ``J a + D f`` at or above its gap allowance, complementary,
    with ``J`` and ``D`` of the step's start; the forces act at the stage's own poses (its
    transforms ``E, r``, roots' rotations ``R0``), B pushed along the normal turning with A at B's
    material point, A pulled back, and are swept through the stage's inertias ``IA .. chol``.
    ``held``: :meth:`~.compiled.Dynamics.hold`."""
    Es, rs, R, p, owner, a, b, n, x, slot, count, D, floor, hi, bias, n_a, x_b = held
    K = D.shape[1]
    N, C = parent.shape[0], a0.shape[0]
    # only the creatures holding a contact: their bodies, their stage accelerations (the bias
    # accelerations aside, as J a reads them) and their poses relative to their roots
    active, creature = count > 0, np.empty(N, np.int64)
    dv, Rs, ps = np.empty((N, 6)), np.empty((N, 3, 3)), np.empty((N, 3))
    for i in range(C):
        creature[i] = i
        if active[i]:
            dv[i] = a0[i]
            Rs[i] = R0[i]
            ps[i] = 0.0  # moments do not care
    for i in range(C, N):
        k = parent[i]
        creature[i] = creature[k]
        if not active[creature[i]]:
            continue
        j = i - C
        _x_apply(Es[j], rs[j], dv[k], dv[i])
        for m in range(6):
            dv[i, m] += S[j, m] * qdd[j]
        for m in range(3):
            for c in range(3):
                Rs[i, m, c] = Rs[k, m, 0] * E[j, c, 0] + Rs[k, m, 1] * E[j, c, 1] + Rs[k, m, 2] * E[j, c, 2]
            ps[i, m] = ps[k, m] + Rs[k, m, 0] * r[j, 0] + Rs[k, m, 1] * r[j, 1] + Rs[k, m, 2] * r[j, 2]
    alpha, f = np.zeros((C, K)), np.zeros((C, K))
    speeds(R, p, dv, owner, a, b, n, x, slot, alpha)
    for c in range(C):
        for s in range(K):
            alpha[c, s] += bias[c, s]
    solve(D, alpha, floor, hi, count, iterations, f)
    wrench = np.zeros((N, 6))
    nn, xx = np.empty(3), np.empty(3)
    for h in range(a.shape[0]):
        if slot[h] < 0:
            continue
        force = f[owner[h], slot[h]]
        A, B = a[h], b[h]
        for c in range(3):
            nn[c] = force * (Rs[A, c, 0] * n_a[h, 0] + Rs[A, c, 1] * n_a[h, 1] + Rs[A, c, 2] * n_a[h, 2])
            xx[c] = Rs[B, c, 0] * x_b[h, 0] + Rs[B, c, 1] * x_b[h, 1] + Rs[B, c, 2] * x_b[h, 2] + ps[B, c]
        _push(Rs, ps, B, xx, nn, 1.0, wrench)
        _push(Rs, ps, A, xx, nn, -1.0, wrench)
    da[:] = 0.0
    dq[:] = 0.0
    _impulse_sweeps(parent, E, r, S, IA, U, d, chol, lock, creature, active, wrench, da, dq, dv)
