"""The step compiled with numba: one loop over the bodies instead of stacked arrays.

:class:`~coursekit.creatures.physics.world.World` runs it by default on the numpy backend
(``compiled=None``; ``compiled=False`` gives the numpy step). :func:`rkn` is a whole
Runge-Kutta-Nystrom step: each of its four stages (:func:`~.kernels.stage`) computes the joint transforms,
the body velocities, the contact springs' forces and Featherstone's articulated-body algorithm with
locked joints in one pass, then the held contacts' forces (:mod:`~.contact_kernels`). Once a step, the
contact detection and anchors (:meth:`Dynamics.begin`), the held contacts' slots and responses (:meth:`Dynamics.hold`),
the joint limits' impulses (:func:`~.kernels.impulse`), the projection's centres of mass, momenta
and inertias (:meth:`Dynamics.mass_properties`) and the poses (:meth:`Dynamics.poses_rows`) are
compiled too, and so are the brains' neurons (:class:`~coursekit.creatures.brain.BrainBatch`), the
limits' decisions (:func:`limits`), the guards (:func:`diverged`) and the roots' rotations, these
three with numpy's own arithmetic in numpy's order, bit for bit. What stays in numpy is the rest
of the glue: the sensors, and the small array operations that join the kernels.

It is the algorithm of :mod:`~coursekit.creatures.physics.aba` (hybrid dynamics, water damping,
contact wrenches) and :mod:`~coursekit.creatures.physics.integrate`, written body by body in the
book's terms, so the states agree with the numpy step to rounding (the tests hold them to 1e-10
over 100 steps, and every stage to the textbook ABA of
:mod:`~coursekit.creatures.physics.reference`), not bit for bit: a run with it is a different run
of the same physics. A creature's motion does not depend on its batch, bit for bit, as with numpy.

Why hand-written: the numpy step pays Python's and numpy's overhead on each of its thousands of
array operations a step, which dominates at a lesson's batch of one and at evolution's refinement
of three, and whole-array passes over memory at big batches (``benchmarks/NOTES.md``, "The
compiled step"). No library compiles this simulator's own data layout; numba compiles these loops
as they are.

The packed model's order makes the loops simple: every parent comes before its children (roots,
then inner bodies level by level, then leaves), so an outward sweep runs over the bodies in order
and an inward one in reverse. A joint transform ``Xup = [[E, 0], [-E rx, E]]`` is kept as ``E``
and ``r`` (from the model's fast forms, :func:`~coursekit.creatures.physics.jcalc.joint_basis`)
and applied as such.

numba compiles the kernels on their first call (10-20 s) and caches them beside this module
(in ``__pycache__``, or numba's user cache folder); where no folder is writable, each session
compiles them anew. The grader's sandbox is read-only: the grader compiles them once and gives
each notebook a copy (:mod:`coursekit.grading.warm`).
"""

from __future__ import annotations

import numpy as np

from . import kernels
from . import contact_kernels as ck
from .contact_kernels import hold
from .contact_forces import ITERATIONS, RATE
from .kernels import _jit, _poses, _velocities, available, impulse, inertias, stage, transforms

__all__ = ["Dynamics", "available", "mass_properties", "rkn"]


# ---------------------------------------------------------------- the Runge-Kutta-Nystrom step


@_jit
def _chart(theta, R0, R, dinv, coef):  # pragma: no cover - compiled
    """:func:`~.spatial.chart_maps` at one ``theta`` (3,): ``R = R0 exp(theta)``, ``dinv`` =
    ``dexp(theta)^-1`` and ``coef = (alpha, beta, dalpha, dbeta)``."""
    t0, t1, t2 = theta[0], theta[1], theta[2]
    p2 = t0 * t0 + t1 * t1 + t2 * t2
    p = np.sqrt(p2)
    p4 = p2 * p2
    if p < 1e-3:
        alpha = 0.5 - p2 / 24.0 + p4 / 720.0
        beta = 1.0 / 6.0 - p2 / 120.0 + p4 / 5040.0
        dalpha = -1.0 / 12.0 + p2 / 180.0 - p4 / 6720.0
        dbeta = -1.0 / 60.0 + p2 / 1260.0 - p4 / 60480.0
        gamma = 1.0 / 12.0 + p2 / 720.0 + p4 / 30240.0
    else:
        sn, cs = np.sin(p), np.cos(p)
        inv2 = 1.0 / (p * p)
        alpha = (1 - cs) * inv2
        beta = (p - sn) * inv2 / p
        dalpha = (p * sn - 2 * (1 - cs)) * inv2 * inv2
        dbeta = (3 * sn - p * cs - 2 * p) * inv2 * inv2 / p
        half = 0.5 * p
        gamma = (1 - half * np.cos(half) / np.sin(half)) * inv2
    coef[0], coef[1], coef[2], coef[3] = alpha, beta, dalpha, dbeta
    K = np.array([[0.0, -t2, t1], [t2, 0.0, -t0], [-t1, t0, 0.0]])
    ex = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            K2 = theta[a] * theta[b] - (p2 if a == b else 0.0)
            one = 1.0 if a == b else 0.0
            ex[a, b] = one + (1.0 - p2 * beta) * K[a, b] + alpha * K2
            dinv[a, b] = one + 0.5 * K[a, b] + gamma * K2
    for a in range(3):
        for b in range(3):
            R[a, b] = R0[a, 0] * ex[0, b] + R0[a, 1] * ex[1, b] + R0[a, 2] * ex[2, b]


