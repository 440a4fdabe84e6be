"""The compiled kernels of the swimmers' step: joint transforms, poses, articulated inertias, a
stage of the integrator (velocities, contact springs, the ABA's sweeps), the limits' impulses,
contact detection and the brains' neurons, each a loop compiled with numba. :mod:`~coursekit.creatures.physics.compiled`
says what they are for and builds the step on them.
"""

from __future__ import annotations

import numpy as np

from .contact import TIE

try:
    import numba
except ImportError:  # pragma: no cover - the numpy step needs no numba
    numba = None


def available() -> bool:
    """Whether numba is installed (a dependency of coursekit), so that ``World(compiled=True)`` can run."""
    return numba is not None


def _jit(f):
    if numba is None:
        return f
    # error_model="numpy": a division by zero gives inf or NaN, as numpy's does, for the guards to see
    try:
        return numba.njit(cache=True, error_model="numpy")(f)
    except RuntimeError:  # no folder to cache in (a read-only install): compiled anew each session
        return numba.njit(error_model="numpy")(f)


# ---------------------------------------------------------------- small spatial helpers


@_jit
def _x_apply(E, r, x, out):  # pragma: no cover - compiled
    """``out = Xup x`` for a motion vector: ``(E w, E (u - r x w))``."""
    w0, w1, w2 = x[0], x[1], x[2]
    u0 = x[3] - (r[1] * w2 - r[2] * w1)
    u1 = x[4] - (r[2] * w0 - r[0] * w2)
    u2 = x[5] - (r[0] * w1 - r[1] * w0)
    for i in range(3):
        out[i] = E[i, 0] * w0 + E[i, 1] * w1 + E[i, 2] * w2
        out[i + 3] = E[i, 0] * u0 + E[i, 1] * u1 + E[i, 2] * u2


@_jit
def _xt_apply(E, r, f, out):  # pragma: no cover - compiled
    """``out = Xup' f`` for a force: ``(E' n + r x E' g, E' g)`` with ``f = (n, g)``."""
    n0 = E[0, 0] * f[0] + E[1, 0] * f[1] + E[2, 0] * f[2]
    n1 = E[0, 1] * f[0] + E[1, 1] * f[1] + E[2, 1] * f[2]
    n2 = E[0, 2] * f[0] + E[1, 2] * f[1] + E[2, 2] * f[2]
    g0 = E[0, 0] * f[3] + E[1, 0] * f[4] + E[2, 0] * f[5]
    g1 = E[0, 1] * f[3] + E[1, 1] * f[4] + E[2, 1] * f[5]
    g2 = E[0, 2] * f[3] + E[1, 2] * f[4] + E[2, 2] * f[5]
    out[0] = n0 + r[1] * g2 - r[2] * g1
    out[1] = n1 + r[2] * g0 - r[0] * g2
    out[2] = n2 + r[0] * g1 - r[1] * g0
    out[3], out[4], out[5] = g0, g1, g2


# ---------------------------------------------------------------- joint transforms and poses


@_jit
def transforms(P, revolute, q, E, r):  # pragma: no cover - compiled
    """Every joint's ``E`` (M, 3, 3) and ``r`` (M, 3) at ``q`` from the model's pose coefficients
    ``P`` (M, 3, 12) (:attr:`Model.pose_rows_basis`), in :func:`~.jcalc.joint_basis`'s basis."""
    for j in range(q.shape[0]):
        if revolute[j]:
            t = np.tan(0.5 * q[j])
            t2 = t * t
            k = 1.0 / (1.0 + t2)
            b1, b2 = (1.0 - t2) * k, (t + t) * k
        else:
            b1, b2 = q[j], q[j] * q[j]
        for a in range(3):
            for c in range(3):  # row 3a + c of the coefficients is (E')[a, c] = E[c, a]
                E[j, c, a] = P[j, 0, 3 * a + c] + b1 * P[j, 1, 3 * a + c] + b2 * P[j, 2, 3 * a + c]
            r[j, a] = P[j, 0, 9 + a] + b1 * P[j, 1, 9 + a] + b2 * P[j, 2, 9 + a]


