"""The body tree: the physical phenotype of one creature (paper section 2.3).

This is the contract between phenotype expansion (:mod:`coursekit.creatures.phenotype`, which
produces it), the simulator (:mod:`coursekit.creatures.physics`, which packs many of them into a
batch), the MuJoCo export (:mod:`coursekit.creatures.mjcf`) and rendering.

Conventions
-----------
A creature is a tree of ``B`` rigid boxes stored in pre-order: body 0 is the root and
``parent[i] < i`` for every other body. Every body frame sits at the box's centre of mass with its
axes along the box edges; ``half_extents[i]`` are the half side lengths along those axes.
Boxes have uniform density ``density`` (1.0 = neutrally buoyant in water of density 1), so
``mass = 8 * prod(half_extents) * density``.

The root is joined to the world by a free joint (6 DOF). Every other body ``i`` is joined to
``parent[i]`` by one 1-DOF joint of type ``joint_type[i]`` (:data:`REVOLUTE` or
:data:`PRISMATIC`) with coordinate ``q``:

- ``joint_pos_parent[i]``: the joint anchor in the parent's body frame;
- ``joint_pos_child[i]``: the same anchor in the child's body frame (the paper's "joint position
  relative to the node's centre of mass");
- ``joint_rot[i]``: proper rotation (det +1) taking child-frame vectors to the parent frame at
  ``q = 0``;
- ``joint_axis[i]``: unit joint axis in the child's body frame.

The child's pose in the parent frame as a function of ``q`` is, with ``Rot(a, q)`` the rotation
by angle ``q`` about unit axis ``a``::

    revolute:  R(q) = joint_rot @ Rot(joint_axis, q)
               t(q) = joint_pos_parent - R(q) @ joint_pos_child
    prismatic: R(q) = joint_rot
               t(q) = joint_pos_parent + joint_rot @ (q * joint_axis - joint_pos_child)

so that a point ``x`` in child coordinates is at ``R(q) @ x + t(q)`` in parent coordinates. In
MuJoCo MJCF terms the child ``<body>`` has ``pos = joint_pos_parent - joint_rot @
joint_pos_child`` and ``quat = joint_rot``, and its ``<joint>`` has ``pos = joint_pos_child`` and
``axis = joint_axis``.

``limits[i] = (lo, hi)`` bound ``q`` (radians or metres); ``lo < 0 < hi``. ``gain[i]`` is the
signed force coefficient applied to the effector's output (its sign makes a symmetric copy move
the same way or opposite), and ``strength[i] > 0`` is the largest joint force or torque the
effector can apply (proportional to the cross-sectional area of the parts it joins, Sims 1994).
Row 0 of every per-joint array belongs to the root's free joint and is ignored (zeros; identity
for ``joint_rot``).

Multi-DOF joints. A joint of ``k`` DOFs (a genotype's universal or spherical joint) is ``k``
hinges in series: ``k - 1`` *massless* bodies (``massless[i]``; half extents, mass and inertia
zero) sit at the joint anchor between the parent and the part, each with one hinge, and the part
itself carries the last. Massless bodies feel no water and touch nothing, are not drawn and are
not parts (:attr:`BodyTree.n_parts`); the articulated-body algorithm needs nothing special for
them, the part after them carrying the inertia. In MJCF the ``k`` hinges are ``k`` joints of the
part's one ``<body>`` (MuJoCo applies a body's joints in series, as here).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .extents import MAX_HALF_EXTENT, MIN_HALF_EXTENT  # noqa: F401 (the contract's size limits, read from here too)

FREE = 0
REVOLUTE = 1
PRISMATIC = 2
JOINT_TYPES = {FREE: "free", REVOLUTE: "revolute", PRISMATIC: "prismatic"}

#: Effector strength per square metre of cross-section (Sims 1994: strength grows with area while
#: mass grows with volume, so big creatures are not simply stronger); see :func:`effector_strength`.
STRENGTH_PER_AREA = 2.0

#: The fastest an effector can sweep its joint through the water, in joint ranges per second
#: (Hill's maximum shortening speed of a muscle); see :func:`effector_strength`.
SWEEPS_PER_SECOND = 8.0


def _depths(parent: np.ndarray) -> np.ndarray:
    """(B,) steps from the root along ``parent`` (pre-order: a parent comes before its children)."""
    d = np.zeros(len(parent), dtype=np.int64)
    for i in range(1, len(parent)):
        d[i] = d[parent[i]] + 1
    return d


@dataclass
class BodyTree:
    """A tree of rigid boxes joined by 1-DOF joints (multi-DOF: several, via massless frames); see the module docstring."""

    parent: np.ndarray  # (B,) int, -1 for the root
    half_extents: np.ndarray  # (B, 3)
    joint_type: np.ndarray  # (B,) int
    joint_axis: np.ndarray  # (B, 3)
    joint_pos_parent: np.ndarray  # (B, 3)
    joint_pos_child: np.ndarray  # (B, 3)
    joint_rot: np.ndarray  # (B, 3, 3)
    limits: np.ndarray  # (B, 2)
    gain: np.ndarray  # (B,)
    strength: np.ndarray  # (B,)
    density: float = 1.0
    node_id: np.ndarray | None = None  # (B,) genotype node each body was instantiated from
    meta: dict = field(default_factory=dict)
    massless: np.ndarray | None = None  # (B,) bool: an intermediate frame of a multi-DOF joint (default none)

    def __post_init__(self) -> None:
        B = len(self.parent)
        as_f = lambda a, shape: np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(shape))  # noqa: E731
        self.parent = np.asarray(self.parent, dtype=np.int64).reshape(B)
        self.joint_type = np.asarray(self.joint_type, dtype=np.int64).reshape(B)
        self.half_extents = as_f(self.half_extents, (B, 3))
        self.joint_axis = as_f(self.joint_axis, (B, 3))
        self.joint_pos_parent = as_f(self.joint_pos_parent, (B, 3))
        self.joint_pos_child = as_f(self.joint_pos_child, (B, 3))
        self.joint_rot = as_f(self.joint_rot, (B, 3, 3))
        self.limits = as_f(self.limits, (B, 2))
        self.gain = as_f(self.gain, (B,))
        self.strength = as_f(self.strength, (B,))
        if self.node_id is not None:
            self.node_id = np.asarray(self.node_id, dtype=np.int64).reshape(B)
        self.massless = np.zeros(B, dtype=bool) if self.massless is None else np.asarray(self.massless, dtype=bool).reshape(B)
        self.validate()

    @property
    def n_bodies(self) -> int:
        return len(self.parent)

    @property
    def n_joints(self) -> int:
        """Number of 1-DOF joints (every body but the root): the creature's joint DOFs."""
        return len(self.parent) - 1

    @property
    def n_parts(self) -> int:
        """Number of boxes (bodies that are not massless frames of multi-DOF joints)."""
        return int(len(self.parent) - np.count_nonzero(self.massless))

    def part_of(self) -> np.ndarray:
        """(B,) the part (box) every body belongs to: itself, or for a massless frame the part
        whose joint it is a DOF of (the first part below it)."""
        out = np.arange(self.n_bodies)
        for i in range(self.n_bodies - 1, 0, -1):
            if self.massless[i]:
                out[i] = out[i + 1]  # pre-order: a massless frame's one child comes next
        return out

    def part_parent(self) -> np.ndarray:
        """(B,) the nearest ancestor of every body that is a part (-1 for the root)."""
        out = self.parent.copy()
        for i in range(1, self.n_bodies):
            if self.massless[out[i]]:
                out[i] = out[out[i]]
        return out

    @property
    def mass(self) -> np.ndarray:
        """(B,) mass of every box (0 for massless frames)."""
        return np.where(self.massless, 0.0, 8.0 * np.prod(self.half_extents, axis=1) * self.density)

    @property
    def inertia(self) -> np.ndarray:
        """(B, 3) principal moments of inertia of every box about its centre of mass."""
        s = (2.0 * self.half_extents) ** 2
        m = self.mass[:, None]
        return m / 12.0 * np.stack([s[:, 1] + s[:, 2], s[:, 0] + s[:, 2], s[:, 0] + s[:, 1]], axis=1)

    @property
    def depth(self) -> np.ndarray:
        """(B,) depth of every body in the tree (root 0)."""
        return _depths(self.parent)

    @property
    def part_depth(self) -> np.ndarray:
        """(B,) depth of every body counted in parts (root 0; massless frames add none)."""
        return _depths(self.part_parent())

    def validate(self) -> None:
        """Raise ``ValueError`` naming the field when the tree breaks the conventions."""
        B = self.n_bodies
        if B < 1:
            raise ValueError("BodyTree.parent: a creature needs at least one body, got 0")
        if self.parent[0] != -1:
            raise ValueError(f"BodyTree.parent[0]: the root's parent must be -1, got {self.parent[0]}")
        idx = np.arange(B)
        bad = np.nonzero((self.parent[1:] < 0) | (self.parent[1:] >= idx[1:]))[0]
        if bad.size:
            i = int(bad[0]) + 1
            raise ValueError(f"BodyTree.parent[{i}]: must be in [0, {i}) (pre-order), got {self.parent[i]}")
        if self.joint_type[0] != FREE or np.any((self.joint_type[1:] != REVOLUTE) & (self.joint_type[1:] != PRISMATIC)):
            raise ValueError(
                f"BodyTree.joint_type: root must be FREE (0) and others REVOLUTE (1) or PRISMATIC (2), got {self.joint_type.tolist()}"
            )
        parts = self.half_extents[~self.massless]
        if np.any(parts < MIN_HALF_EXTENT - 1e-12) or not np.all(np.isfinite(parts)):
            i = int(np.flatnonzero(~self.massless)[np.argmin(np.where(np.isfinite(parts), parts, -1).min(axis=1))])
            raise ValueError(f"BodyTree.half_extents[{i}]: every half extent must be >= {MIN_HALF_EXTENT}, got {self.half_extents[i].tolist()}")
        if self.massless.any():
            i = int(np.argmax(self.massless))
            if self.massless[0]:
                raise ValueError("BodyTree.massless[0]: the root must be a part, not a massless frame")
            bad = np.flatnonzero(self.massless & (np.abs(self.half_extents).max(axis=1) > 0))
            if bad.size:
                raise ValueError(f"BodyTree.half_extents[{int(bad[0])}]: a massless frame has half extents 0, got {self.half_extents[int(bad[0])].tolist()}")
            for i in np.flatnonzero(self.massless):
                if i + 1 >= B or self.parent[i + 1] != i or np.count_nonzero(self.parent == i) != 1:
                    raise ValueError(f"BodyTree.massless[{int(i)}]: a massless frame needs exactly one child, the next body")
        if B > 1:
            n = np.linalg.norm(self.joint_axis[1:], axis=1)
            if np.any(np.abs(n - 1.0) > 1e-9):
                i = int(np.argmax(np.abs(n - 1.0))) + 1
                raise ValueError(f"BodyTree.joint_axis[{i}]: must be a unit vector, got {self.joint_axis[i].tolist()}")
            R = self.joint_rot[1:]
            err = np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3)).max(axis=(1, 2))
            det = np.linalg.det(R)
            if np.any(err > 1e-9) or np.any(det < 0):
                i = int(np.argmax(err + (det < 0))) + 1
                raise ValueError(f"BodyTree.joint_rot[{i}]: must be a proper rotation matrix")
            lo, hi = self.limits[1:, 0], self.limits[1:, 1]
            if np.any(~(lo < 0)) or np.any(~(hi > 0)):
                i = int(np.argmax(~(lo < 0) | ~(hi > 0))) + 1
                raise ValueError(f"BodyTree.limits[{i}]: need lo < 0 < hi, got {self.limits[i].tolist()}")
            if np.any(~(self.strength[1:] > 0)):
                i = int(np.argmax(~(self.strength[1:] > 0))) + 1
                raise ValueError(f"BodyTree.strength[{i}]: must be > 0, got {self.strength[i]}")
        if not (self.density > 0):
            raise ValueError(f"BodyTree.density: must be > 0, got {self.density}")


