"""Water: Sims' viscous drag on every face of every box (paper section 2.4, Sims 1994 section 4).

"For each exposed moving surface, a viscous force resists the normal component of its velocity,
proportional to its surface area and normal velocity magnitude." Here every one of the six faces
of every box feels, at every point ``x`` of the face, the force per area
``-k (n . v(x)) n`` with ``v(x) = v + omega x x`` the local velocity. Integrating over the face
*exactly* (not only at its centre) gives, for a box of half extents ``(a, b, c)``, a constant
diagonal damping matrix in body coordinates, ``f = -D v`` with::

    linear:  D_vx = 2 k A_x,  A_x = 4 b c        (both x faces; likewise y, z)
    angular: D_wx = (2 k / 3) (A_y c^2 + A_z b^2)  (the rotational term across the y and z faces)

The rotational term is included: a face spinning about an in-plane axis sweeps water with one
half and is resisted by both halves. Faces covered by a neighbouring part are not removed (parts
overlap only near their joints). Both faces of a pair are counted, so the drag is symmetric and
``v . D v >= 0``: drag never adds energy.

Stiffness: drag relaxes body ``b``'s velocity at rates up to ``lambda_b = max(D_b / I_b)`` and the
whole articulated system's rates are bounded by ``max_b lambda_b`` (a Rayleigh-quotient argument:
``v'Dv <= max_b lambda_b v'Mv``). For a box that is ``k / h_min`` at most (``h_min`` the smallest
half extent). The simulator bounds the step rather than treating drag implicitly: it sub-steps so
that ``dt * lambda_max <= STABLE_DRAG_STEP``, well inside the RK4/RKN stability interval
(``2.785``). With :data:`~coursekit.creatures.extents.MIN_HALF_EXTENT` = 0.025 m and the default
``k = 2`` this is ``lambda <= 80 /s``, so ``dt = 1/60 s`` needs no sub-steps.

Plug-in point: every function here takes an optional ``box_drag(half_extents, k) -> (6,)``, a
per-box version of :func:`drag_diagonal` (exercise 07 has students write one); the simulator then
uses it for every box instead of the library's closed form (``World(..., drag=box_drag)``).
"""

from __future__ import annotations

import numpy as np

from coursekit.creatures.extents import MIN_HALF_EXTENT

from . import backend as bk

#: Default drag coefficient ``k``: force per unit area per unit normal speed (N s / m^3).
DRAG_COEFFICIENT = 2.0
#: Largest ``dt * lambda_max`` the simulator allows before sub-stepping.
STABLE_DRAG_STEP = 1.5


def drag_diagonal(half_extents: np.ndarray, k: float) -> np.ndarray:
    """(B, 6) diagonal ``(D_wx, D_wy, D_wz, D_vx, D_vy, D_vz)`` of the body-frame drag matrix."""
    if not (np.isfinite(k) and k >= 0):
        raise ValueError(f"drag_coefficient: must be finite and >= 0, got {k}")
    h = np.asarray(half_extents, dtype=np.float64)
    a, b, c = h[:, 0], h[:, 1], h[:, 2]
    Ax, Ay, Az = 4 * b * c, 4 * a * c, 4 * a * b
    lin = 2 * k * np.stack([Ax, Ay, Az], axis=1)
    ang = (2 * k / 3) * np.stack([Ay * c**2 + Az * b**2, Ax * c**2 + Az * a**2, Ax * b**2 + Ay * a**2], axis=1)
    return np.concatenate([ang, lin], axis=1)


def body_drag(half_extents: np.ndarray, k: float, box_drag=None) -> np.ndarray:
    """(B, 6) drag diagonals from the library's closed form or from a per-box function.

    Args:
        half_extents: (B, 3) box half extents.
        k: drag coefficient.
        box_drag: optional ``box_drag(half_extents (3,), k) -> (6,)``, called once per box on a
            copy of its half extents; its results must be finite and >= 0. Rows of half extents
            0 (massless frames of multi-DOF joints) have no drag and are not passed to it.
    Returns:
        (B, 6) float64 array ``(D_wx, D_wy, D_wz, D_vx, D_vy, D_vz)`` per box.
    """
    if box_drag is None:
        return drag_diagonal(half_extents, k)
    if not callable(box_drag):
        raise TypeError(f"drag: must be True, False or a function box_drag(half_extents, k), got {type(box_drag).__name__}")
    if not (np.isfinite(k) and k >= 0):
        raise ValueError(f"drag_coefficient: must be finite and >= 0, got {k}")
    h = np.asarray(half_extents, dtype=np.float64)
    out = np.zeros((len(h), 6))
    for i, hb in enumerate(h):
        if not hb.any():
            continue  # a massless frame of a multi-DOF joint: no faces, no water
        d = np.asarray(box_drag(hb.copy(), float(k)), dtype=np.float64)
        if d.shape != (6,) or not np.all(np.isfinite(d)) or np.any(d < 0):
            raise ValueError(f"drag: {getattr(box_drag, '__name__', 'box_drag')}({hb.tolist()}, {k}) returned {d.tolist()}; "
                             "expected 6 finite numbers >= 0 (D_wx, D_wy, D_wz, D_vx, D_vy, D_vz)")
        out[i] = d
    return out


def _coefficient(k) -> float:
    """``k`` as a float, or a TypeError naming ``drag_coefficient`` (its range is checked by the drag)."""
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, float, np.integer, np.floating)):
        raise TypeError(f"drag_coefficient: must be a number >= 0, got {k!r}")
    return float(k)


def drag_matrix(model, k: float | None = None, box_drag=None):
    """The (N, 6) drag diagonals of a packed model, on its backend (see :func:`body_drag`)."""
    k = DRAG_COEFFICIENT if k is None else _coefficient(k)
    return bk.asarray(model.xp, body_drag(model.half_extents_np, k, box_drag), device=model.device)


def max_drag_rate(model, k: float | None = None, box_drag=None) -> float:
    """Upper bound on the drag relaxation rate of the batch (1/s), which sets the sub-steps.

    With the library's drag it is the bound for *any* valid box, ``k / (density h_min)`` with
    ``h_min`` = :data:`~coursekit.creatures.extents.MIN_HALF_EXTENT` (the boxes' own rates are at
    most that), not the stiffest box present: a creature's step, and so its trajectory and
    fitness to the last bit, must not depend on which creatures share its batch. (Creatures of
    other densities than water's still share the batch's smallest density.) A student's
    ``box_drag`` that is stiffer than the law allows raises it to the rates of the boxes present.
    """
    k = DRAG_COEFFICIENT if k is None else float(k)
    bound = k / (min(float(t.density) for t in model.trees) * MIN_HALF_EXTENT)
    if box_drag is None:
        return bound
    parts = ~model.massless_np
    return max(bound, float(np.max(body_drag(model.half_extents_np[parts], k, box_drag) / model.inertia_diag_np[parts])))
