"""Forward dynamics in MuJoCo's state layout: the validation interface (paper section 2.4).

Per creature, ``qpos = (root position (3), root quaternion w,x,y,z (4), joint coordinates)`` and
``qvel = (root linear velocity in world coordinates (3), root angular velocity in root coordinates
(3), joint rates)``, joints in BodyTree order -- exactly MuJoCo's layout for the model written by
:func:`coursekit.creatures.mjcf.to_mjcf`, so the two can be compared number for number.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike
from typing import Any

from . import backend as bk
from . import spatial as sp
from .aba import aba
from .model import Model
from .water import drag_matrix


def flatten_layout(x, sizes: np.ndarray, name: str):
    """``(flat, form)``: a list of per-creature vectors, a (C, n) array (equal sizes) or a flat
    concatenation as one flat float64 vector, and which of the three it was (for
    :func:`unflatten_layout`); ``sizes`` (C,) are the per-creature lengths."""
    C, total = len(sizes), int(sizes.sum())
    if isinstance(x, (list, tuple)):
        if len(x) != C:
            raise ValueError(f"{name}: expected {C} per-creature arrays, got {len(x)}")
        parts = [bk.to_numpy(xi).astype(np.float64).reshape(-1) for xi in x]
        for i, (p, n) in enumerate(zip(parts, sizes)):
            if p.size != n:
                raise ValueError(f"{name}[{i}]: expected length {n}, got {p.size}")
        return np.concatenate(parts), "list"
    a = bk.to_numpy(x).astype(np.float64)
    if a.ndim == 2 and a.shape[0] == C and np.all(sizes == a.shape[1]):
        return a.reshape(-1), "2d"
    if a.ndim == 1 and a.size == total:
        return a, "flat"
    raise ValueError(f"{name}: expected a list of {C} vectors, a ({C}, n) array or a flat array of length {total}, got shape {a.shape}")


def unflatten_layout(flat, sizes, form):
    """``flat`` back in the container ``form`` :func:`flatten_layout` found."""
    if form == "flat":
        return flat
    if form == "2d":
        return flat.reshape(len(sizes), -1)
    offs = np.r_[0, np.cumsum(sizes)]
    return [flat[offs[i] : offs[i + 1]] for i in range(len(sizes))]


def split_layout(model: Model, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, ...]:
    """Flat MuJoCo-layout qpos/qvel (numpy) -> internal arrays (numpy)."""
    oq = np.r_[0, np.cumsum(model.nq)[:-1]]
    ov = np.r_[0, np.cumsum(model.nv)[:-1]]
    pos = qpos[oq[:, None] + np.arange(3)]
    quat = qpos[oq[:, None] + 3 + np.arange(4)]
    lin = qvel[ov[:, None] + np.arange(3)]
    omega = qvel[ov[:, None] + 3 + np.arange(3)]
    jq = np.concatenate([qpos[o + 7 : o + 7 + n] for o, n in zip(oq, model.joints_per_creature)]) if model.n_joints else np.zeros(0)
    jv = np.concatenate([qvel[o + 6 : o + 6 + n] for o, n in zip(ov, model.joints_per_creature)]) if model.n_joints else np.zeros(0)
    q = np.empty(model.n_joints)
    qd = np.empty(model.n_joints)
    q[model.joint_order] = jq
    qd[model.joint_order] = jv
    return pos, quat, q, lin, omega, qd


def join_velocity_layout(model: Model, root_lin: ArrayLike, root_ang: ArrayLike, joint: ArrayLike) -> np.ndarray:
    """Internal root (C, 3) + (C, 3) and joint (M,) arrays (numpy) -> flat qvel-layout vector."""
    jl = joint[model.joint_order]
    offs = np.r_[0, np.cumsum(model.joints_per_creature)]
    return np.concatenate([np.r_[root_lin[i], root_ang[i], jl[offs[i] : offs[i + 1]]] for i in range(model.n_creatures)])


def forward_dynamics(creatures: Any, qpos: ArrayLike, qvel: ArrayLike, tau: ArrayLike | None = None, *,
                     drag: bool = False, backend: str = "numpy", drag_coefficient: float | None = None) -> Any:
    """Generalised accelerations ``qacc`` of a population, in MuJoCo's layout (module docstring).

    Args:
        creatures: a list of BodyTrees or creatures (or a packed ``Model``).
        qpos, qvel: per creature, as a list of vectors, a (C, n) array (equal sizes) or one flat
            concatenated vector.
        tau: generalised forces in the qvel layout (root: world force, root-frame torque; then
            joint forces), or joint forces only (one per joint); ``None`` for zero.
        drag: include the water drag of :mod:`~coursekit.creatures.physics.water`.
        backend: "numpy" or "torch".
        drag_coefficient: drag per unit area and normal speed (default
            :data:`~coursekit.creatures.physics.water.DRAG_COEFFICIENT`).

    Returns:
        ``qacc`` in the qvel layout and the same container form as ``qvel`` (numpy arrays).
    """
    model = creatures if isinstance(creatures, Model) else Model(creatures, backend=backend)
    xp = model.xp
    qp, _ = flatten_layout(qpos, model.nq, "qpos")
    qv, form = flatten_layout(qvel, model.nv, "qvel")
    pos, quat, q, lin, omega, qd = split_layout(model, qp, qv)
    nrm = np.linalg.norm(quat, axis=1)
    if np.any(np.abs(nrm - 1) > 1e-6):
        raise ValueError(f"qpos: root quaternions must be unit length, got norms {nrm.tolist()}")
    quat = quat / nrm[:, None]
    C, M = model.n_creatures, model.n_joints
    f_root = np.zeros((C, 6))
    jt = np.zeros(M)
    if tau is not None:
        nj = model.joints_per_creature
        try:
            t, _ = flatten_layout(tau, model.nv, "tau")
            _, _, _, F, T, jt = split_layout(model, np.zeros(int(model.nq.sum())), t)
            R = sp.quat_to_mat(np, quat)
            f_root = np.concatenate([T, np.einsum("cji,cj->ci", R, F)], axis=1)
        except ValueError:
            t, _ = flatten_layout(tau, nj, "tau")
            jt = np.empty(M)
            jt[model.joint_order] = t
    R0 = sp.quat_to_mat(np, quat)
    vb = np.einsum("cji,cj->ci", R0, lin)
    f = lambda a: bk.asarray(xp, a, device=model.device)  # noqa: E731
    f_ext = None
    if np.any(f_root):
        f_ext = xp.zeros((model.n_bodies, 6), dtype=xp.float64, device=model.device)
        f_ext[:C] = f(f_root)
    damping = drag_matrix(model, drag_coefficient) if drag else None
    a0, qdd, _ = aba(model, f(q), f(qd), f(np.concatenate([omega, vb], axis=1)), f(jt), f_ext=f_ext, damping=damping)
    a0, qdd = bk.to_numpy(a0), bk.to_numpy(qdd)
    lin_acc = np.einsum("cij,cj->ci", R0, a0[:, 3:] + np.cross(omega, vb))
    return unflatten_layout(join_velocity_layout(model, lin_acc, a0[:, :3], qdd), model.nv, form)
