"""The articulated-body algorithm for one creature, as the book writes it (paper section 2.4).

This is Featherstone's ABA (*Rigid Body Dynamics Algorithms*, 2008, table 7.1, with the floating
base of section 9.5; spatial_v2's ``FDab`` and ``FDfb``), one body at a time in plain loops, in
the book's notation and without any of the batched simulator's tricks. It is the text to read
beside :mod:`~coursekit.creatures.physics.aba` (which computes the same numbers for a whole
population at once, and which the tests hold equal to this) and a second oracle next to MuJoCo. :func:`aba` is the algorithm on one creature in its body
coordinates; :func:`forward_dynamics` calls it creature by creature in MuJoCo's state layout, with
the signature of :func:`coursekit.creatures.physics.forward_dynamics`.

A creature is a tree of bodies in pre-order (``parent[i] < i``, body 0 the root). Every vector is
a spatial vector in the coordinates of its own body, whose frame sits at the body's centre of
mass: motions ``(omega, v)``, forces ``(moment, force)``. Three sweeps:

1. **Outwards, velocities.** Each joint ``i`` has its transform ``Xup[i]`` from the parent's
   coordinates into the child's and its motion subspace ``S[i]``
   (:func:`~coursekit.creatures.physics.jcalc.jcalc`); the joint's velocity is ``vJ = S qd``, so

       ``v[i] = Xup[i] v[parent] + vJ``,   ``c[i] = crm(v[i]) vJ``

   (``c`` is the velocity-product acceleration: what the joint's motion adds as the body turns).
   Every body starts with its own rigid inertia, ``IA[i] = I[i]``, and its bias force, the force
   it would need to keep moving as it does: ``pA[i] = crf(v[i]) I[i] v[i]``, plus the water's
   damping ``D v`` and less any external force.

2. **Inwards, articulated inertias.** From the leaves to the root, each body hands its parent
   what the parent feels through the joint -- its inertia and bias *less the part the joint lets
   go*: with ``U = IA S``, ``d = S' U`` and ``u = tau - S' pA``,

       ``Ia = IA - U U' / d``,   ``pa = pA + Ia c + U u / d``,
       ``IA[parent] += Xup' Ia Xup``,   ``pA[parent] += Xup' pa``.

3. **Outwards, accelerations.** The root floats: nothing holds it, so ``IA[0] a[0] + pA[0] = 0``
   gives ``a[0] = -IA[0]^-1 pA[0]``. Then for each joint

       ``a' = Xup a[parent] + c``,   ``qdd = (u - U' a') / d``,   ``a[i] = a' + S qdd``.

*Hybrid dynamics* (section 9.3; the joint limits): a *locked* joint moves with a prescribed
acceleration instead of its force. It then passes on its whole articulated inertia (``Ia = IA``,
``pa = pA + IA (c + S qdd)``), takes ``qdd`` as given in sweep 3, and the force it needs is what
its body transmits, ``tau = S' (IA a + pA)``.
"""

from __future__ import annotations

import numpy as np

from coursekit.creatures.body import BodyTree

from . import spatial as sp
from .dynamics import flatten_layout, unflatten_layout
from .jcalc import jcalc
from .model import Model, as_trees
from .water import DRAG_COEFFICIENT, drag_diagonal


def spatial_inertia(mass: float, inertia: np.ndarray) -> np.ndarray:
    """(6, 6) rigid-body inertia about the centre of mass, axes the principal axes:
    ``diag(Ixx, Iyy, Izz, m, m, m)``."""
    return np.diag(np.r_[inertia, mass, mass, mass])