@_jit
def _poses(parent, E, r, R0, p0, R, p):  # pragma: no cover - compiled
    """World rotations ``R`` (N, 3, 3) and positions ``p`` (N, 3): ``R = R_parent E'``,
    ``p = p_parent + R_parent r``."""
    C = R0.shape[0]
    for i in range(C):
        R[i] = R0[i]
        p[i] = p0[i]
    for i in range(C, parent.shape[0]):
        j, k = i - C, parent[i]
        for a in range(3):
            for c in range(3):
                R[i, a, c] = R[k, a, 0] * E[j, c, 0] + R[k, a, 1] * E[j, c, 1] + R[k, a, 2] * E[j, c, 2]
            p[i, a] = p[k, a] + R[k, a, 0] * r[j, 0] + R[k, a, 1] * r[j, 1] + R[k, a, 2] * r[j, 2]


# ---------------------------------------------------------------- articulated inertias


@_jit
def inertias(parent, E, r, S, inertia, lock, IA, U, d, chol):  # pragma: no cover - compiled
    """The velocity-independent half of the ABA at the joints' ``E, r``: articulated inertias
    ``IA`` (N, 6, 6), ``U = IA S`` (M, 6), ``d = S'U`` (M,) and the roots' Cholesky factors
    ``chol`` (C, 6, 6). A free joint passes ``Xup' (IA - U U'/d) Xup`` to its parent, a locked one its
    whole ``Xup' IA Xup`` (Featherstone 2008, section 9.3)."""
    N, C = parent.shape[0], chol.shape[0]
    Ia = np.empty((6, 6))
    B = np.empty((3, 3))
    Y = np.empty((4, 3, 3))  # Ia Xup in 3 x 3 blocks: [[Y0, Y1], [Y2, Y3]]
    for i in range(N):
        for a in range(6):
            for b in range(6):
                IA[i, a, b] = 0.0
            IA[i, a, a] = inertia[i, a]
    for i in range(N - 1, C - 1, -1):  # children before their parents
        j, k = i - C, parent[i]
        dd = 0.0
        for a in range(6):
            acc = 0.0
            for b in range(6):
                acc += IA[i, a, b] * S[j, b]
            U[j, a] = acc
            dd += S[j, a] * acc
        d[j] = dd
        inv = 0.0 if lock[j] else 1.0 / dd  # a locked joint passes its whole IA
        for a in range(6):
            ua = U[j, a] * inv
            for b in range(6):
                Ia[a, b] = IA[i, a, b] - ua * U[j, b]
        # Xup = [[E, 0], [B, E]] with B = -E rx (rows of B are r x rows of E), so with Ia =
        # [[P, Q], [Q', D]]: Xup' Ia Xup = [[E'Y0 + B'Y2, E'Y1 + B'Y3], [., E'Y3]] (symmetric),
        # Y0 = P E + Q B, Y1 = Q E, Y2 = Q'E + D B, Y3 = D E
        for a in range(3):
            B[a, 0] = r[j, 1] * E[j, a, 2] - r[j, 2] * E[j, a, 1]
            B[a, 1] = r[j, 2] * E[j, a, 0] - r[j, 0] * E[j, a, 2]
            B[a, 2] = r[j, 0] * E[j, a, 1] - r[j, 1] * E[j, a, 0]
        for a in range(3):
            for b in range(3):
                y0 = y1 = y2 = y3 = 0.0
                for m in range(3):
                    e, bb = E[j, m, b], B[m, b]
                    y0 += Ia[a, m] * e + Ia[a, m + 3] * bb
                    y1 += Ia[a, m + 3] * e
                    y2 += Ia[m, a + 3] * e + Ia[a + 3, m + 3] * bb
                    y3 += Ia[a + 3, m + 3] * e
                Y[0, a, b], Y[1, a, b], Y[2, a, b], Y[3, a, b] = y0, y1, y2, y3
        for a in range(3):
            for b in range(3):
                top = right = 0.0
                for m in range(3):
                    e, bb = E[j, m, a], B[m, a]
                    top += e * Y[0, m, b] + bb * Y[2, m, b]
                    right += e * Y[1, m, b] + bb * Y[3, m, b]
                IA[k, a, b] += top
                IA[k, a, b + 3] += right
                IA[k, b + 3, a] += right
                if b >= a:  # E'Y3 is symmetric
                    low = E[j, 0, a] * Y[3, 0, b] + E[j, 1, a] * Y[3, 1, b] + E[j, 2, a] * Y[3, 2, b]
                    IA[k, a + 3, b + 3] += low
                    if b != a:
                        IA[k, b + 3, a + 3] += low
    for c in range(C):  # the roots' IA = L L'
        for a in range(6):
            for b in range(a + 1):
                acc = IA[c, a, b]
                for m in range(b):
                    acc -= chol[c, a, m] * chol[c, b, m]
                chol[c, a, b] = np.sqrt(acc) if a == b else acc / chol[c, b, b]
            for b in range(a + 1, 6):
                chol[c, a, b] = 0.0