@_jit
def _cross(a, b, out):  # pragma: no cover - compiled
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@_jit
def _quat_to_mat(q, R):  # pragma: no cover - compiled
    w, x, y, z = q[0], q[1], q[2], q[3]
    x2, y2, z2 = x + x, y + y, z + z
    xx, yy, zz, xy, xz, yz = x * x2, y * y2, z * z2, x * y2, x * z2, y * z2
    wx, wy, wz = w * x2, w * y2, w * z2
    R[0, 0], R[0, 1], R[0, 2] = 1 - (yy + zz), xy - wz, xz + wy
    R[1, 0], R[1, 1], R[1, 2] = xy + wz, 1 - (xx + zz), yz - wx
    R[2, 0], R[2, 1], R[2, 2] = xz - wy, yz + wx, 1 - (xx + yy)


@_jit
def _held_stage(parent, S, iterations, holds, E, r, IA, U, d, chol, lock, R, A_l, A_w, A_q, a0):  # pragma: no cover - compiled
    """Add the held contacts' forces (:func:`~.contact_kernels.hold`, through the stage's
    transforms ``E, r`` and inertias ``IA .. chol`` with ``lock``) to a stage's accelerations: the
    roots' world linear ``A_l`` (C, 3) (``R``: the roots' rotations), angular ``A_w`` (C, 3) and
    the joints' ``A_q`` (M,), from the roots' spatial accelerations ``a0``."""
    C, M = a0.shape[0], A_q.shape[0]
    da, dq = np.empty((C, 6)), np.empty(M)
    hold(parent, S, iterations, holds, E, r, IA, U, d, chol, lock, R, a0, A_q, da, dq)
    for i in range(C):
        for m in range(3):
            A_w[i, m] += da[i, m]
            A_l[i, m] += R[i, m, 0] * da[i, 3] + R[i, m, 1] * da[i, 4] + R[i, m, 2] * da[i, 5]
    for j in range(M):
        A_q[j] += dq[j]


