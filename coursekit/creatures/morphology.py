"""The morphology graph of a genotype: nodes and their links (paper section 2.1.1).

A genotype (:class:`~coursekit.creatures.genotype.Creature`) is a list of :class:`Node` (node 0
is the root) plus a central brain. Nodes are never copied to express repetition; links are
attributes of a node, as in the paper's Haskell types:

- ``children = [ChildLink(child, pos, ...)]`` — the paper's ``[(id, pos)]``; beyond the paper (as
  Sims did) a link has an orientation ``rot``, a ``scale``, a ``terminal_only`` flag (the link
  applies only at the last instance of a recursion: tails, hands) and an optional ``reflect``
  axis (the child is a mirror image);
- ``recursion = [Recursion(pos, scale, rot)]`` — the node virtually copies itself to ``pos``,
  scaled, up to ``recursive_limit`` times along a chain;
- ``symmetry = [Symmetry(child, axis)]`` — every link to node ``child`` gets a second, mirrored
  element, reflected across the parent's plane ``axis = 0, 1, 2`` (x, y, z).

The child-link graph must be acyclic (repetition is the recursion attribute's job). A node also
describes the joint to its parent: ``joint_type`` (Sims' types, :data:`JOINT_AXES`: rotational
``"revolute"`` about ``joint_axis`` or translational ``"prismatic"`` along it, 1 DOF each;
``"twist"`` about the attachment axis; ``"universal"`` about two bend axes; ``"bend_twist"``,
``"twist_bend"`` and ``"spherical"`` with 2 and 3 DOF -- :func:`joint_axes` gives each DOF's
axis; :data:`JOINT_DOF` the counts), ``joint_pos`` (relative to the node's centre of
mass, in units of its half extents, so ``(-1, 0, 0)`` is the centre of its −x face),
``joint_axis`` (unit, node frame), ``limits`` (mobility of the first DOF, ``lo < 0 < hi``: radians for a rotational
joint; for a prismatic joint in units of the part's half-width along its axis, so a slide means
the same at every scale), ``extra_limits`` (one ``[lo, hi]`` per further DOF; ``dof_limits``
lists them all) and ``force`` (the signed force coefficient: a mirrored copy of the node
has gain ``force`` and the original ``|force|``, so a positive value moves symmetric parts as
mirror images — wings — and a negative one in opposition — legs).

Positions ``pos`` are in units of the parent's half extents (``[-1, 1]^3``; the surface where a
component is ±1); sizes are half extents within [``MIN_HALF_EXTENT``, ``MAX_HALF_EXTENT``]
(:mod:`.body`). This module holds the elements, their validation and JSON reading, and the walks
over the graph; random elements and the value lists they draw from are in :mod:`.generation`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .body import MAX_HALF_EXTENT, MIN_HALF_EXTENT
from .neural import MAX_JOINT_DOF, MAX_NEURONS, N_SENSORS, Input, Neuron, is_int, is_real, need_keys, validate_input, validate_neuron

__all__ = ["JOINT_AXES", "JOINT_DOF", "MAX_DOF", "ROTATIONAL_TYPES", "SPHERICAL_BEND_BOUND", "limit_bound", "joint_axes", "MAX_NODES", "MAX_CHILDREN", "MAX_RECURSION_ENTRIES", "MAX_RECURSIVE_LIMIT", "MAX_SYMMETRY",
           "MAX_FORCE", "SCALE_RANGE", "IDENTITY", "ChildLink", "Recursion", "Symmetry", "Node", "node_from_dict",
           "validate_node", "preorder", "renumber", "has_cycle"]

#: Joint types (Sims 1994's, but rigid) and the axis of each of their DOFs, in the order the DOFs
#: act (parent side first): ``"axis"`` the node's ``joint_axis`` (a slide for prismatic);
#: ``"twist"`` the attachment axis (the normal of the face the joint sits on, ``joint_pos``);
#: ``"bend"`` ``joint_axis`` made perpendicular to the twist axis; ``"bend2"`` perpendicular to
#: both. Adding a type is one row here (every per-DOF list -- limits, effectors, sensors, bodies,
#: MJCF joints -- is sized from it).
JOINT_AXES = {
    "revolute": ("axis",), "prismatic": ("axis",), "twist": ("twist",), "universal": ("bend", "bend2"),
    "bend_twist": ("bend", "twist"), "twist_bend": ("twist", "bend"), "spherical": ("twist", "bend", "bend2"),
}
#: Joint types and their degrees of freedom.
JOINT_DOF = {name: len(axes) for name, axes in JOINT_AXES.items()}
MAX_DOF = max(JOINT_DOF.values())
assert MAX_DOF <= MAX_JOINT_DOF, "neural.MAX_JOINT_DOF bounds the DOF sensor ids"
#: Every type but ``"prismatic"`` turns about its axes (limits in radians).
ROTATIONAL_TYPES = tuple(t for t in JOINT_AXES if t != "prismatic")
#: The largest ``|limit|`` of a spherical joint's middle (bend) DOF: three hinges in series lose a
#: DOF where the first and the last axes line up, at a bend of ±π/2 (gimbal lock: the joint
#: inertia becomes singular and a strong effector whips the part past any speed), so the bend
#: stays well short of it.
SPHERICAL_BEND_BOUND = 1.0


def limit_bound(joint_type: str, dof: int) -> float:
    """The largest ``|limit|`` DOF ``dof`` of a ``joint_type`` joint may have (radians, or half
    widths for a prismatic joint).

    >>> limit_bound("revolute", 0), limit_bound("spherical", 1)
    (3.141592653589793, 1.0)
    """
    if joint_type == "prismatic":
        return MAX_HALF_EXTENT
    return SPHERICAL_BEND_BOUND if joint_type == "spherical" and dof == 1 else math.pi

MAX_NODES = 24  #: genotype node cap (after garbage collection)
MAX_CHILDREN = 4  #: child links per node
MAX_RECURSION_ENTRIES = 2
MAX_RECURSIVE_LIMIT = 4
MAX_SYMMETRY = 3
MAX_FORCE = 2.0
SCALE_RANGE = (0.5, 1.5)
#: A link's orientation when it has none (the first of :data:`.generation.ROTATIONS`).
IDENTITY = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _vec(v, where: str, *, lo=-1.0, hi=1.0) -> None:
    if not isinstance(v, (list, tuple)) or len(v) != 3 or not all(is_real(c) for c in v):
        raise ValueError(f"{where}: expected 3 finite numbers, got {v!r}")
    if lo is not None and not all(lo - 1e-12 <= c <= hi + 1e-12 for c in v):
        raise ValueError(f"{where}: every component must be in [{lo}, {hi}], got {list(v)}")


def _rot(R, where: str) -> None:
    if (not isinstance(R, (list, tuple)) or len(R) != 3
            or not all(isinstance(r, (list, tuple)) and len(r) == 3 and all(is_real(v) for v in r) for r in R)):
        raise ValueError(f"{where}: expected a 3x3 rotation matrix of finite numbers, got {R!r}")
    A = np.asarray(R, dtype=float)
    if np.abs(A).max() > 1.0 + 1e-9 or np.abs(A @ A.T - np.eye(3)).max() > 1e-9 or np.linalg.det(A) < 0:
        raise ValueError(f"{where}: must be a proper rotation matrix (orthonormal, det +1), got {A.tolist()}")


@dataclass
class ChildLink:
    """A link to a child node at ``pos`` on this node (units of half extents)."""

    child: int
    pos: tuple = (1.0, 0.0, 0.0)
    rot: tuple = IDENTITY  #: child frame -> parent frame at q = 0
    scale: float = 1.0
    terminal_only: bool = False
    reflect: int = -1  #: -1: none; 0, 1, 2: the child is mirrored across this parent axis

    def to_dict(self) -> dict:
        return {"child": self.child, "pos": list(self.pos), "rot": [list(r) for r in self.rot], "scale": self.scale,
                "terminal_only": self.terminal_only, "reflect": self.reflect}


@dataclass
class Recursion:
    """A virtual copy of the node itself at ``pos``, scaled by ``scale``."""

    pos: tuple = (1.0, 0.0, 0.0)
    scale: float = 1.0
    rot: tuple = IDENTITY

    def to_dict(self) -> dict:
        return {"pos": list(self.pos), "scale": self.scale, "rot": [list(r) for r in self.rot]}


@dataclass
class Symmetry:
    """Mirror every link to node ``child`` across the parent's plane normal to ``axis``."""

    child: int
    axis: int

    def to_dict(self) -> dict:
        return {"child": self.child, "axis": self.axis}