@_jit
def _root_solve(L, b, x):  # pragma: no cover - compiled
    """``x = -(L L')^-1 b``."""
    y = np.empty(6)
    for a in range(6):
        acc = b[a]
        for m in range(a):
            acc -= L[a, m] * y[m]
        y[a] = acc / L[a, a]
    for a in range(5, -1, -1):
        acc = y[a]
        for m in range(a + 1, 6):
            acc -= L[m, a] * x[m]
        x[a] = acc / L[a, a]
    for a in range(6):
        x[a] = -x[a]


# ---------------------------------------------------------------- one stage


@_jit
def _velocities(parent, E, r, S, v0, qd, v, cJ):  # pragma: no cover - compiled
    """Body velocities ``v`` (N, 6) and joint bias accelerations ``cJ = v x (S qd)`` (M, 6)."""
    C = v0.shape[0]
    vJ = np.empty(6)
    for i in range(C):
        v[i] = v0[i]
    for i in range(C, parent.shape[0]):
        j = i - C
        _x_apply(E[j], r[j], v[parent[i]], v[i])
        for a in range(6):
            vJ[a] = S[j, a] * qd[j]
            v[i, a] += vJ[a]
        w0, w1, w2, u0, u1, u2 = v[i, 0], v[i, 1], v[i, 2], v[i, 3], v[i, 4], v[i, 5]
        cJ[j, 0] = w1 * vJ[2] - w2 * vJ[1]
        cJ[j, 1] = w2 * vJ[0] - w0 * vJ[2]
        cJ[j, 2] = w0 * vJ[1] - w1 * vJ[0]
        cJ[j, 3] = w1 * vJ[5] - w2 * vJ[4] + u1 * vJ[2] - u2 * vJ[1]
        cJ[j, 4] = w2 * vJ[3] - w0 * vJ[5] + u2 * vJ[0] - u0 * vJ[2]
        cJ[j, 5] = w0 * vJ[4] - w1 * vJ[3] + u0 * vJ[1] - u1 * vJ[0]