@_jit
def rkn(P, revolute, parent, S, inertia, damping, lock, tau, held, E1, r1, IA1, U1, d1, chol1, pos, quat, q, lin, omega, qd, h,
        contacts, a, b, xa, xb, n0, depth0, cap, k, c, holding, holds, iterations,
        new_pos, new_quat, new_q, new_lin, new_omega, new_qd, need):  # pragma: no cover - compiled
    """One step of :func:`~.integrate.step` with the 4-stage Nystrom method, every stage a
    :func:`~.kernels.stage` in the chart ``R = R_n exp(theta)``. ``held``: the inertias ``E1 .. chol1`` are
    those of ``q`` already (else they are computed into them). ``need``: the locked joints' forces
    of the last stage. ``holding``: the contacts ``holds`` are held in every stage (:func:`_held_stage`)."""
    C, M, N = pos.shape[0], q.shape[0], parent.shape[0]
    if not held:
        transforms(P, revolute, q, E1, r1)
        inertias(parent, E1, r1, S, inertia, lock, IA1, U1, d1, chol1)
    E, r, IA, U, d, chol = np.empty((M, 3, 3)), np.empty((M, 3)), np.empty((N, 6, 6)), np.empty((M, 6)), np.empty(M), np.empty((C, 6, 6))
    R0, R = np.empty((C, 3, 3)), np.empty((C, 3, 3))
    for i in range(C):
        _quat_to_mat(quat[i], R0[i])
    # the stages' accelerations in chart coordinates: (C, 3) root, (C, 3) theta, (M,) joints
    A_l, A_w, A_q = np.empty((4, C, 3)), np.empty((4, C, 3)), np.empty((4, M))
    a0 = np.empty((C, 6))
    stage(parent, E1, r1, S, inertia, damping, IA1, U1, d1, chol1, lock, tau, R0, lin, omega, qd,
          contacts, a, b, xa, xb, n0, depth0, cap, k, c, A_l[0], A_w[0], A_q[0], need, a0)  # theta = 0: the chart is the identity
    if holding:
        _held_stage(parent, S, iterations, holds, E1, r1, IA1, U1, d1, chol1, lock, R0, A_l[0], A_w[0], A_q[0], a0)
    h2, hh8, hh2 = h / 2, h * h / 8, h * h / 2
    y_t, y_q = np.empty((C, 3)), np.empty(M)  # the root's position moves no force
    v_l, v_t, v_q = np.empty((C, 3)), np.empty((C, 3)), np.empty(M)
    om, wd, cr, t1, t2 = np.empty((C, 3)), np.empty((C, 3)), np.empty(3), np.empty(3), np.empty(3)
    dinv, coef = np.empty((C, 3, 3)), np.empty((C, 4))
    for s in range(1, 4):
        g = s - 1  # the stage whose acceleration moves this one: a1 for 2 and 3's positions, a3 for 4's
        if s != 2:  # stages 2 and 3 share positions, hence the chart and the inertias
            ky, kp, e = (h2, hh8, 0) if s == 1 else (h, hh2, 2)  # y + h/2 y' + h^2/8 a1, or y + h y' + h^2/2 a3
            for i in range(C):
                for m in range(3):
                    y_t[i, m] = ky * omega[i, m] + kp * A_w[e, i, m]
                _chart(y_t[i], R0[i], R[i], dinv[i], coef[i])
            for j in range(M):
                y_q[j] = q[j] + ky * qd[j] + kp * A_q[e, j]
            transforms(P, revolute, y_q, E, r)
            inertias(parent, E, r, S, inertia, lock, IA, U, d, chol)
        kv = h if s == 3 else h2
        for i in range(C):
            for m in range(3):
                v_l[i, m] = lin[i, m] + kv * A_l[g, i, m]
                v_t[i, m] = omega[i, m] + kv * A_w[g, i, m]
            # omega = dexp(theta) theta_d and the curvature (spatial.chart_rates_at)
            th, td = y_t[i], v_t[i]
            _cross(th, td, t1)
            _cross(th, t1, t2)
            al, be, dal, dbe = coef[i, 0], coef[i, 1], coef[i, 2], coef[i, 3]
            pdot = th[0] * td[0] + th[1] * td[1] + th[2] * td[2]
            n2 = td[0] * td[0] + td[1] * td[1] + td[2] * td[2]
            for m in range(3):
                om[i, m] = td[m] - al * t1[m] + be * t2[m]
            for m in range(3):
                cr[m] = (dbe * pdot) * t2[m] - (dal * pdot) * t1[m] + be * (th[m] * n2 - td[m] * pdot)
            for m in range(3):
                wd[i, m] = cr[m]  # kept until the stage's angular acceleration is known
        for j in range(M):
            v_q[j] = qd[j] + kv * A_q[g, j]
        stage(parent, E, r, S, inertia, damping, IA, U, d, chol, lock, tau, R, v_l, om, v_q,
              contacts, a, b, xa, xb, n0, depth0, cap, k, c, A_l[s], A_w[s], A_q[s], need, a0)
        if holding:
            _held_stage(parent, S, iterations, holds, E, r, IA, U, d, chol, lock, R, A_l[s], A_w[s], A_q[s], a0)
        for i in range(C):  # theta'' = dexp^-1 (omega' - curvature)
            for m in range(3):
                t1[m] = A_w[s, i, m] - wd[i, m]
            for m in range(3):
                A_w[s, i, m] = dinv[i, m, 0] * t1[0] + dinv[i, m, 1] * t1[1] + dinv[i, m, 2] * t1[2]
    h6, h3, hh6 = h / 6, h / 3, h * h / 6
    th = np.empty(3)
    td = np.empty(3)
    for i in range(C):
        for m in range(3):
            new_pos[i, m] = pos[i, m] + h * lin[i, m] + hh6 * (A_l[0, i, m] + A_l[1, i, m] + A_l[2, i, m])
            new_lin[i, m] = lin[i, m] + h6 * (A_l[0, i, m] + A_l[3, i, m]) + h3 * (A_l[1, i, m] + A_l[2, i, m])
            th[m] = h * omega[i, m] + hh6 * (A_w[0, i, m] + A_w[1, i, m] + A_w[2, i, m])
            td[m] = omega[i, m] + h6 * (A_w[0, i, m] + A_w[3, i, m]) + h3 * (A_w[1, i, m] + A_w[2, i, m])
        # the new orientation q_n exp(theta) (normalised, w >= 0) and its body rate dexp(theta) theta_d
        p2 = th[0] * th[0] + th[1] * th[1] + th[2] * th[2]
        phi = np.sqrt(p2)
        kq = 0.5 - p2 / 48.0 + p2 * p2 / 3840.0 if phi < 1e-4 else np.sin(0.5 * phi) / phi
        ew, ex, ey, ez = np.cos(0.5 * phi), kq * th[0], kq * th[1], kq * th[2]
        aw, ax, ay, az = quat[i, 0], quat[i, 1], quat[i, 2], quat[i, 3]
        w = aw * ew - (ax * ex + ay * ey + az * ez)
        x = aw * ex + ew * ax + (ay * ez - az * ey)
        y = aw * ey + ew * ay + (az * ex - ax * ez)
        z = aw * ez + ew * az + (ax * ey - ay * ex)
        norm = np.sqrt(w * w + x * x + y * y + z * z)
        sign = -1.0 if w / norm < 0 else 1.0
        new_quat[i, 0], new_quat[i, 1], new_quat[i, 2], new_quat[i, 3] = sign * w / norm, sign * x / norm, sign * y / norm, sign * z / norm
        _chart(th, R0[i], R[i], dinv[i], coef[i])
        _cross(th, td, t1)
        _cross(th, t1, t2)
        for m in range(3):
            new_omega[i, m] = td[m] - coef[i, 0] * t1[m] + coef[i, 1] * t2[m]
    for j in range(M):
        new_q[j] = q[j] + h * qd[j] + hh6 * (A_q[0, j] + A_q[1, j] + A_q[2, j])
        new_qd[j] = qd[j] + h6 * (A_q[0, j] + A_q[3, j]) + h3 * (A_q[1, j] + A_q[2, j])