@dataclass
class Node:
    """A morphology node: its box, its joint to the parent, its links and its local network."""

    size: tuple = (0.1, 0.1, 0.1)  #: half extents (m)
    joint_type: str = "revolute"
    joint_pos: tuple = (-1.0, 0.0, 0.0)
    joint_axis: tuple = (0.0, 0.0, 1.0)
    limits: tuple = (-0.8, 0.8)
    force: float = 1.0
    recursive_limit: int = 0
    children: list = field(default_factory=list)
    recursion: list = field(default_factory=list)
    symmetry: list = field(default_factory=list)
    neurons: list = field(default_factory=list)
    effectors: list = field(default_factory=list)  #: one Input (or None: output 0) per DOF
    extra_limits: list = field(default_factory=list)  #: ``[lo, hi]`` of every DOF after the first

    @property
    def dof(self) -> int:
        return JOINT_DOF[self.joint_type]

    @property
    def dof_limits(self) -> list:
        """``(lo, hi)`` of every DOF, in DOF order: ``limits`` then ``extra_limits``."""
        return [tuple(self.limits)] + [tuple(lim) for lim in self.extra_limits]

    def to_dict(self) -> dict:
        return {
            "size": list(self.size), "joint_type": self.joint_type, "joint_pos": list(self.joint_pos),
            "joint_axis": list(self.joint_axis), "limits": list(self.limits), "force": self.force,
            "recursive_limit": self.recursive_limit,
            "children": [c.to_dict() for c in self.children],
            "recursion": [r.to_dict() for r in self.recursion],
            "symmetry": [s.to_dict() for s in self.symmetry],
            "neurons": [n.to_dict() for n in self.neurons],
            "effectors": [None if e is None else e.to_dict() for e in self.effectors],
            "extra_limits": [list(lim) for lim in self.extra_limits],
        }