@_jit
def _wrench(a, b, xa, xb, n0, depth0, cap, k, c, R, p, v, f):  # pragma: no cover - compiled
    """Add the contact springs' body-frame wrenches to ``f`` (N, 6)
    (:meth:`~coursekit.creatures.physics.contact.Contacts.wrench`, pair by pair)."""
    Xa, Xb, nw, va, vb, F = np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for i in range(a.shape[0]):
        A, B = a[i], b[i]
        for m in range(3):
            Xa[m] = R[A, m, 0] * xa[i, 0] + R[A, m, 1] * xa[i, 1] + R[A, m, 2] * xa[i, 2] + p[A, m]
            Xb[m] = R[B, m, 0] * xb[i, 0] + R[B, m, 1] * xb[i, 1] + R[B, m, 2] * xb[i, 2] + p[B, m]
            nw[m] = R[A, m, 0] * n0[i, 0] + R[A, m, 1] * n0[i, 1] + R[A, m, 2] * n0[i, 2]
        depth = depth0[i] + nw[0] * (Xa[0] - Xb[0]) + nw[1] * (Xa[1] - Xb[1]) + nw[2] * (Xa[2] - Xb[2])
        depth = min(depth, cap[i])
        # both boxes' velocities at B's point, in world coordinates
        e0, e1, e2 = Xb[0] - p[A, 0], Xb[1] - p[A, 1], Xb[2] - p[A, 2]
        s0 = R[A, 0, 0] * e0 + R[A, 1, 0] * e1 + R[A, 2, 0] * e2  # xb in A's frame
        s1 = R[A, 0, 1] * e0 + R[A, 1, 1] * e1 + R[A, 2, 1] * e2
        s2 = R[A, 0, 2] * e0 + R[A, 1, 2] * e1 + R[A, 2, 2] * e2
        l0 = v[A, 3] + v[A, 1] * s2 - v[A, 2] * s1
        l1 = v[A, 4] + v[A, 2] * s0 - v[A, 0] * s2
        l2 = v[A, 5] + v[A, 0] * s1 - v[A, 1] * s0
        m0 = v[B, 3] + v[B, 1] * xb[i, 2] - v[B, 2] * xb[i, 1]
        m1 = v[B, 4] + v[B, 2] * xb[i, 0] - v[B, 0] * xb[i, 2]
        m2 = v[B, 5] + v[B, 0] * xb[i, 1] - v[B, 1] * xb[i, 0]
        for m in range(3):
            va[m] = R[A, m, 0] * l0 + R[A, m, 1] * l1 + R[A, m, 2] * l2
            vb[m] = R[B, m, 0] * m0 + R[B, m, 1] * m1 + R[B, m, 2] * m2
        vn = (vb[0] - va[0]) * nw[0] + (vb[1] - va[1]) * nw[1] + (vb[2] - va[2]) * nw[2]
        mag = max(k[i] * depth - c[i] * vn, 0.0)
        for m in range(3):
            F[m] = mag * nw[m]
        for body, sign in ((B, 1.0), (A, -1.0)):  # B pushed along +n, A along -n, both through xb
            d0, d1, d2 = Xb[0] - p[body, 0], Xb[1] - p[body, 1], Xb[2] - p[body, 2]
            t0 = sign * (d1 * F[2] - d2 * F[1])
            t1 = sign * (d2 * F[0] - d0 * F[2])
            t2 = sign * (d0 * F[1] - d1 * F[0])
            for m in range(3):
                f[body, m] += R[body, 0, m] * t0 + R[body, 1, m] * t1 + R[body, 2, m] * t2
                f[body, m + 3] += sign * (R[body, 0, m] * F[0] + R[body, 1, m] * F[1] + R[body, 2, m] * F[2])


@_jit
def _sweeps(parent, E, r, S, inertia, damping, IA, U, d, chol, lock, ap, tau, v, cJ, f_ext, a0, qdd, need):  # pragma: no cover - compiled
    """The bias and acceleration sweeps of the hybrid ABA (:func:`~.aba.aba`), given the
    velocities ``v``, the joints' bias accelerations ``cJ`` and the external forces ``f_ext``:
    the roots' accelerations ``a0`` (C, 6), the joints' ``qdd`` (M,) and the forces the locked
    joints need ``need`` (M,) (``tau`` for the free ones)."""
    N, C = parent.shape[0], a0.shape[0]
    pA = np.empty((N, 6))
    u = np.empty(N)
    pa = np.empty(6)
    out = np.empty(6)
    a = np.empty((N, 6))
    for i in range(N):  # v x* I v + D v - f_ext
        w0, w1, w2, u0, u1, u2 = v[i, 0], v[i, 1], v[i, 2], v[i, 3], v[i, 4], v[i, 5]
        h0, h1, h2 = inertia[i, 0] * w0, inertia[i, 1] * w1, inertia[i, 2] * w2
        l0, l1, l2 = inertia[i, 3] * u0, inertia[i, 4] * u1, inertia[i, 5] * u2
        pA[i, 0] = w1 * h2 - w2 * h1 + u1 * l2 - u2 * l1 + damping[i, 0] * w0 - f_ext[i, 0]
        pA[i, 1] = w2 * h0 - w0 * h2 + u2 * l0 - u0 * l2 + damping[i, 1] * w1 - f_ext[i, 1]
        pA[i, 2] = w0 * h1 - w1 * h0 + u0 * l1 - u1 * l0 + damping[i, 2] * w2 - f_ext[i, 2]
        pA[i, 3] = w1 * l2 - w2 * l1 + damping[i, 3] * u0 - f_ext[i, 3]
        pA[i, 4] = w2 * l0 - w0 * l2 + damping[i, 4] * u1 - f_ext[i, 4]
        pA[i, 5] = w0 * l1 - w1 * l0 + damping[i, 5] * u2 - f_ext[i, 5]
    for i in range(N - 1, C - 1, -1):  # inwards: pa = pA + IA c + U (u - U'c) / d, or + U ap if locked
        j = i - C
        SpA, Uc = 0.0, 0.0
        for m in range(6):
            SpA += S[j, m] * pA[i, m]
            Uc += U[j, m] * cJ[j, m]
        u[i] = tau[j] - SpA
        gain = ap[j] if lock[j] else (u[i] - Uc) / d[j]
        for m in range(6):
            acc = pA[i, m] + U[j, m] * gain
            for b in range(6):
                acc += IA[i, m, b] * cJ[j, b]
            pa[m] = acc
        _xt_apply(E[j], r[j], pa, out)
        for m in range(6):
            pA[parent[i], m] += out[m]
    for c in range(C):
        _root_solve(chol[c], pA[c], a0[c])
        a[c] = a0[c]
    for i in range(C, N):  # outwards: a = Xup a_parent + c + S qdd
        j = i - C
        _x_apply(E[j], r[j], a[parent[i]], a[i])
        Ua = 0.0
        for m in range(6):
            a[i, m] += cJ[j, m]
            Ua += U[j, m] * a[i, m]
        if lock[j]:
            qdd[j] = ap[j]
            need[j] = tau[j] - u[i] + Ua + d[j] * ap[j]  # S'pA + U'(Xup a_parent + c) + d ap
        else:
            qdd[j] = (u[i] - Ua) / d[j]
            need[j] = tau[j]
        for m in range(6):
            a[i, m] += S[j, m] * qdd[j]


