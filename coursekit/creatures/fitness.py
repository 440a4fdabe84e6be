"""Sims' swimming fitness (paper section 2.5; Sims 1994 section 5.1).

Sims rewards "the distance the centre of mass travels per unit time", uses "the maximum distance
from the initial centre of mass" so that circling does not pay, and weights "final-phase
velocities more heavily" so that a single initial push does not pay. He does not publish the
weights; ours are:

``fitness = DISTANCE_WEIGHT * max_t |c(t) - c(0)| / T  +  LATE_SPEED_WEIGHT * sum_k w_k s_k``

where the evaluation time ``T`` (after the settle phase) is cut into :data:`WINDOWS` equal
windows, ``s_k`` is the rate at which the distance from the initial centre of mass grows over window ``k``
(``(|c(t_k+1) - c(0)| - |c(t_k) - c(0)|) / window``; circling in place averages to about 0), and
the window weights grow linearly, ``w_k = k / sum(1..K)``, so the last window counts ``K`` times as
much as the first. A steady swimmer at speed ``v`` scores ``v``; a creature that coasts after one
push scores less than a steady swimmer covering the same distance. Fitness is clipped at 0;
diverged creatures score 0.
"""

from __future__ import annotations

import numpy as np

#: Weight of the maximum distance from the initial centre of mass, per unit time.
DISTANCE_WEIGHT = 0.5
#: Weight of the late-weighted window speed.
LATE_SPEED_WEIGHT = 0.5
#: Number of windows for the late-phase speed.
WINDOWS = 10


def window_weights(k: int = WINDOWS) -> np.ndarray:
    """Linearly increasing, normalised weights of the ``k`` windows (first to last)."""
    w = np.arange(1, k + 1, dtype=np.float64)
    return w / w.sum()


def swimming_fitness(com: np.ndarray, times: np.ndarray, diverged: np.ndarray | None = None) -> np.ndarray:
    """Fitness of every creature from its centre-of-mass trajectory.

    Args:
        com: (C, T, 3) centre of mass at ``times``.
        times: (T,) increasing sample times (the evaluation phase; ``T >= WINDOWS + 1``).
        diverged: optional (C,) flags; those creatures score 0.

    Returns:
        (C,) fitness (m/s), finite and >= 0.
    """
    com = np.asarray(com, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    if com.ndim != 3 or com.shape[2] != 3:
        raise ValueError(f"com: expected shape (C, T, 3), got {com.shape}")
    if times.shape != (com.shape[1],) or times.size < WINDOWS + 1 or np.any(np.diff(times) <= 0):
        raise ValueError(f"times: expected {com.shape[1]} increasing sample times (at least {WINDOWS + 1}), got shape {times.shape}")
    duration = times[-1] - times[0]
    start = com[:, :1]
    max_dist = np.max(np.linalg.norm(com - start, axis=2), axis=1) / duration
    edges = np.linspace(times[0], times[-1], WINDOWS + 1)
    at = np.stack([np.stack([np.interp(edges, times, com[c, :, k]) for k in range(3)], axis=1) for c in range(com.shape[0])])
    speeds = np.diff(np.linalg.norm(at - start, axis=2), axis=1) / np.diff(edges)
    late = np.sum(speeds * window_weights(), axis=1)  # row by row: a BLAS matrix-vector product rounds differently with the batch size
    fit = DISTANCE_WEIGHT * max_dist + LATE_SPEED_WEIGHT * late
    fit = np.where(np.isfinite(fit), np.maximum(fit, 0.0), 0.0)
    if diverged is not None:
        fit = np.where(np.asarray(diverged, dtype=bool), 0.0, fit)
    return fit
