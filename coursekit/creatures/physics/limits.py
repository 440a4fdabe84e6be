"""Joint mobility limits as stiff spring-dampers (paper section 2.3: "restoring spring forces").

Beyond a limit the joint feels ``tau = -k (q - limit) - b q'``; inside, nothing. The gains come
from a natural frequency ``w`` and the joint's *effective inertia* ``m_eff`` in the free-floating
creature -- the inertia a force on that one coordinate meets when every other coordinate, the
root included, is free: ``m_eff = 1 / (M^-1)_jj`` with ``M`` the joint-space mass matrix, measured
at the rest pose with one unit-force probe per joint through the articulated-body algorithm.
``k = m_eff w^2`` and ``b = 2 zeta m_eff w`` then give each limit mode the rate ``w`` (spring)
and ``2 zeta w`` (damper), and the simulator keeps ``dt * w =`` :data:`STIFFNESS_PER_STEP` =
0.25, well inside the RK4/RKN stability interval (about 2.8).

The damper is explicit, and ``m_eff`` changes with the pose: a creature folded far from its
rest pose can meet a joint's force with an inertia tens of times smaller. The damping ratio is
therefore light, ``zeta =`` :data:`LIMIT_DAMPING_RATIO` = 0.2 (``dt * 2 zeta w = 0.1``): with
``zeta = 1`` a random 8-part creature thrown against its limits gained 67x its energy in 2 s
(its ``m_eff`` had dropped over 5x); at 0.2 the margin is 28x. The water does most of the
damping anyway. (An implicit damper -- ``dt * b`` added to the joint's articulated inertia as
armature -- removes the bound but breaks momentum conservation: armature carries momentum no
body has, and the exploit creature above drifted 4 cm in 5 s without water. Not adopted.)

Why not the part's own inertia: in a free-floating chain a light part between light neighbours
can be far lighter, along its joint, than either box alone suggests (the parent side recoils and
rotates). Gains from the parts' own inertias made the damper of such a joint explicit-unstable at
``dt = 1/60`` -- the limit *created* energy and momentum, and evolution found it within ten
generations (a 3-box creature of 41 g "swimming" 8.7 m/s with drag off). The probes measure what
the integrator actually sees; configuration changes within the limits move ``m_eff`` by small
factors, which the margin of 0.25 against 2.8 covers (the dissipation tests check it on random
creatures).
"""

from __future__ import annotations

import numpy as np

from . import backend as bk

#: Default ``dt * w`` of the joint-limit springs.
STIFFNESS_PER_STEP = 0.25
#: Default damping ratio ``zeta`` of the joint-limit dampers (see the module docstring).
LIMIT_DAMPING_RATIO = 0.2


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
    """(M,) effective inertia ``1 / (M^-1)_jj`` of every joint (internal order) at the rest pose (numpy).

    One articulated-body solve per joint rank: probe ``j`` applies a unit force to the ``j``-th
    joint of every creature at once (creatures are independent), from rest at ``q = 0``; the
    joint's own acceleration is ``(M^-1)_jj``.
    """
    from .aba import aba

    xp, C, M = model.xp, model.n_creatures, model.n_joints
    nj = np.asarray(model.joints_per_creature)
    first = np.r_[0, np.cumsum(nj)[:-1]]
    f = lambda a: bk.asarray(xp, a, device=model.device)  # noqa: E731
    zero_q, zero_v = f(np.zeros(M)), f(np.zeros((C, 6)))
    inv_diag = np.empty(M)
    for j in range(int(nj.max(initial=0))):
        rows = np.asarray(model.joint_order)[first[nj > j] + j]  # internal rows of every creature's j-th joint
        tau = np.zeros(M)
        tau[rows] = 1.0
        _, qdd, _ = aba(model, zero_q, zero_q, zero_v, f(tau))
        inv_diag[rows] = bk.to_numpy(qdd)[rows]
    if M and not np.all(inv_diag > 0):
        raise ValueError("effective_inertia: the joint-space mass matrix is not positive definite")
    return 1.0 / inv_diag


def limit_forces(xp, q, qd, lo, hi, k, b):
    """Spring-damper joint forces (M,) of joints beyond their limits ``lo``/``hi``."""
    pen = q - xp.minimum(xp.maximum(q, lo), hi)  # the penetration beyond the limit, 0 inside
    return -k * pen - xp.where(pen != 0, b * qd, xp.zeros_like(q))


def limit_energy(xp, q, lo, hi, k):
    """Potential energy stored in the limit springs, per joint."""
    pen = q - xp.minimum(xp.maximum(q, lo), hi)
    return 0.5 * k * pen * pen