_NODE_KEYS = ("size", "joint_type", "joint_pos", "joint_axis", "limits", "force", "recursive_limit", "children",
              "recursion", "symmetry", "neurons", "effectors")


def _tuple(v):
    return tuple(_tuple(x) for x in v) if isinstance(v, list) else v


def node_from_dict(d, where: str, version: int = 2) -> Node:
    """A node from its JSON object (``version`` 1 files have no ``extra_limits``: 1-DOF joints)."""
    need_keys(d, _NODE_KEYS + (("extra_limits",) if version >= 2 else ()), where)
    extra = d.get("extra_limits", [])
    for k in ("children", "recursion", "symmetry", "neurons", "effectors"):
        if not isinstance(d[k], list):
            raise TypeError(f"{where}.{k}: expected a list, got {type(d[k]).__name__}")
    children = []
    for k, c in enumerate(d["children"]):
        need_keys(c, ("child", "pos", "rot", "scale", "terminal_only", "reflect"), f"{where}.children[{k}]")
        children.append(ChildLink(c["child"], _tuple(c["pos"]), _tuple(c["rot"]), c["scale"], c["terminal_only"], c["reflect"]))
    recursion = []
    for k, r in enumerate(d["recursion"]):
        need_keys(r, ("pos", "scale", "rot"), f"{where}.recursion[{k}]")
        recursion.append(Recursion(_tuple(r["pos"]), r["scale"], _tuple(r["rot"])))
    symmetry = []
    for k, s in enumerate(d["symmetry"]):
        need_keys(s, ("child", "axis"), f"{where}.symmetry[{k}]")
        symmetry.append(Symmetry(s["child"], s["axis"]))
    neurons = [Neuron.from_dict(n, f"{where}.neurons[{k}]") for k, n in enumerate(d["neurons"])]
    effectors = [None if e is None else Input.from_dict(e, f"{where}.effectors[{k}]") for k, e in enumerate(d["effectors"])]
    return Node(_tuple(d["size"]), d["joint_type"], _tuple(d["joint_pos"]), _tuple(d["joint_axis"]), _tuple(d["limits"]),
                d["force"], d["recursive_limit"], children, recursion, symmetry, neurons, effectors,
                [_tuple(lim) for lim in extra] if isinstance(extra, list) else extra)