def effector_strength(half_extents, parent, joint_type, joint_axis, joint_pos_child, limits) -> np.ndarray:
    """(B,) largest force or torque of every joint's effector (0 for the root).

    Sims' law: :data:`STRENGTH_PER_AREA` times the smaller of the two joined parts' largest
    cross-sectional areas. Strength then grows with the square of a part's size while its drag
    about the joint grows with the fourth power and its inertia with the fifth, so a small part
    would sweep its joint ever faster: a 5 cm part 64 times faster than a 40 cm one, through its
    whole range within one 1/60 s step -- motion no fixed-step integrator resolves, and the
    "invisible flipper" exploit of the literature. Real muscles have a maximum shortening speed
    (Hill), and so do these effectors: the strength is capped at the force that sweeps the child
    part alone through still water at :data:`SWEEPS_PER_SECOND` joint ranges per second, i.e.
    ``c * SWEEPS_PER_SECOND * (hi - lo)`` with ``c`` the child box's drag about (revolute) or along
    (prismatic) its joint axis (:mod:`~coursekit.creatures.physics.water`, default coefficient).
    Large parts keep Sims' law; small ones are capped.
    """
    from .physics.water import DRAG_COEFFICIENT, drag_diagonal  # water's law, the box's drag

    h = np.asarray(half_extents, dtype=np.float64)
    parent = np.asarray(parent)
    area = 4.0 * np.max(np.stack([h[:, 1] * h[:, 2], h[:, 0] * h[:, 2], h[:, 0] * h[:, 1]], axis=1), axis=1)
    strength = np.zeros(len(h))
    if len(h) < 2:
        return strength
    D = drag_diagonal(h[1:], DRAG_COEFFICIENT)
    a = np.asarray(joint_axis, dtype=np.float64)[1:]
    lever = np.cross(a, np.asarray(joint_pos_child, dtype=np.float64)[1:])  # COM speed per unit joint rate
    revolute = np.asarray(joint_type)[1:] == REVOLUTE
    c = np.where(revolute, np.sum(D[:, :3] * a * a, axis=1) + np.sum(D[:, 3:] * lever * lever, axis=1), np.sum(D[:, 3:] * a * a, axis=1))
    lim = np.asarray(limits, dtype=np.float64)[1:]
    strength[1:] = np.minimum(STRENGTH_PER_AREA * np.minimum(area[1:], area[parent[1:]]), c * SWEEPS_PER_SECOND * (lim[:, 1] - lim[:, 0]))
    return strength


def rotation_about(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues' rotation: matrices ``(..., 3, 3)`` rotating by ``angle`` about unit ``axis``."""
    axis = np.asarray(axis, dtype=np.float64)
    angle = np.asarray(angle, dtype=np.float64)
    x, y, z = np.moveaxis(axis, -1, 0)
    c, s = np.cos(angle), np.sin(angle)
    C = 1.0 - c
    return np.stack(
        [
            np.stack([c + x * x * C, x * y * C - z * s, x * z * C + y * s], axis=-1),
            np.stack([y * x * C + z * s, c + y * y * C, y * z * C - x * s], axis=-1),
            np.stack([z * x * C - y * s, z * y * C + x * s, c + z * z * C], axis=-1),
        ],
        axis=-2,
    )
