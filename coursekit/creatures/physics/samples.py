"""Random body trees for tests, benchmarks and lessons (paper section 2.3 shapes, no genotype).

Builds valid :class:`~coursekit.creatures.body.BodyTree` objects directly -- boxes attached to
random faces of random earlier boxes with revolute and prismatic joints -- so the simulator can be
exercised without the genotype and expansion code.
"""

from __future__ import annotations

import numpy as np

from coursekit.creatures.body import FREE, PRISMATIC, REVOLUTE, BodyTree, effector_strength, rotation_about


def _random_rotation(rng: np.random.Generator, max_angle: float) -> np.ndarray:
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    return rotation_about(axis, rng.uniform(-max_angle, max_angle))


def _depth_first(parents: list[int]) -> np.ndarray:
    """Relabel a random tree (``parents[i-1] < i``) into depth-first pre-order; returns parents 1.."""
    B = len(parents) + 1
    children = [[] for _ in range(B)]
    for i, p in enumerate(parents, start=1):
        children[p].append(i)
    order, stack = [], [0]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    new = np.empty(B, dtype=np.int64)
    new[order] = np.arange(B)
    out = np.empty(B, dtype=np.int64)
    out[new[1:]] = new[np.asarray(parents, dtype=np.int64)]
    return out[1:]


def random_body_tree(
    rng: np.random.Generator,
    n_bodies: int | tuple[int, int] = (10, 20),
    *,
    prismatic_fraction: float = 0.2,
    size_range: tuple[float, float] = (0.05, 0.35),
    max_tilt: float = 0.6,
) -> BodyTree:
    """A random creature body.

    Args:
        rng: random generator.
        n_bodies: number of boxes, or an inclusive range ``(lo, hi)`` to draw it from.
        prismatic_fraction: probability that a joint is prismatic rather than revolute.
        size_range: range of the half extents (metres).
        max_tilt: largest angle (rad) of the random rotation between a child and its parent.

    Returns:
        A :class:`BodyTree` whose children hang off a face of their parent, anchors on that face.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected numpy.random.Generator, got {type(rng).__name__}")
    B = int(rng.integers(n_bodies[0], n_bodies[1] + 1)) if isinstance(n_bodies, tuple) else int(n_bodies)
    if B < 1:
        raise ValueError(f"n_bodies: must be >= 1, got {B}")
    half = rng.uniform(size_range[0], size_range[1], size=(B, 3))
    parent = np.full(B, -1)
    jtype = np.full(B, FREE)
    axis = np.zeros((B, 3))
    jpp = np.zeros((B, 3))
    jpc = np.zeros((B, 3))
    rot = np.tile(np.eye(3), (B, 1, 1))
    limits = np.zeros((B, 2))
    gain = np.zeros(B)
    parent[1:] = _depth_first([int(rng.integers(0, i)) for i in range(1, B)])
    for i in range(1, B):
        p = parent[i]
        face_axis, sign = int(rng.integers(0, 3)), rng.choice([-1.0, 1.0])
        anchor = rng.uniform(-0.8, 0.8, size=3) * half[p]
        anchor[face_axis] = sign * half[p, face_axis]
        jpp[i] = anchor
        R = _random_rotation(rng, max_tilt)
        rot[i] = R
        # child extends away from the face: its anchor lies on its own face facing the parent
        n_child = R.T @ (sign * np.eye(3)[face_axis])
        k = int(np.argmax(np.abs(n_child)))
        c = rng.uniform(-0.5, 0.5, size=3) * half[i]
        c[k] = -np.sign(n_child[k]) * half[i, k]
        jpc[i] = c
        a = rng.normal(size=3)
        axis[i] = a / np.linalg.norm(a)
        if rng.random() < prismatic_fraction:
            jtype[i] = PRISMATIC
            limits[i] = [-rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2)]
        else:
            jtype[i] = REVOLUTE
            limits[i] = [-rng.uniform(0.4, 1.5), rng.uniform(0.4, 1.5)]
        gain[i] = rng.choice([-1.0, 1.0]) * rng.uniform(0.5, 1.5)
    return BodyTree(parent, half, jtype, axis, jpp, jpc, rot, limits, gain, effector_strength(half, parent, jtype, axis, jpc, limits))


def random_state(rng: np.random.Generator, tree: BodyTree, *, speed: float = 1.0,
                 inside: float = 0.9) -> tuple[np.ndarray, np.ndarray]:
    """A random MuJoCo-layout ``(qpos, qvel)`` for ``tree`` with joints inside ``inside`` x limits."""
    nj = tree.n_joints
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    q = rng.uniform(tree.limits[1:, 0] * inside, tree.limits[1:, 1] * inside) if nj else np.zeros(0)
    qpos = np.concatenate([rng.normal(size=3), quat, q])
    qvel = speed * rng.normal(size=6 + nj)
    return qpos, qvel