# ---------------------------------------------------------------- what the limits' projection keeps


@_jit
def mass_properties(parent, E, r, S, inertia, creature, R0, p0, lin, omega, qd, com, h, Ic):  # pragma: no cover - compiled
    """Every creature's centre of mass ``com`` (C, 3), world linear momentum and angular momentum
    about the world origin ``h`` (C, 6), and rotational inertia about its centre of mass ``Ic``
    (C, 3, 3), at root poses ``R0, p0``, joints ``q`` (in ``E, r``) and the given rates."""
    N, C, M = parent.shape[0], R0.shape[0], qd.shape[0]
    R, p = np.empty((N, 3, 3)), np.empty((N, 3))
    _poses(parent, E, r, R0, p0, R, p)
    v0, v, cJ = np.empty((C, 6)), np.empty((N, 6)), np.empty((M, 6))
    for c in range(C):
        for m in range(3):
            v0[c, m] = omega[c, m]
            v0[c, m + 3] = R0[c, 0, m] * lin[c, 0] + R0[c, 1, m] * lin[c, 1] + R0[c, 2, m] * lin[c, 2]
    _velocities(parent, E, r, S, v0, qd, v, cJ)
    total = np.zeros(C)
    com[:] = 0.0
    h[:] = 0.0
    Ic[:] = 0.0
    P, L = np.empty(3), np.empty(3)
    for i in range(N):
        c, mass = creature[i], inertia[i, 3]
        total[c] += mass
        for a in range(3):
            com[c, a] += mass * p[i, a]
            P[a] = R[i, a, 0] * mass * v[i, 3] + R[i, a, 1] * mass * v[i, 4] + R[i, a, 2] * mass * v[i, 5]
            L[a] = R[i, a, 0] * inertia[i, 0] * v[i, 0] + R[i, a, 1] * inertia[i, 1] * v[i, 1] + R[i, a, 2] * inertia[i, 2] * v[i, 2]
        L[0] += p[i, 1] * P[2] - p[i, 2] * P[1]
        L[1] += p[i, 2] * P[0] - p[i, 0] * P[2]
        L[2] += p[i, 0] * P[1] - p[i, 1] * P[0]
        for a in range(3):
            h[c, a] += P[a]
            h[c, a + 3] += L[a]
    for c in range(C):
        for a in range(3):
            com[c, a] /= total[c]
    for i in range(N):  # R diag(I) R' + m (|d|^2 - d d'), d from the centre of mass (parallel axes)
        c, mass = creature[i], inertia[i, 3]
        d0, d1, d2 = p[i, 0] - com[c, 0], p[i, 1] - com[c, 1], p[i, 2] - com[c, 2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        for a in range(3):
            da = d0 if a == 0 else (d1 if a == 1 else d2)
            for b in range(3):
                db = d0 if b == 0 else (d1 if b == 1 else d2)
                acc = R[i, a, 0] * inertia[i, 0] * R[i, b, 0] + R[i, a, 1] * inertia[i, 1] * R[i, b, 1] + R[i, a, 2] * inertia[i, 2] * R[i, b, 2]
                Ic[c, a, b] += acc + mass * ((dd if a == b else 0.0) - da * db)


# ---------------------------------------------------------------- the glue around them, once a (sub-)step
# The same arithmetic as numpy's, in the same order, so the step is the numpy glue's bit for bit.


@_jit
def rotations(quat, R):  # pragma: no cover - compiled
    """``R[c]``: the rotation of the unit quaternion ``quat[c]`` (:func:`~.spatial.quat_to_mat`)."""
    for c in range(quat.shape[0]):
        _quat_to_mat(quat[c], R[c])


@_jit
def diverged(pos, quat, lin, omega, q, qd, joint_creature, vmax2, wmax2, qmax, bad):  # pragma: no cover - compiled
    """``bad[c]``: creature ``c``'s state is not finite, or past a speed cap (``World._guard``'s test)."""
    for c in range(pos.shape[0]):
        finite = np.isfinite(pos[c, 0]) and np.isfinite(pos[c, 1]) and np.isfinite(pos[c, 2])
        for a in range(4):
            finite = finite and np.isfinite(quat[c, a])
        v2 = lin[c, 0] * lin[c, 0] + lin[c, 1] * lin[c, 1] + lin[c, 2] * lin[c, 2]
        w2 = omega[c, 0] * omega[c, 0] + omega[c, 1] * omega[c, 1] + omega[c, 2] * omega[c, 2]
        bad[c] = not (finite and v2 <= vmax2 and w2 <= wmax2)
    for j in range(q.shape[0]):
        if not (np.isfinite(q[j]) and abs(qd[j]) <= qmax):
            bad[joint_creature[j]] = True


@_jit
def _maximum(a, b):  # pragma: no cover - compiled
    return a if (a >= b or a != a) else b  # numpy's maximum: a NaN wins


@_jit
def _minimum(a, b):  # pragma: no cover - compiled
    return a if (a <= b or a != a) else b


@_jit
def limits(q, qd, tau, h, lo, hi, mid, tol, push, lock, target, new_lock, up, new_target, beyond, at, rate):  # pragma: no cover - compiled
    """:meth:`~.limits.Limits.begin` (the locks, where the locked joints stand) and the rates
    :meth:`~.limits.Limits.rate` gives the joints there, joint by joint."""
    for j in range(q.shape[0]):
        ahead = q[j] + h * qd[j]
        toward = 1.0 if target[j] == hi[j] else -1.0
        held = lock[j] and (push[j] * toward <= 0 or tau[j] * toward > 0)
        beyond[j] = _maximum(_maximum(q[j] - hi[j], lo[j] - q[j]), 0.0)
        out = beyond[j] > tol[j]
        new_lock[j] = held or out or _maximum(ahead - hi[j], lo[j] - ahead) > tol[j]
        up[j] = (q[j] if (held or out) else ahead) > mid[j]
        new_target[j] = hi[j] if up[j] else lo[j]
        at[j] = new_target[j] if out else q[j]
        reach = (new_target[j] - at[j]) / h
        free = _minimum(qd[j], reach) if up[j] else _maximum(qd[j], reach)
        rate[j] = free if new_lock[j] else qd[j]


# ---------------------------------------------------------------- what the world calls


class Dynamics:
    """The compiled kernels bound to one packed numpy :class:`~.model.Model` (``World(compiled=True)``).

    :meth:`inertias` returns ``(E, r, IA, U, d, chol)``; :meth:`transforms` the joint
    transforms ``Xup`` of them as matrices, for the numpy code that reads them.
    """

    def __init__(self, model, damping=None):
        if not available():
            raise ImportError("compiled: the compiled step needs numba (a dependency of coursekit): pip install numba")
        m = self.model = model
        self.parent = np.ascontiguousarray(m.parent, dtype=np.int64)
        self.P = np.ascontiguousarray(np.transpose(m.pose_rows_basis, (2, 0, 1)))  # (M, 3, 12)
        self.revolute = np.ascontiguousarray(m.revolute)
        self.S = np.ascontiguousarray(m.S)
        self.inertia = np.ascontiguousarray(m.inertia_diag)
        self.damping = np.zeros_like(self.inertia) if damping is None else np.ascontiguousarray(damping)
        self.free = np.zeros(m.n_joints, dtype=bool)  # no joint locked (a world without limits)
        self.creature = np.ascontiguousarray(m.creature, dtype=np.int64)
        self.joint_creature = np.ascontiguousarray(m.joint_creature, dtype=np.int64)
        i, f = np.zeros(0, np.int64), np.zeros((0, 3))  # no contact held (rkn's arguments keep their types)
        self._none = (np.zeros((0, 3, 3)), f, np.zeros((0, 3, 3)), f, i, i, i, f, f, i, i, np.zeros((0, 0, 0)), np.zeros((0, 0)),
                      np.zeros((0, 0)), np.zeros((0, 0)), f, f)

    def inertias(self, q, lock=None):
        m = self.model
        M, N, C = m.n_joints, m.n_bodies, m.n_creatures
        E, r = np.empty((M, 3, 3)), np.empty((M, 3))
        transforms(self.P, self.revolute, np.ascontiguousarray(q), E, r)
        IA, U, d, chol = np.empty((N, 6, 6)), np.empty((M, 6)), np.empty(M), np.empty((C, 6, 6))
        inertias(self.parent, E, r, self.S, self.inertia, self.free if lock is None else lock, IA, U, d, chol)
        return E, r, IA, U, d, chol

    def poses_rows(self, R0, p0, q):
        """:func:`~.jcalc.poses_rows`: world rotations (3, 3, N) and positions (3, N), component-major."""
        m = self.model
        E, r = np.empty((m.n_joints, 3, 3)), np.empty((m.n_joints, 3))
        transforms(self.P, self.revolute, np.ascontiguousarray(q), E, r)
        R, p = np.empty((m.n_bodies, 3, 3)), np.empty((m.n_bodies, 3))
        _poses(self.parent, E, r, np.ascontiguousarray(R0), np.ascontiguousarray(p0), R, p)
        return np.ascontiguousarray(R.transpose(1, 2, 0)), np.ascontiguousarray(p.T)

    def mass_properties(self, R0, p0, q, lin, omega, qd):
        """``(com, h, Ic)`` of :func:`mass_properties` at this pose and these rates."""
        m = self.model
        C = m.n_creatures
        E, r = np.empty((m.n_joints, 3, 3)), np.empty((m.n_joints, 3))
        transforms(self.P, self.revolute, np.ascontiguousarray(q), E, r)
        com, h, Ic = np.empty((C, 3)), np.empty((C, 6)), np.empty((C, 3, 3))
        mass_properties(self.parent, E, r, self.S, self.inertia, self.creature, np.ascontiguousarray(R0),
                                np.ascontiguousarray(p0), np.ascontiguousarray(lin), np.ascontiguousarray(omega),
                                np.ascontiguousarray(qd), com, h, Ic)
        return com, h, Ic

    def begin(self, contacts):
        """``begin(R, p, held) -> (found, sensors)``: :meth:`~.contact.Contacts.begin`'s detection,
        anchors and face sensors for ``contacts``' candidate pairs, compiled (``found``: the
        contacts held for the step, as ``Contacts.held`` keeps them)."""
        a, b = np.ascontiguousarray(contacts.a, dtype=np.int64), np.ascontiguousarray(contacts.b, dtype=np.int64)
        reach2, half, P, N = np.ascontiguousarray(contacts.reach2), np.ascontiguousarray(contacts.half_extents), len(a), self.model.n_bodies
        touching = np.zeros(P)  # no margin: the springs push pairs in touch
        none = {"pair": np.zeros(0, np.int64), "xa": np.zeros((0, 3)), "xb": np.zeros((0, 3)), "n": np.zeros((0, 3)), "depth": np.zeros(0)}

        def begin(R, p, held):
            R, p = np.ascontiguousarray(R), np.ascontiguousarray(p)
            pair, n, depth, x = np.empty(P, np.int64), np.empty((P, 3)), np.empty(P), np.empty((P, 3))
            k = kernels.detect(a, b, reach2, half, R, p, pair, n, depth, x, touching)
            held = none if held is None else held
            out = {"pair": np.empty(P, np.int64), "xa": np.empty((P, 3)), "xb": np.empty((P, 3)), "n": np.empty((P, 3)), "depth": np.empty(P)}
            sensors = np.full((N, 6), -1.0)
            k = kernels.anchors(a, b, held["pair"], held["xa"], held["xb"], held["n"], held["depth"], pair[:k], n[:k], x[:k], R, p,
                                out["pair"], out["xa"], out["xb"], out["n"], out["depth"], sensors)
            return {key: v[:k] for key, v in out.items()}, sensors

        return begin

    def _pairs(self, active):
        if active is None:
            no, none = np.zeros(0, np.int64), np.zeros((0, 3))
            return (no, no, none, none, none, np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0))
        return tuple(active[key] for key in ("a", "b", "xa", "xb", "n", "depth", "cap", "k", "c"))

    def step(self, state, h, tau, lock, active, held=None, holds=None):
        """``(new state, need)``: one :func:`rkn` step from ``state``; ``held``: the
        :meth:`inertias` at ``state.q`` with this ``lock``, if known; ``holds``: the contacts
        held in every stage (:meth:`hold`), if any."""
        from .integrate import State

        m = self.model
        C, M, N = m.n_creatures, m.n_joints, m.n_bodies
        lock = self.free if lock is None else lock
        if held is None:
            held = (np.empty((M, 3, 3)), np.empty((M, 3)), np.empty((N, 6, 6)), np.empty((M, 6)), np.empty(M), np.empty((C, 6, 6)))
            known = False
        else:
            known = True
        new = State(np.empty((C, 3)), np.empty((C, 4)), np.empty(M), np.empty((C, 3)), np.empty((C, 3)), np.empty(M))
        need = np.empty(M)
        rkn(self.P, self.revolute, self.parent, self.S, self.inertia, self.damping, lock, tau, known, *held,
            state.pos, state.quat, state.q, state.lin, state.omega, state.qd, float(h), active is not None, *self._pairs(active),
            holds is not None, self._none if holds is None else holds, ITERATIONS,
            new.pos, new.quat, new.q, new.lin, new.omega, new.qd, need)
        return new, need

    def accel(self, held, R, qd, lin, omega, tau, lock, active, holds=None):
        """``(lin_acc, ang_acc, qdd, need)`` of :func:`stage` at a state whose :meth:`inertias` are
        ``held``, with the contacts ``holds`` held (:meth:`hold`), if any."""
        E, r, IA, U, d, chol = held
        C, M = self.model.n_creatures, self.model.n_joints
        out = np.empty((C, 3)), np.empty((C, 3)), np.empty(M), np.empty(M)
        a0 = np.empty((C, 6))
        lock = self.free if lock is None else lock
        R = np.ascontiguousarray(R)
        stage(self.parent, E, r, self.S, self.inertia, self.damping, IA, U, d, chol, lock, tau,
              R, lin, omega, qd, active is not None, *self._pairs(active), *out, a0)
        if holds is not None:
            _held_stage(self.parent, self.S, ITERATIONS, holds, E, r, IA, U, d, chol, lock, R,
                        out[0], out[1], out[2], a0)
        return out

    def rotations(self, quat):
        """(C, 3, 3) :func:`~.spatial.quat_to_mat` of the roots' ``quat``."""
        R = np.empty((quat.shape[0], 3, 3))
        rotations(np.ascontiguousarray(quat), R)
        return R

    def diverged(self, state, caps):
        """(C,) bool: the creatures whose ``state`` is not finite or past ``caps`` (vmax, wmax, qmax)."""
        vmax, wmax, qmax = caps
        bad = np.empty(self.model.n_creatures, dtype=bool)
        diverged(state.pos, state.quat, state.lin, state.omega, state.q, state.qd, self.joint_creature,
                 float(vmax) ** 2, float(wmax) ** 2, float(qmax), bad)
        return bad

    def limits(self, lim, q, qd, tau):
        """``(lock, at, rate)``: ``lim.begin(q, qd, tau)`` and ``lim.rate(at, qd)`` of a numpy
        :class:`~.limits.Limits`, whose ``lock``, ``up``, ``target`` and ``beyond`` it sets as those do."""
        M = q.shape[0]
        lock, up, target, beyond, at, rate = (np.empty(M, dtype=bool), np.empty(M, dtype=bool), np.empty(M), np.empty(M),
                                              np.empty(M), np.empty(M))
        limits(q, qd, tau, float(lim.h), lim.lo, lim.hi, lim.mid, lim.tol, lim.push, lim.lock, lim.target,
               lock, up, target, beyond, at, rate)
        lim.lock, lim.up, lim.target, lim.beyond = lock, up, target, beyond
        return lock, at, rate

    def hold(self, forces, R0, state, inertias, lock, h):
        """:meth:`~.contact_forces.ContactForces.hold` compiled: the pairs at ``state`` within their
        reach with their slots (:func:`~.contact_kernels.slots`), their Delassus matrices through
        the step's ``inertias`` and ``lock`` (:func:`~.contact_kernels.responses`), gap allowances
        and bounds, as :func:`~.contact_kernels.hold` reads them in every stage; or ``None``."""
        m, c = self.model, forces.contacts
        C, M, N, P = m.n_creatures, m.n_joints, m.n_bodies, c.n_pairs
        E, r, IA, U, d, chol = inertias
        lock = self.free if lock is None else lock
        R, p = np.empty((N, 3, 3)), np.empty((N, 3))
        _poses(self.parent, E, r, np.ascontiguousarray(R0), np.ascontiguousarray(state.pos), R, p)
        v0 = np.ascontiguousarray(np.concatenate([state.omega, np.einsum("cji,cj->ci", R0, state.lin)], axis=1))
        v = np.empty((N, 6))
        _velocities(self.parent, E, r, self.S, v0, np.ascontiguousarray(state.qd), v, np.empty((M, 6)))
        reach = np.ascontiguousarray(forces.reach(h, v))
        pair, n, depth, x = np.empty(P, np.int64), np.empty((P, 3)), np.empty(P), np.empty((P, 3))
        a, b = np.ascontiguousarray(c.a, dtype=np.int64), np.ascontiguousarray(c.b, dtype=np.int64)
        H = kernels.detect(a, b, np.ascontiguousarray(c.reach2), np.ascontiguousarray(c.half_extents), R, p, pair, n, depth, x, reach)
        if H == 0:
            return None
        pair, n, depth, x = pair[:H], n[:H], depth[:H], x[:H]
        a, b = a[pair], b[pair]
        vn = np.empty(H)
        ck.normal_speeds(R, p, v, a, b, n, x, vn)
        owner, slot, count = forces.owner[pair], np.empty(H, np.int64), np.zeros(C, np.int64)
        K = ck.slots(owner, depth - h * vn, forces.thin[pair], forces.cap, slot, count)  # the deepest at the step's end
        r0, rq, D = np.zeros((K, C, 6)), np.zeros((K, M)), np.zeros((C, K, K))
        ck.responses(self.parent, E, r, self.S, IA, U, d, chol, lock, self.creature, R, p, owner, a, b, n, x, slot, count, r0, rq, D)
        floor, bias, rate = np.zeros((C, K)), np.zeros((C, K)), np.zeros((C, K))
        ck.per_slot(owner, slot, forces.floor[pair], floor)
        ck.per_slot(owner, slot, (np.clip(-depth, 0.0, None) + vn * h) / h**2, bias)  # close at most the gap in a step
        ck.rates(rq, r0, self.joint_creature, rate)
        hi = np.where(rate > 0, RATE / (h * np.where(rate > 0, rate, 1.0)), np.inf)
        n_a = np.ascontiguousarray(np.einsum("hji,hj->hi", R[a], n))
        x_b = np.ascontiguousarray(np.einsum("hji,hj->hi", R[b], x - p[b]))
        return (E, r, R, p, owner, a, b, n, x, slot, count, D, floor, hi, bias, n_a, x_b)

    def impulse(self, held, lock, change, wrench=None, forces=False):
        """``(dv0, dqd)``, or ``(dv0, dqd, force)`` with ``forces``, of :func:`impulse` (``wrench``: the bodies' impulses, none if ``None``)."""
        E, r, IA, U, d, chol = held
        m = self.model
        dv0, dqd, force = np.empty((m.n_creatures, 6)), np.empty(m.n_joints), np.empty(m.n_joints)
        wrench = np.zeros((m.n_bodies, 6)) if wrench is None else np.ascontiguousarray(wrench)
        impulse(self.parent, E, r, self.S, self.inertia, IA, U, d, chol, self.free if lock is None else lock,
                np.ascontiguousarray(change), wrench, dv0, dqd, force)
        return (dv0, dqd, force) if forces else (dv0, dqd)