def validate_node(node: Node, where: str, n_nodes: int, n_brain: int) -> None:
    """Check one node's fields and references (``n_nodes`` nodes, ``n_brain`` brain neurons)."""
    if not isinstance(node, Node):
        raise TypeError(f"{where}: expected a Node, got {type(node).__name__}")
    for k in ("children", "recursion", "symmetry", "neurons", "effectors"):
        if not isinstance(getattr(node, k), list):
            raise TypeError(f"{where}.{k}: expected a list, got {type(getattr(node, k)).__name__}")
    _vec(node.size, f"{where}.size", lo=MIN_HALF_EXTENT, hi=MAX_HALF_EXTENT)
    if not isinstance(node.joint_type, str) or node.joint_type not in JOINT_DOF:
        raise ValueError(f"{where}.joint_type: must be one of {list(JOINT_DOF)}, got {node.joint_type!r}")
    _vec(node.joint_pos, f"{where}.joint_pos")
    _vec(node.joint_axis, f"{where}.joint_axis", lo=None)
    if abs(math.hypot(*node.joint_axis) - 1.0) > 1e-9:
        raise ValueError(f"{where}.joint_axis: must be a unit vector, got {list(node.joint_axis)}")
    _limits(node.limits, f"{where}.limits", node.joint_type, limit_bound(node.joint_type, 0))
    if not isinstance(node.extra_limits, (list, tuple)) or len(node.extra_limits) != node.dof - 1:
        raise ValueError(f"{where}.extra_limits: a {node.joint_type} joint ({node.dof} DOF) needs a list of "
                         f"{node.dof - 1} [lo, hi] pairs (one per DOF after the first), got {node.extra_limits!r:.80}")
    for k, lim in enumerate(node.extra_limits):
        _limits(lim, f"{where}.extra_limits[{k}]", node.joint_type, limit_bound(node.joint_type, k + 1))
    if not is_real(node.force) or node.force == 0 or abs(node.force) > MAX_FORCE:
        raise ValueError(f"{where}.force: must be nonzero with |force| <= {MAX_FORCE}, got {node.force!r}")
    if not is_int(node.recursive_limit) or not 0 <= node.recursive_limit <= MAX_RECURSIVE_LIMIT:
        raise ValueError(f"{where}.recursive_limit: must be an int in [0, {MAX_RECURSIVE_LIMIT}], got {node.recursive_limit!r}")
    if len(node.children) > MAX_CHILDREN:
        raise ValueError(f"{where}.children: at most {MAX_CHILDREN} links, got {len(node.children)}")
    for k, c in enumerate(node.children):
        w = f"{where}.children[{k}]"
        if not isinstance(c, ChildLink):
            raise TypeError(f"{w}: expected a ChildLink, got {type(c).__name__}")
        if not is_int(c.child) or not 0 <= c.child < n_nodes:
            raise ValueError(f"{w}.child: must be a node id in [0, {n_nodes}), got {c.child!r}")
        _vec(c.pos, f"{w}.pos")
        _rot(c.rot, f"{w}.rot")
        if not is_real(c.scale) or not SCALE_RANGE[0] <= c.scale <= SCALE_RANGE[1]:
            raise ValueError(f"{w}.scale: must be in {list(SCALE_RANGE)}, got {c.scale!r}")
        if not isinstance(c.terminal_only, bool):
            raise TypeError(f"{w}.terminal_only: expected a bool, got {c.terminal_only!r}")
        if not is_int(c.reflect) or c.reflect not in (-1, 0, 1, 2):
            raise ValueError(f"{w}.reflect: must be -1 (none), 0, 1 or 2, got {c.reflect!r}")
    if len(node.recursion) > MAX_RECURSION_ENTRIES:
        raise ValueError(f"{where}.recursion: at most {MAX_RECURSION_ENTRIES} entries, got {len(node.recursion)}")
    for k, r in enumerate(node.recursion):
        w = f"{where}.recursion[{k}]"
        if not isinstance(r, Recursion):
            raise TypeError(f"{w}: expected a Recursion, got {type(r).__name__}")
        _vec(r.pos, f"{w}.pos")
        _rot(r.rot, f"{w}.rot")
        if not is_real(r.scale) or not SCALE_RANGE[0] <= r.scale <= SCALE_RANGE[1]:
            raise ValueError(f"{w}.scale: must be in {list(SCALE_RANGE)}, got {r.scale!r}")
    if len(node.symmetry) > MAX_SYMMETRY:
        raise ValueError(f"{where}.symmetry: at most {MAX_SYMMETRY} entries, got {len(node.symmetry)}")
    linked = {c.child for c in node.children}
    for k, s in enumerate(node.symmetry):
        w = f"{where}.symmetry[{k}]"
        if not isinstance(s, Symmetry):
            raise TypeError(f"{w}: expected a Symmetry, got {type(s).__name__}")
        if not is_int(s.child) or s.child not in linked:
            raise ValueError(f"{w}.child: must name a node this node links to ({sorted(linked)}), got {s.child!r}")
        if not is_int(s.axis) or s.axis not in (0, 1, 2):
            raise ValueError(f"{w}.axis: must be 0, 1 or 2, got {s.axis!r}")
    if len(node.neurons) > MAX_NEURONS:
        raise ValueError(f"{where}.neurons: at most {MAX_NEURONS} neurons, got {len(node.neurons)}")
    n_local = N_SENSORS + len(node.neurons)
    for k, n in enumerate(node.neurons):
        validate_neuron(n, f"{where}.neurons[{k}]", brain=False, n_local=n_local, n_brain=n_brain, dof=node.dof)
    if len(node.effectors) != node.dof:
        raise ValueError(f"{where}.effectors: need one per DOF ({node.dof}), got {len(node.effectors)}")
    for k, e in enumerate(node.effectors):
        if e is not None:
            validate_input(e, f"{where}.effectors[{k}]", brain=False, n_local=n_local, n_brain=n_brain, dof=node.dof)


