"""Joint mobility limits as stiff spring-dampers (paper section 2.3: "restoring spring forces").

Beyond a limit the joint feels ``tau = -k (q - limit) - b q'``; inside, nothing. The stiffness is
set per joint from a natural frequency ``w`` and the child part's own inertia about the joint
(``m_eff = S' I_child S``, a lower bound of the joint's articulated inertia):
``k = m_eff w^2``, ``b = 2 zeta m_eff w``. Because ``m_eff`` is a lower bound, the real limit
modes are no faster than ``w``; choosing ``dt * w`` below the RK4 stability bound (about 2.8 on
both axes) keeps the limits stable at the chosen step. The bound is not rigorous -- a light part
between two heavy ones has faster modes -- so the simulator defaults to ``dt * w = 0.5``; the
divergence guard catches what is left.
"""

from __future__ import annotations

import numpy as np

from . import backend as bk


def limit_gains(model, frequency: float, damping_ratio: float = 1.0):
    """Per-joint stiffness and damping ``(k, b)`` (backend arrays, (M,))."""
    if not (np.isfinite(frequency) and frequency > 0):
        raise ValueError(f"limit_frequency: must be a positive number (rad/s), got {frequency}")
    if not (np.isfinite(damping_ratio) and damping_ratio >= 0):
        raise ValueError(f"limit_damping_ratio: must be >= 0, got {damping_ratio}")
    S = model.S_np
    m_eff = np.sum(S * S * model.inertia_diag_np[model.n_creatures :], axis=1)
    k = m_eff * frequency**2
    b = 2.0 * damping_ratio * m_eff * frequency
    return bk.asarray(model.xp, k, device=model.device), bk.asarray(model.xp, b, device=model.device)


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