@_jit
def stage(parent, E, r, S, inertia, damping, IA, U, d, chol, lock, tau, R0, lin, omega, qd,
          contacts, a, b, xa, xb, n0, depth0, cap, k, c, lin_acc, ang_acc, qdd, need, a0):  # pragma: no cover - compiled
    """One evaluation of the dynamics for the integrator (:meth:`World._accel`): the roots'
    linear acceleration (world) ``lin_acc`` (C, 3) and angular acceleration (root frame)
    ``ang_acc`` (C, 3), the joints' ``qdd`` (M,) and the locked joints' forces ``need`` (M,).
    Locked joints keep their rates. With ``contacts`` the anchored contact springs ``a .. c``
    (:meth:`~coursekit.creatures.physics.contact.Contacts.begin`) push at the stage's poses.
    ``a0`` (C, 6): the roots' spatial accelerations (root coordinates), for the held contacts."""
    N, C, M = parent.shape[0], R0.shape[0], qd.shape[0]
    v0 = np.empty((C, 6))
    for i in range(C):  # (omega, R' lin): the root's velocity in its own frame
        for m in range(3):
            v0[i, m] = omega[i, m]
            v0[i, m + 3] = R0[i, 0, m] * lin[i, 0] + R0[i, 1, m] * lin[i, 1] + R0[i, 2, m] * lin[i, 2]
    v = np.empty((N, 6))
    cJ = np.empty((M, 6))
    _velocities(parent, E, r, S, v0, qd, v, cJ)
    f_ext = np.zeros((N, 6))
    if contacts:
        R = np.empty((N, 3, 3))
        p = np.empty((N, 3))
        _poses(parent, E, r, R0, np.zeros((C, 3)), R, p)  # positions relative to the roots: forces do not care
        _wrench(a, b, xa, xb, n0, depth0, cap, k, c, R, p, v, f_ext)
    _sweeps(parent, E, r, S, inertia, damping, IA, U, d, chol, lock, np.zeros(M), tau, v, cJ, f_ext, a0, qdd, need)
    for i in range(C):  # R (a0_lin + omega x v0_lin)
        w0, w1, w2 = v0[i, 0], v0[i, 1], v0[i, 2]
        x0 = a0[i, 3] + w1 * v0[i, 5] - w2 * v0[i, 4]
        x1 = a0[i, 4] + w2 * v0[i, 3] - w0 * v0[i, 5]
        x2 = a0[i, 5] + w0 * v0[i, 4] - w1 * v0[i, 3]
        for m in range(3):
            lin_acc[i, m] = R0[i, m, 0] * x0 + R0[i, m, 1] * x1 + R0[i, m, 2] * x2
            ang_acc[i, m] = a0[i, m]