def joint_model(tree: BodyTree, i: int, q: float):
    """``(Xup, S)`` of body ``i``'s joint at ``q``, in the child's (centre-of-mass) coordinates.

    ``Xup = Xc XJ(q) Xtree``: ``Xtree`` from the parent's frame to the joint frame at rest
    (origin at the anchor ``joint_pos_parent``, rotated by ``joint_rot``), the joint's own motion
    ``XJ(q)`` and ``Xc``, the shift from the anchor to the child's centre of mass; ``S = Xc S_J``.
    """
    Xtree = sp.transform_matrix(np, tree.joint_rot[i].T, tree.joint_pos_parent[i])
    Xc = sp.transform_matrix(np, np.eye(3), -tree.joint_pos_child[i])
    XJ, S_J = jcalc(int(tree.joint_type[i]), tree.joint_axis[i], q)
    return Xc @ XJ @ Xtree, Xc @ S_J


def aba(tree: BodyTree, q, qd, v0, tau, f_ext=None, damping=None, lock=None, prescribed=None):
    """Accelerations of one floating creature by the ABA, in body coordinates (module docstring).

    Args:
        tree: the creature's :class:`~coursekit.creatures.body.BodyTree`.
        q, qd, tau: (B - 1,) joint coordinates, rates and forces, joints in BodyTree order.
        v0: (6,) the root's spatial velocity ``(omega, v)`` in root coordinates.
        f_ext: optional (B, 6) external spatial force on every body, in its coordinates.
        damping: optional (B, 6) diagonal of every body's damping matrix ``D`` (force ``-D v``).
        lock, prescribed: optional (B - 1,) bool and accelerations: the locked joints move with
            the ``prescribed`` accelerations (0 if ``None``), whatever ``tau`` says.

    Returns:
        ``(a0, qdd, tau)``: the root's spatial acceleration (6,) in root coordinates, the joint
        accelerations (B - 1,) and the joint forces (B - 1,) -- the given ones, and for the
        locked joints the forces they need.
    """
    B, parent = tree.n_bodies, tree.parent
    q, qd, tau = (np.asarray(x, dtype=np.float64).reshape(B - 1) for x in (q, qd, tau))
    locked = np.zeros(B - 1, dtype=bool) if lock is None else np.asarray(lock, dtype=bool).reshape(B - 1)
    qdd_locked = np.zeros(B - 1) if prescribed is None else np.asarray(prescribed, dtype=np.float64).reshape(B - 1)
    I = [spatial_inertia(m, J) for m, J in zip(tree.mass, tree.inertia)]
    Xup, S, c = [None] * B, [None] * B, [np.zeros(6)] * B
    v, IA, pA = [np.asarray(v0, dtype=np.float64)] + [None] * (B - 1), [None] * B, [None] * B

    # 1. outwards: velocities, velocity-product accelerations, rigid inertias and bias forces
    for i in range(B):
        if i > 0:
            j = i - 1  # joint i joins body i to its parent
            Xup[i], S[i] = joint_model(tree, i, q[j])
            vJ = S[i] * qd[j]
            v[i] = Xup[i] @ v[parent[i]] + vJ
            c[i] = sp.crm(v[i]) @ vJ
        IA[i] = I[i].copy()
        pA[i] = sp.crf(v[i]) @ I[i] @ v[i]
        if damping is not None:
            pA[i] = pA[i] + damping[i] * v[i]  # the force -D v, moved to the bias side
        if f_ext is not None:
            pA[i] = pA[i] - f_ext[i]

    # 2. inwards: articulated inertias and bias forces
    U, d, u = [None] * B, np.zeros(B), np.zeros(B)
    for i in range(B - 1, 0, -1):
        j = i - 1
        U[i] = IA[i] @ S[i]
        d[i] = S[i] @ U[i]
        u[i] = tau[j] - S[i] @ pA[i]
        if locked[j]:  # the joint moves as prescribed: the parent feels the whole body
            Ia = IA[i]
            pa = pA[i] + IA[i] @ (c[i] + S[i] * qdd_locked[j])
        else:
            Ia = IA[i] - np.outer(U[i], U[i]) / d[i]
            pa = pA[i] + Ia @ c[i] + U[i] * u[i] / d[i]
        IA[parent[i]] = IA[parent[i]] + Xup[i].T @ Ia @ Xup[i]
        pA[parent[i]] = pA[parent[i]] + Xup[i].T @ pa

    # 3. outwards: accelerations, from the floating root
    a = [None] * B
    a[0] = -np.linalg.solve(IA[0], pA[0])
    qdd, force = np.zeros(B - 1), tau.copy()
    for i in range(1, B):
        j = i - 1
        a_prime = Xup[i] @ a[parent[i]] + c[i]
        qdd[j] = qdd_locked[j] if locked[j] else (u[i] - U[i] @ a_prime) / d[i]
        a[i] = a_prime + S[i] * qdd[j]
        if locked[j]:
            force[j] = S[i] @ (IA[i] @ a[i] + pA[i])  # what the joint transmits along S
    return a[0], qdd, force


