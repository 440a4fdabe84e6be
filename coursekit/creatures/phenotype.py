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

Multi-DOF joints: a part whose node's joint has ``k`` DOFs (:data:`~.morphology.JOINT_AXES`) is
preceded in the body tree by ``k - 1`` massless frames, one hinge each, about the axes of
:func:`~.morphology.joint_axes` (mirrored like a revolute axis) with the node's per-DOF limits
(:attr:`~.morphology.Node.dof_limits`); see :mod:`.body`. Each DOF gets the node's gain and its
part's strength, and one effector and one angle/velocity sensor pair in the brain.

Part cap: expansion stops creating parts once :data:`MAX_PARTS` (default 64) exist; later links
are dropped in pre-order and ``body.meta["truncated"]`` is set; :func:`~coursekit.creatures.simulate.simulate` scores such a body 0.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .body import MAX_HALF_EXTENT, MIN_HALF_EXTENT, PRISMATIC, REVOLUTE, BodyTree, effector_strength, rotation_about
from .brain import Brain, build_brain
from .morphology import joint_axes

if TYPE_CHECKING:
    from .genotype import Creature

MAX_PARTS = 64


@dataclass
class Phenotype:
    """An expanded creature: the body tree and its flat neural system."""

    body: BodyTree
    brain: Brain
    children: list  #: children[b]: body indices of part b's child parts, in relative-id order ([] for massless frames)


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
    if callable(getattr(creature, "validate", None)):  # a genotype may have been changed since it was built
        creature.validate()
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
    body, first = _body_tree(nodes, insts, [half_of(i) for i in insts], truncated)
    real = [int(f) + nodes[i.node].dof - 1 if k else 0 for k, (f, i) in enumerate(zip(first, insts))]  # part -> body
    B = body.n_bodies
    node_of = body.node_id.tolist()
    parent_of = [-1] * B
    kids: list[list[int]] = [[] for _ in range(B)]
    dof_bodies: list[list[int]] = [[] for _ in range(B)]
    for k, inst in enumerate(insts):
        b = real[k]
        parent_of[b] = real[inst.parent] if k else -1
        kids[b] = [real[c] for c in children[k]]
        dof_bodies[b] = list(range(int(first[k]), b + 1)) if k else [0]
    brain = build_brain(creature, node_of, parent_of, kids, dof_bodies, body.massless.tolist())
    return Phenotype(body, brain, kids)


def _body_tree(nodes, insts, halves, truncated) -> tuple[BodyTree, np.ndarray]:
    """The body tree of the part instances (pre-order); a part whose joint has ``k`` DOFs gets
    ``k - 1`` massless frames before it (:mod:`.body`). Also returns every part's first body."""
    first = np.zeros(len(insts), dtype=np.int64)
    B = 1
    for k in range(1, len(insts)):
        first[k] = B
        B += nodes[insts[k].node].dof
    real = first + np.array([nodes[i.node].dof - 1 for i in insts]) * (first > 0)
    parent = np.full(B, -1, dtype=np.int64)
    half = np.zeros((B, 3))
    jtype = np.zeros(B, dtype=np.int64)
    axis = np.zeros((B, 3))
    jpp = np.zeros((B, 3))
    jpc = np.zeros((B, 3))
    rot = np.tile(np.eye(3), (B, 1, 1))
    limits = np.zeros((B, 2))
    gain = np.zeros(B)
    massless = np.zeros(B, dtype=bool)
    node_id = np.zeros(B, dtype=np.int64)
    half[0] = halves[0]
    # for the effectors' strength, every DOF body stands for its part (the box it turns, the
    # part it is attached to)
    part_half = np.zeros((B, 3))
    part_parent = np.zeros(B, dtype=np.int64)
    part_half[0] = halves[0]
    for k in range(1, len(insts)):
        inst = insts[k]
        node = nodes[inst.node]
        F = inst.F
        det = float(np.prod(F))
        h = halves[k]
        chain = range(int(first[k]), int(real[k]) + 1)
        anchor_child = F * (np.asarray(node.joint_pos, dtype=np.float64) * h)
        for d, (b, a, lim) in enumerate(zip(chain, joint_axes(node), node.dof_limits)):
            parent[b] = real[inst.parent] if d == 0 else b - 1
            node_id[b] = inst.node
            if node.joint_type == "prismatic":
                jtype[b] = PRISMATIC
                axis[b] = F * a
                limits[b] = np.asarray(lim, dtype=np.float64) * np.sum(np.abs(a) * h)  # half-widths along the axis
            else:
                jtype[b] = REVOLUTE
                axis[b] = det * F * a
                limits[b] = lim
            axis[b] /= np.linalg.norm(axis[b])
            if d == 0:
                jpp[b] = inst.anchor
                rot[b] = inst.rot
            if b == real[k]:
                half[b] = h
                jpc[b] = anchor_child
            else:
                massless[b] = True
            gain[b] = abs(node.force) if det > 0 else node.force
            part_half[b] = h
            part_parent[b] = real[inst.parent]
    jpc_part = jpc.copy()
    for k in range(1, len(insts)):
        jpc_part[int(first[k]):int(real[k]) + 1] = jpc[int(real[k])]
    strength = effector_strength(part_half, np.where(np.arange(B) > 0, part_parent, -1), jtype, axis, jpc_part, limits)
    body = BodyTree(parent, half, jtype, axis, jpp, jpc, rot, limits, gain, strength, node_id=node_id,
                    meta={"truncated": truncated}, massless=massless)
    return body, first


def part_poses(body: BodyTree, q: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(B, 3, 3)`` and centres ``(B, 3)`` of every part, root at the origin.

    Args:
        body: the body tree.
        q: (B - 1,) joint coordinates (default zeros: the rest pose).
    """
    if not isinstance(body, BodyTree):
        raise TypeError(f"body: expected a BodyTree (creature.expand().body), got {type(body).__name__}")
    B = body.n_bodies
    if q is None:
        q = np.zeros(B - 1)
    else:
        try:
            q = np.asarray(q, dtype=np.float64).reshape(B - 1)
        except (TypeError, ValueError):
            raise ValueError(f"q: expected {B - 1} joint coordinates (one per joint), got {q!r:.60}") from None
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