@_jit
def impulse(parent, E, r, S, inertia, IA, U, d, chol, lock, change, wrench, dv0, dqd, force):  # pragma: no cover - compiled
    """:func:`~.aba.impulse`: the root's velocity change ``dv0`` (C, 6), the joints' ``dqd``
    (M,) and the locked joints' impulses ``force`` (M,; 0 for the free ones) when the locked
    joints' rates change by ``change`` from rest and the bodies take the impulses ``wrench`` (N, 6)."""
    N, M = parent.shape[0], change.shape[0]
    zero = np.zeros((N, 6))
    _sweeps(parent, E, r, S, inertia, zero, IA, U, d, chol, lock, change, np.zeros(M), zero, np.zeros((M, 6)),
            wrench, dv0, dqd, force)


# ---------------------------------------------------------------- contact detection


@_jit
def detect(a, b, reach2, half, R, p, pair, n, depth, x, margin):  # pragma: no cover - compiled
    """The candidate pairs ``a, b`` in contact at poses ``R, p`` (N, 3, 3), (N, 3):
    :meth:`~coursekit.creatures.physics.contact.Contacts.detect` pair by pair (bounding spheres,
    then the 15 separating axes). Writes the pairs in contact, in candidate order, to ``pair``,
    their unit normals from A to B to ``n``, their depths and contact points; returns how many.
    ``margin`` (P,): pairs closer than it count too (depth > -margin; zeros: touching pairs only)."""
    Rm, Am, t, over = np.empty((3, 3)), np.empty((3, 3)), np.empty(3), np.empty(15)
    d, nrm = np.empty(3), np.empty(3)
    found = 0
    for k in range(a.shape[0]):
        A, B = a[k], b[k]
        for c in range(3):
            d[c] = p[B, c] - p[A, c]
        reach = np.sqrt(reach2[k]) + margin[k]
        if d[0] * d[0] + d[1] * d[1] + d[2] * d[2] >= (reach2[k] if margin[k] == 0.0 else reach * reach):
            continue  # the bounding spheres do not overlap
        for i in range(3):
            t[i] = R[A, 0, i] * d[0] + R[A, 1, i] * d[1] + R[A, 2, i] * d[2]
            for j in range(3):
                Rm[i, j] = R[A, 0, i] * R[B, 0, j] + R[A, 1, i] * R[B, 1, j] + R[A, 2, i] * R[B, 2, j]
                Am[i, j] = abs(Rm[i, j])
        hA, hB = half[A], half[B]
        for i in range(3):
            over[i] = hA[i] + (Am[i, 0] * hB[0] + Am[i, 1] * hB[1] + Am[i, 2] * hB[2]) - abs(t[i])
            over[3 + i] = (Am[0, i] * hA[0] + Am[1, i] * hA[1] + Am[2, i] * hA[2]) + hB[i] - abs(Rm[0, i] * t[0] + Rm[1, i] * t[1] + Rm[2, i] * t[2])
        if min(over[0], over[1], over[2], over[3], over[4], over[5]) <= -margin[k]:
            continue  # a face axis separates them
        for i in range(3):
            i1, i2 = (i + 1) % 3, (i + 2) % 3
            for j in range(3):
                j1, j2 = (j + 1) % 3, (j + 2) % 3
                length = np.sqrt(max(1.0 - Rm[i, j] * Rm[i, j], 0.0))  # |A_i x B_j|
                if length > 1e-6:  # parallel edges: the face axes already decide
                    over[6 + 3 * i + j] = (hA[i1] * Am[i2, j] + hA[i2] * Am[i1, j] + hB[j1] * Am[i, j2] + hB[j2] * Am[i, j1]
                                           - abs(t[i2] * Rm[i1, j] - t[i1] * Rm[i2, j])) / length
                else:
                    over[6 + 3 * i + j] = np.inf
        lo = over[0]
        for m in range(1, 15):
            lo = min(lo, over[m])
        if lo <= -margin[k]:
            continue
        best = 0
        while over[best] > lo + TIE:  # the first axis of least overlap, ties within TIE included
            best += 1
        for c in range(3):  # the normal: A's axis, B's axis or their cross product
            if best < 3:
                nrm[c] = R[A, c, best]
            elif best < 6:
                nrm[c] = R[B, c, best - 3]
        if best >= 6:
            i, j = (best - 6) // 3, (best - 6) % 3
            nrm[0] = R[A, 1, i] * R[B, 2, j] - R[A, 2, i] * R[B, 1, j]
            nrm[1] = R[A, 2, i] * R[B, 0, j] - R[A, 0, i] * R[B, 2, j]
            nrm[2] = R[A, 0, i] * R[B, 1, j] - R[A, 1, i] * R[B, 0, j]
        size = np.sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2])
        flip = -1.0 if (nrm[0] * d[0] + nrm[1] * d[1] + nrm[2] * d[2]) / size < 0 else 1.0
        for c in range(3):
            nrm[c] = flip * nrm[c] / size
        for c in range(3):  # deepest vertices: of A along +n, of B along -n; the point halfway
            vA, vB = p[A, c], p[B, c]
            for i in range(3):
                sa = R[A, 0, i] * nrm[0] + R[A, 1, i] * nrm[1] + R[A, 2, i] * nrm[2]
                sb = R[B, 0, i] * nrm[0] + R[B, 1, i] * nrm[1] + R[B, 2, i] * nrm[2]
                vA += R[A, c, i] * hA[i] * (0.0 if abs(sa) < 1e-9 else np.sign(sa))  # a face or an edge: its centre
                vB -= R[B, c, i] * hB[i] * (0.0 if abs(sb) < 1e-9 else np.sign(sb))
            x[found, c] = 0.5 * (vA + vB)
            n[found, c] = nrm[c]
        pair[found], depth[found] = k, lo
        found += 1
    return found


