"""Phenotype expansion: every virtual node becomes a real part (paper section 2.3).

:func:`expand` walks the genotype graph from the root, depth first, and instantiates a part for
every link it meets. The children of one part instance, in order (this order is what a relative
id ``m`` counts, 1-based):

1. for every child link of the node (a ``terminal_only`` link only at a terminal instance): the
   child, then one mirrored copy per symmetry entry naming that child;
2. unless the instance is terminal: one copy of the node itself per recursion entry, scale
   multiplied by the entry's scale.

An instance is *terminal* when its recursion depth has reached the node's ``recursive_limit``
(or the node has no recursion entries).

Mirroring. Each instance carries a diagonal reflection ``F`` (its own frame): the physical part
is the genotype part reflected by ``F``. A link placed under a parent with reflection ``F_p``
and mirror ``M`` (the symmetry or reflect axis, else identity) gets ``G = M F_p``: anchor
``G (pos * h_parent)``; rotation ``G R F_c``, where ``F_c`` is the diagonal reflection with
``det F_c = det G`` closest to ``Rᵀ G R`` (exactly ``Rᵀ G R`` for the cube rotations), so the
rotation stays proper and — boxes being symmetric — the part is the exact mirror image. Joint
positions become ``F_c (joint_pos * h)``; a revolute axis is a pseudovector
(``det(F_c) F_c a``) and a prismatic axis a vector (``F_c a``), so the same joint coordinate
gives the mirror-image motion. The gain is ``|force|`` for unmirrored instances
(``det F = +1``) and ``force`` for mirrored ones: the sign of the force coefficient decides
whether symmetric parts move alike (mirror images) or opposite.

Sizes: an instance's half extents are ``size * scale`` clamped to ``[MIN_HALF_EXTENT,
MAX_HALF_EXTENT]``; prismatic limits are in units of the part's half-width along the joint axis. Strength follows Sims' law (∝ the joined parts'
cross-section), capped for small parts by a maximum sweep speed (:func:`body.effector_strength`).

Part cap: expansion stops creating parts once :data:`MAX_PARTS` (default 64) exist; later links
are dropped in pre-order and ``body.meta["truncated"]`` is set; :func:`~coursekit.creatures.simulate.simulate` scores such a body 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .body import MAX_HALF_EXTENT, MIN_HALF_EXTENT, PRISMATIC, REVOLUTE, BodyTree, effector_strength, rotation_about
from .brain import Brain, build_brain

if TYPE_CHECKING:
    from .genotype import Creature

MAX_PARTS = 64


@dataclass
class Phenotype:
    """An expanded creature: the body tree and its flat neural system."""

    body: BodyTree
    brain: Brain
    children: list  #: children[b]: part indices of part b's children, in relative-id order


@dataclass
class _Instance:
    node: int
    parent: int
    scale: float
    F: np.ndarray  # (3,) diagonal reflection, this part's frame
    depth: int  # recursion depth of this node's chain
    anchor: np.ndarray  # joint anchor in the parent's (physical) frame
    rot: np.ndarray  # child -> parent rotation


def _child_reflection(R: np.ndarray, G: np.ndarray) -> np.ndarray:
    """The diagonal reflection with det = det(G) closest to Rᵀ diag(G) R."""
    d = np.einsum("ji,j,ji->i", R, G, R)
    F = np.where(d < 0, -1.0, 1.0)
    if np.prod(F) != np.prod(G):
        k = int(np.argmin(np.abs(d)))
        F[k] = -F[k]
    return F


def _flip(axis: int) -> np.ndarray:
    f = np.ones(3)
    if axis >= 0:
        f[axis] = -1.0
    return f


def _place(inst_parent: _Instance, half_parent: np.ndarray, pos, rot, mirror: np.ndarray):
    G = inst_parent.F * mirror
    R = np.asarray(rot, dtype=np.float64)
    Fc = _child_reflection(R, G)
    anchor = G * (np.asarray(pos, dtype=np.float64) * half_parent)
    return anchor, (G[:, None] * R) * Fc[None, :], Fc


def expand(creature: Creature, max_parts: int = MAX_PARTS) -> Phenotype:
    """Instantiate every virtual node of ``creature`` (see the module docstring).

    Args:
        creature: a valid genotype: a :class:`~coursekit.creatures.genotype.Creature` (or
            anything holding its ``nodes`` and ``brain`` lists).
        max_parts: the part cap (>= 1).

    Returns:
        A :class:`Phenotype` whose ``body.node_id`` names the genotype node of every part.
    """
    if not (isinstance(getattr(creature, "nodes", None), list) and isinstance(getattr(creature, "brain", None), list)):
        raise TypeError(f"expand: expected a Creature, got {type(creature).__name__}")
    if not isinstance(max_parts, (int, np.integer)) or max_parts < 1:
        raise ValueError(f"expand.max_parts: must be an int >= 1, got {max_parts!r}")
    nodes = creature.nodes
    insts: list[_Instance] = []
    children: list[list[int]] = []
    truncated = False

    def half_of(inst: _Instance) -> np.ndarray:
        return np.clip(np.asarray(nodes[inst.node].size, dtype=np.float64) * inst.scale, MIN_HALF_EXTENT, MAX_HALF_EXTENT)

    def grow(inst: _Instance) -> None:
        nonlocal truncated
        b = len(insts)
        insts.append(inst)
        children.append([])
        node = nodes[inst.node]
        h = half_of(inst)
        terminal = inst.depth >= node.recursive_limit or not node.recursion
        todo = []
        for link in node.children:
            if link.terminal_only and not terminal:
                continue
            own = _flip(link.reflect)
            mirrors = [own] + [own * _flip(s.axis) for s in node.symmetry if s.child == link.child]
            for mir in mirrors:
                todo.append((link.child, link.pos, link.rot, link.scale, mir, 0))
        if not terminal:
            for r in node.recursion:
                todo.append((inst.node, r.pos, r.rot, r.scale, np.ones(3), inst.depth + 1))
        for child, pos, rot, scale, mir, depth in todo:
            if len(insts) >= max_parts:
                truncated = True
                return
            anchor, R, Fc = _place(inst, h, pos, rot, mir)
            children[b].append(len(insts))
            grow(_Instance(child, b, inst.scale * scale, Fc, depth, anchor, R))

    grow(_Instance(0, -1, 1.0, np.ones(3), 0, np.zeros(3), np.eye(3)))
    body = _body_tree(nodes, insts, [half_of(i) for i in insts], truncated)
    brain = build_brain(creature, [i.node for i in insts], [i.parent for i in insts], children)
    return Phenotype(body, brain, children)


def _body_tree(nodes, insts, halves, truncated) -> BodyTree:
    B = len(insts)
    parent = np.array([i.parent for i in insts], dtype=np.int64)
    half = np.array(halves)
    jtype = np.zeros(B, dtype=np.int64)
    axis = np.zeros((B, 3))
    jpp = np.zeros((B, 3))
    jpc = np.zeros((B, 3))
    rot = np.tile(np.eye(3), (B, 1, 1))
    limits = np.zeros((B, 2))
    gain = np.zeros(B)
    for b in range(1, B):
        inst = insts[b]
        node = nodes[inst.node]
        F = inst.F
        det = float(np.prod(F))
        a = np.asarray(node.joint_axis, dtype=np.float64)
        if node.joint_type == "revolute":
            jtype[b] = REVOLUTE
            axis[b] = det * F * a
            limits[b] = node.limits
        else:
            jtype[b] = PRISMATIC
            axis[b] = F * a
            limits[b] = np.asarray(node.limits, dtype=np.float64) * np.sum(np.abs(a) * half[b])  # half-widths along the axis
        axis[b] /= np.linalg.norm(axis[b])
        jpp[b] = inst.anchor
        jpc[b] = F * (np.asarray(node.joint_pos, dtype=np.float64) * half[b])
        rot[b] = inst.rot
        gain[b] = abs(node.force) if det > 0 else node.force
    strength = effector_strength(half, parent, jtype, axis, jpc, limits)
    return BodyTree(parent, half, jtype, axis, jpp, jpc, rot, limits, gain, strength,
                    node_id=np.array([i.node for i in insts], dtype=np.int64), meta={"truncated": truncated})


def part_poses(body: BodyTree, q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(B, 3, 3)`` and centres ``(B, 3)`` of every part, root at the origin.

    Args:
        body: the body tree.
        q: (B - 1,) joint coordinates (default zeros: the rest pose).
    """
    B = body.n_bodies
    q = np.zeros(B - 1) if q is None else np.asarray(q, dtype=np.float64).reshape(B - 1)
    Rw = np.zeros((B, 3, 3))
    tw = np.zeros((B, 3))
    Rw[0] = np.eye(3)
    for i in range(1, B):
        p = body.parent[i]
        if body.joint_type[i] == REVOLUTE:
            R = body.joint_rot[i] @ rotation_about(body.joint_axis[i], q[i - 1])
            t = body.joint_pos_parent[i] - R @ body.joint_pos_child[i]
        else:
            R = body.joint_rot[i]
            t = body.joint_pos_parent[i] + R @ (q[i - 1] * body.joint_axis[i] - body.joint_pos_child[i])
        Rw[i] = Rw[p] @ R
        tw[i] = Rw[p] @ t + tw[p]
    return Rw, tw