def forward_dynamics(creatures, qpos, qvel, tau=None, *, drag=False, backend="numpy", drag_coefficient=None):
    """Generalised accelerations ``qacc`` in MuJoCo's layout, by :func:`aba`, creature by creature.

    The signature and layout of :func:`coursekit.creatures.physics.forward_dynamics`: per
    creature ``qpos = (root position, root quaternion w,x,y,z, joint coordinates)``, ``qvel =
    (root linear velocity in world coordinates, root angular velocity in root coordinates, joint
    rates)``; ``tau`` in the qvel layout (root: world force, root-frame torque) or joint forces
    only; ``drag`` adds the water of :mod:`~coursekit.creatures.physics.water`. Returns ``qacc``
    in the qvel layout and the same container form as ``qvel``. numpy only: ``backend`` must be
    ``"numpy"``.
    """
    if backend != "numpy":
        raise ValueError(f"backend: the textbook ABA runs on numpy only, got {backend!r}")
    trees = creatures.trees if isinstance(creatures, Model) else as_trees(creatures)
    nj = np.array([t.n_joints for t in trees])
    qp, _ = flatten_layout(qpos, 7 + nj, "qpos")
    qv, form = flatten_layout(qvel, 6 + nj, "qvel")
    if tau is None:
        tau, joint_only = np.zeros(int(nj.sum())), True
    else:
        try:
            tau, _ = flatten_layout(tau, 6 + nj, "tau")
            joint_only = False
        except ValueError:
            tau, _ = flatten_layout(tau, nj, "tau")
            joint_only = True
    k = DRAG_COEFFICIENT if drag_coefficient is None else float(drag_coefficient)
    oq, ov, ot = (np.r_[0, np.cumsum(n)] for n in (7 + nj, 6 + nj, nj if joint_only else 6 + nj))
    qacc = []
    for c, t in enumerate(trees):
        x, v, f = qp[oq[c] : oq[c + 1]], qv[ov[c] : ov[c + 1]], tau[ot[c] : ot[c + 1]]
        quat = x[3:7]
        if abs(np.linalg.norm(quat) - 1) > 1e-6:
            raise ValueError(f"qpos[{c}]: the root quaternion must be unit length, got norm {np.linalg.norm(quat)}")
        R0 = sp.quat_to_mat(np, quat / np.linalg.norm(quat))  # root -> world
        omega, vb = v[3:6], R0.T @ v[:3]  # the root's spatial velocity, in root coordinates
        f_ext = np.zeros((t.n_bodies, 6))
        if not joint_only:
            f_ext[0] = np.r_[f[3:6], R0.T @ f[:3]]  # MuJoCo's root force is in world coordinates
        joint_tau = f if joint_only else f[6:]
        damping = drag_diagonal(t.half_extents, k) if drag else None
        a0, qdd, _ = aba(t, x[7:], v[6:], np.r_[omega, vb], joint_tau, f_ext=f_ext, damping=damping)
        # the root's spatial acceleration -> the acceleration of its centre in world coordinates
        qacc.append(np.r_[R0 @ (a0[3:] + np.cross(omega, vb)), a0[:3], qdd])
    return unflatten_layout(np.concatenate(qacc), 6 + nj, form)