@_jit
def _face_of(R, body, n0, n1, n2, sign):  # pragma: no cover - compiled
    """The face (0-5: -x, +x, -y, +y, -z, +z) of ``body`` whose outward normal is closest to ``sign n``."""
    best, value = 0, 0.0
    for k in range(3):
        dl = sign * (R[body, 0, k] * n0 + R[body, 1, k] * n1 + R[body, 2, k] * n2)
        if k == 0 or abs(dl) > abs(value):
            best, value = k, dl
    return 2 * best + (1 if value > 0 else 0)


@_jit
def anchors(a, b, held_pair, held_xa, held_xb, held_n, held_depth, pair, n, x, R, p,
            out_pair, out_xa, out_xb, out_n, out_depth, sensors):  # pragma: no cover - compiled
    """:meth:`~coursekit.creatures.physics.contact.Contacts.begin` after detection: the held
    contacts still touching keep their anchors, the pairs newly found in contact (``pair, n, x``)
    are anchored relaxed (depth 0), in that order; the faces touching are set in ``sensors``
    (N, 6). Returns how many contacts there are."""
    seen = np.zeros(a.shape[0], dtype=np.bool_)
    k = 0
    for i in range(held_pair.shape[0]):
        A, B = a[held_pair[i]], b[held_pair[i]]
        depth = held_depth[i]
        for m in range(3):
            nw = R[A, m, 0] * held_n[i, 0] + R[A, m, 1] * held_n[i, 1] + R[A, m, 2] * held_n[i, 2]
            xa = R[A, m, 0] * held_xa[i, 0] + R[A, m, 1] * held_xa[i, 1] + R[A, m, 2] * held_xa[i, 2] + p[A, m]
            xb = R[B, m, 0] * held_xb[i, 0] + R[B, m, 1] * held_xb[i, 1] + R[B, m, 2] * held_xb[i, 2] + p[B, m]
            depth += nw * (xa - xb)
        if depth > 0:
            out_pair[k], out_depth[k] = held_pair[i], held_depth[i]
            out_xa[k], out_xb[k], out_n[k] = held_xa[i], held_xb[i], held_n[i]
            seen[held_pair[i]] = True
            k += 1
    for j in range(pair.shape[0]):
        if seen[pair[j]]:
            continue
        A, B = a[pair[j]], b[pair[j]]
        for m in range(3):  # in the boxes' own frames: xa, xb from the point, n from A
            out_xa[k, m] = R[A, 0, m] * (x[j, 0] - p[A, 0]) + R[A, 1, m] * (x[j, 1] - p[A, 1]) + R[A, 2, m] * (x[j, 2] - p[A, 2])
            out_xb[k, m] = R[B, 0, m] * (x[j, 0] - p[B, 0]) + R[B, 1, m] * (x[j, 1] - p[B, 1]) + R[B, 2, m] * (x[j, 2] - p[B, 2])
            out_n[k, m] = R[A, 0, m] * n[j, 0] + R[A, 1, m] * n[j, 1] + R[A, 2, m] * n[j, 2]
        out_pair[k], out_depth[k] = pair[j], 0.0
        k += 1
    for i in range(k):
        A, B = a[out_pair[i]], b[out_pair[i]]
        n0 = R[A, 0, 0] * out_n[i, 0] + R[A, 0, 1] * out_n[i, 1] + R[A, 0, 2] * out_n[i, 2]
        n1 = R[A, 1, 0] * out_n[i, 0] + R[A, 1, 1] * out_n[i, 1] + R[A, 1, 2] * out_n[i, 2]
        n2 = R[A, 2, 0] * out_n[i, 0] + R[A, 2, 1] * out_n[i, 1] + R[A, 2, 2] * out_n[i, 2]
        sensors[B, _face_of(R, B, n0, n1, n2, -1.0)] = 1.0
        sensors[A, _face_of(R, A, n0, n1, n2, 1.0)] = 1.0
    return k


