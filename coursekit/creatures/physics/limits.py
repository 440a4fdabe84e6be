"""Joint mobility limits as stiff spring-dampers (paper section 2.3: "restoring spring forces").

Beyond a limit the joint feels ``tau = -k (q - limit) - b q'``; inside, nothing. The stiffness is
set per joint from a natural frequency ``w`` and the smaller of the child's and the parent's own
inertia about the joint (``m_eff = min(S' I_child S, S' I_parent S)``; taking the smaller one
keeps a light part between two heavy ones from getting stiff springs on both sides):
``k = m_eff w^2``, ``b = 2 zeta m_eff w``. The limit modes are then roughly no faster than ``w``
(not rigorously: several springs -- limits and contacts -- can act on one light part), so the
simulator keeps ``dt * w =`` :data:`STIFFNESS_PER_STEP` = 0.25, well below the RK4 stability bound
(about 2.8); the divergence guard catches what is left. (On 60 random genotype-expanded
creatures, 0.5 let 7 diverge within 3 s and 0.25 let 1.)
"""

from __future__ import annotations

import numpy as np

from . import backend as bk

#: Default ``dt * w`` of the joint-limit and contact springs.
STIFFNESS_PER_STEP = 0.25


def limit_gains(model, frequency: float, damping_ratio: float = 1.0):
    """Per-joint stiffness and damping ``(k, b)`` (backend arrays, (M,))."""
    if not (np.isfinite(frequency) and frequency > 0):
        raise ValueError(f"limit_frequency: must be a positive number (rad/s), got {frequency}")
    if not (np.isfinite(damping_ratio) and damping_ratio >= 0):
        raise ValueError(f"limit_damping_ratio: must be >= 0, got {damping_ratio}")
    m_eff = effective_inertia(model)
    k = m_eff * frequency**2
    b = 2.0 * damping_ratio * m_eff * frequency
    return bk.asarray(model.xp, k, device=model.device), bk.asarray(model.xp, b, device=model.device)


def effective_inertia(model) -> np.ndarray:
    """(M,) the smaller of the child's and the parent's own inertia about each joint (numpy)."""
    C = model.n_creatures
    S = model.S_np
    child = np.sum(S * S * model.inertia_diag_np[C:], axis=1)
    # the same joint motion expressed in the parent's frame at q = 0
    R = model.joint_rot_np
    a = np.einsum("mij,mj->mi", R, model.axis_np)
    Sp = np.where(model.joint_type_np[:, None] == 1, np.concatenate([a, np.cross(model.jpp_np, a)], axis=1), np.concatenate([np.zeros_like(a), a], axis=1))
    parent = np.sum(Sp * Sp * model.inertia_diag_np[model.parent[C:]], axis=1)
    return np.minimum(child, parent)


def limit_forces(xp, q, qd, lo, hi, k, b):
    """Spring-damper joint forces (M,) of joints beyond their limits ``lo``/``hi``."""
    zero = xp.zeros_like(q)
    pen = xp.where(q > hi, q - hi, xp.where(q < lo, q - lo, zero))
    return -k * pen - xp.where(pen != 0, b * qd, zero)


def limit_energy(xp, q, lo, hi, k):
    """Potential energy stored in the limit springs, per joint."""
    zero = xp.zeros_like(q)
    pen = xp.where(q > hi, q - hi, xp.where(q < lo, q - lo, zero))
    return 0.5 * k * pen * pen