def _limits(lim, where: str, joint_type: str, bound: float) -> None:
    if not isinstance(lim, (list, tuple)) or len(lim) != 2 or not all(is_real(v) for v in lim) or not lim[0] < 0 < lim[1]:
        raise ValueError(f"{where}: need [lo, hi], two finite numbers with lo < 0 < hi, got {lim!r}")
    if -lim[0] > bound or lim[1] > bound:
        raise ValueError(f"{where}: {joint_type} limits must lie within ±{bound:g} here, got {list(lim)}")


def joint_axes(node: Node) -> list:
    """The unit axis (node frame) of every DOF of ``node``'s joint, in DOF order (:data:`JOINT_AXES`).

    >>> [tuple(map(float, a)) for a in joint_axes(Node(joint_type="universal", joint_pos=(-1.0, 0.0, 0.0),
    ...                                                joint_axis=(0.0, 0.0, 1.0)))]
    [(0.0, 0.0, 1.0), (0.0, -1.0, 0.0)]
    """
    a = np.asarray(node.joint_axis, dtype=np.float64)
    kinds = JOINT_AXES[node.joint_type]
    if kinds == ("axis",):
        return [a]
    jp = np.asarray(node.joint_pos, dtype=np.float64)
    t = np.zeros(3)
    t[int(np.argmax(np.abs(jp)))] = 1.0  # the attachment axis: the joint face's normal (x when centred)
    bend = a - (a @ t) * t
    if np.linalg.norm(bend) < 1e-6:  # joint_axis along the twist axis: the next cube axis
        bend = np.roll(t, 1)
    bend = bend / np.linalg.norm(bend)
    axes = {"twist": t, "bend": bend, "bend2": np.cross(t, bend)}
    return [axes[k] for k in kinds]


def preorder(nodes: list) -> list[int]:
    """Node ids in LR (pre-order) traversal from the root, each at its first visit.

    ``None`` entries (empty positions during recombination) are skipped.
    """
    order, seen, stack = [], set(), [0]
    while stack:
        i = stack.pop()
        if i in seen or nodes[i] is None:
            continue
        seen.add(i)
        order.append(i)
        stack.extend(c.child for c in reversed(nodes[i].children) if c.child not in seen)
    return order


def renumber(nodes: list) -> list:
    """Nodes reachable from the root, renumbered in LR (pre-order) order; links follow.

    Unreachable nodes are dropped (garbage collection). The nodes are modified in place.
    """
    order = preorder(nodes)
    new_id = {old: k for k, old in enumerate(order)}
    out = []
    for old in order:
        node = nodes[old]
        for c in node.children:
            c.child = new_id[c.child]
        for s in node.symmetry:
            s.child = new_id.get(s.child, -1)
        out.append(node)
    return out


def has_cycle(nodes: list) -> bool:
    """True when the child-link graph has a directed cycle."""
    state = [0] * len(nodes)  # 0 new, 1 on stack, 2 done

    def visit(i):
        state[i] = 1
        for c in nodes[i].children:
            if state[c.child] == 1 or (state[c.child] == 0 and visit(c.child)):
                return True
        state[i] = 2
        return False

    return any(state[i] == 0 and visit(i) for i in range(len(nodes)))