# ---------------------------------------------------------------- the brains' neurons


@_jit
def neurons(code, x, n_inputs, param, y_prev, s_prev, first, t, dt, limit, out, sums):  # pragma: no cover - compiled
    """:func:`~coursekit.creatures.neural.evaluate`, neuron by neuron: outputs ``out`` (N,) and
    input sums ``sums`` (N,) of neurons with function codes ``code`` (the order of
    :data:`~coursekit.creatures.neural.FUNCTION_NAMES`; the tests hold every one to ``evaluate``),
    weighted inputs ``x`` (N, 3); outputs clipped to ``limit``."""
    for i in range(code.shape[0]):
        n, p, f = n_inputs[i], param[i], code[i]
        x0, x1, x2 = x[i, 0], x[i, 1], x[i, 2]
        s = x0 + (x1 if n >= 2 else 0.0) + (x2 if n >= 3 else 0.0)
        sums[i] = s
        b = x1 if n >= 2 else (1.0 if f == 2 or f == 20 else 0.0)  # divide and memory default b to 1
        c = x2 if n >= 3 else (1.0 if f == 10 else 0.0)  # interpolate defaults c to 1
        if f == 0:  # sum
            y = s
        elif f == 1:  # product
            y = x0 * (x1 if n >= 2 else 1.0) * (x2 if n >= 3 else 1.0)
        elif f == 2:  # divide
            y = 0.0 if abs(b) < 1e-6 else x0 / b
        elif f == 3:  # sum_threshold
            y = 1.0 if s > p else -1.0
        elif f == 4:  # greater_than
            y = 1.0 if x0 > b else -1.0
        elif f == 5:  # sign_of
            y = np.sign(s)
        elif f == 6 or f == 7:  # min, max (a NaN input gives NaN, as numpy's)
            y = x0
            for k in range(1, n):
                v = x[i, k]
                if np.isnan(y) or np.isnan(v):
                    y = np.nan
                elif (v < y) if f == 6 else (v > y):
                    y = v
        elif f == 8:  # abs
            y = abs(s)
        elif f == 9:  # if
            y = b if x0 > 0 else c
        elif f == 10:  # interpolate
            w = 0.0 if x0 < 0.0 else (1.0 if x0 > 1.0 else x0)
            y = b + (c - b) * w
        elif f == 11:
            y = np.sin(s)
        elif f == 12:
            y = np.cos(s)
        elif f == 13:
            y = np.arctan(s)
        elif f == 14:  # log
            v = abs(s)
            y = np.log(1e-6 if v < 1e-6 else v)
        elif f == 15:  # expt
            y = np.exp(20.0 if s > 20.0 else s)
        elif f == 16:  # sigmoid
            y = 1.0 / (1.0 + np.exp(-s))
        elif f == 17:  # integrate
            y = y_prev[i] + dt * s
        elif f == 18:  # differentiate
            y = 0.0 if first else (s - s_prev[i]) / dt
        elif f == 19:  # smooth
            y = y_prev[i] + (1.0 - np.exp(-p * dt)) * (s - y_prev[i])
        elif f == 20:  # memory
            y = x0 if b > 0 else y_prev[i]
        elif f == 21:  # oscillate_wave
            y = np.sin(2.0 * np.pi * p * t + s)
        else:  # oscillate_saw
            y = 2.0 * np.mod(p * t + s / (2.0 * np.pi), 1.0) - 1.0
        if np.isnan(y):
            y = 0.0
        out[i] = -limit if y < -limit else (limit if y > limit else y)
