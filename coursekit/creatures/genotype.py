"""The morphology genotype: a directed graph of singleton nodes (paper section 2.1.1).

A :class:`Creature` is a list of :class:`Node` (node 0 is the root) plus a central brain (a list
of :class:`~coursekit.creatures.neural.Neuron`). Nodes are never copied to express repetition;
links are attributes of a node, as in the paper's Haskell types:

- ``children = [ChildLink(child, pos, ...)]`` — the paper's ``[(id, pos)]``; beyond the paper (as
  Sims did) a link has an orientation ``rot``, a ``scale``, a ``terminal_only`` flag (the link
  applies only at the last instance of a recursion: tails, hands) and an optional ``reflect``
  axis (the child is a mirror image);
- ``recursion = [Recursion(pos, scale, rot)]`` — the node virtually copies itself to ``pos``,
  scaled, up to ``recursive_limit`` times along a chain;
- ``symmetry = [Symmetry(child, axis)]`` — every link to node ``child`` gets a second, mirrored
  element, reflected across the parent's plane ``axis = 0, 1, 2`` (x, y, z).

The child-link graph must be acyclic (repetition is the recursion attribute's job). A node also
describes the joint to its parent: ``joint_type`` (rotational ``"revolute"`` or translational
``"prismatic"``, 1 DOF each — the design keeps a type name and per-type DOF count so universal or
spherical joints can be added), ``joint_pos`` (relative to the node's centre of mass, in units
of its half extents, so ``(-1, 0, 0)`` is the centre of its −x face), ``joint_axis`` (unit, node
frame), ``limits`` (mobility, ``lo < 0 < hi``: radians for a revolute joint; for a prismatic joint in
units of the part's half-width along its axis, so a slide means the same at every scale) and ``force`` (the signed force coefficient: a
mirrored copy of the node has gain ``force`` and the original ``|force|``, so a positive value
moves symmetric parts as mirror images — wings — and a negative one in opposition — legs).

Positions ``pos`` are in units of the parent's half extents (``[-1, 1]^3``; the surface where a
component is ±1). Random genomes and mutation draw from the predefined value lists below
(paper section 2.2.2: "a predefined list of valid values").

Files are JSON with ``"format": "coursekit.creature/1"``, written atomically.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import copy
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .body import MIN_HALF_EXTENT
from .neural import (
    MAX_BRAIN_NEURONS,
    MAX_NEURONS,
    N_SENSORS,
    Input,
    Neuron,
    _is_int,
    _is_real,
    _need_keys,
    random_input,
    random_neuron,
    validate_input,
    validate_neuron,
)

FORMAT = "coursekit.creature/1"

#: Joint types and their degrees of freedom (add "universal": 2, "spherical": 3 here and in
#: expansion to extend; every per-DOF list — effectors, sensors — is sized from this table).
JOINT_DOF = {"revolute": 1, "prismatic": 1}

MAX_HALF_EXTENT = 1.0
MAX_NODES = 24  #: genotype node cap (after garbage collection)
MAX_CHILDREN = 4  #: child links per node
MAX_RECURSION_ENTRIES = 2
MAX_RECURSIVE_LIMIT = 4
MAX_SYMMETRY = 3
MAX_FORCE = 2.0
SCALE_RANGE = (0.5, 1.5)

# Predefined value lists used by random generation and mutation.
SIZES = (0.025, 0.04, 0.06, 0.08, 0.1, 0.125, 0.15, 0.2, 0.25, 0.3)
COORDS = (-1.0, -0.5, 0.0, 0.5, 1.0)
FORCES = (-2.0, -1.0, -0.5, -0.25, 0.25, 0.5, 1.0, 2.0)
REVOLUTE_LIMITS = (0.2, 0.4, 0.6, 0.8, 1.0, 1.3, 1.6)
PRISMATIC_LIMITS = (0.25, 0.5, 0.75, 1.0)  #: in units of the part's half-width along the joint axis
SCALES = (0.6, 0.75, 0.9, 1.0, 1.1)
AXES = tuple(
    tuple(float(v) for v in np.asarray(a, float) / np.linalg.norm(a))
    for a in [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1)]
)


def _cube_rotations() -> tuple:
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            R = np.zeros((3, 3))
            for r, (c, s) in enumerate(zip(perm, signs)):
                R[r, c] = s
            if np.linalg.det(R) > 0:
                out.append(tuple(tuple(float(v) + 0.0 for v in row) for row in R))
    return tuple(out)


#: The 24 rotations of the cube: the predefined orientations of links.
ROTATIONS = _cube_rotations()
_ROTATION_ARRAY = np.array(ROTATIONS)
IDENTITY = ROTATIONS[0]
FACES = tuple(tuple(float(v) for v in f) for f in [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)])


def _vec(v, where: str, *, lo=-1.0, hi=1.0) -> None:
    if not isinstance(v, (list, tuple)) or len(v) != 3 or not all(_is_real(c) for c in v):
        raise ValueError(f"{where}: expected 3 finite numbers, got {v!r}")
    if lo is not None and not all(lo - 1e-12 <= c <= hi + 1e-12 for c in v):
        raise ValueError(f"{where}: every component must be in [{lo}, {hi}], got {list(v)}")


def _rot(R, where: str) -> None:
    if (not isinstance(R, (list, tuple)) or len(R) != 3
            or not all(isinstance(r, (list, tuple)) and len(r) == 3 and all(_is_real(v) for v in r) for r in R)):
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

    @property
    def dof(self) -> int:
        return JOINT_DOF[self.joint_type]

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
        }


_NODE_KEYS = ("size", "joint_type", "joint_pos", "joint_axis", "limits", "force", "recursive_limit", "children",
              "recursion", "symmetry", "neurons", "effectors")


def _tuple(v):
    return tuple(_tuple(x) for x in v) if isinstance(v, list) else v


def _node_from_dict(d, where: str) -> Node:
    _need_keys(d, _NODE_KEYS, where)
    for k in ("children", "recursion", "symmetry", "neurons", "effectors"):
        if not isinstance(d[k], list):
            raise TypeError(f"{where}.{k}: expected a list, got {type(d[k]).__name__}")
    children = []
    for k, c in enumerate(d["children"]):
        _need_keys(c, ("child", "pos", "rot", "scale", "terminal_only", "reflect"), f"{where}.children[{k}]")
        children.append(ChildLink(c["child"], _tuple(c["pos"]), _tuple(c["rot"]), c["scale"], c["terminal_only"], c["reflect"]))
    recursion = []
    for k, r in enumerate(d["recursion"]):
        _need_keys(r, ("pos", "scale", "rot"), f"{where}.recursion[{k}]")
        recursion.append(Recursion(_tuple(r["pos"]), r["scale"], _tuple(r["rot"])))
    symmetry = []
    for k, s in enumerate(d["symmetry"]):
        _need_keys(s, ("child", "axis"), f"{where}.symmetry[{k}]")
        symmetry.append(Symmetry(s["child"], s["axis"]))
    neurons = [Neuron.from_dict(n, f"{where}.neurons[{k}]") for k, n in enumerate(d["neurons"])]
    effectors = [None if e is None else Input.from_dict(e, f"{where}.effectors[{k}]") for k, e in enumerate(d["effectors"])]
    return Node(_tuple(d["size"]), d["joint_type"], _tuple(d["joint_pos"]), _tuple(d["joint_axis"]), _tuple(d["limits"]),
                d["force"], d["recursive_limit"], children, recursion, symmetry, neurons, effectors)


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
    lim = node.limits
    if not isinstance(lim, (list, tuple)) or len(lim) != 2 or not all(_is_real(v) for v in lim) or not lim[0] < 0 < lim[1]:
        raise ValueError(f"{where}.limits: need (lo, hi) with lo < 0 < hi, got {lim!r}")
    bound = math.pi if node.joint_type == "revolute" else MAX_HALF_EXTENT
    if -lim[0] > bound or lim[1] > bound:
        raise ValueError(f"{where}.limits: {node.joint_type} limits must lie within ±{bound:g}, got {list(lim)}")
    if not _is_real(node.force) or node.force == 0 or abs(node.force) > MAX_FORCE:
        raise ValueError(f"{where}.force: must be nonzero with |force| <= {MAX_FORCE}, got {node.force!r}")
    if not _is_int(node.recursive_limit) or not 0 <= node.recursive_limit <= MAX_RECURSIVE_LIMIT:
        raise ValueError(f"{where}.recursive_limit: must be an int in [0, {MAX_RECURSIVE_LIMIT}], got {node.recursive_limit!r}")
    if len(node.children) > MAX_CHILDREN:
        raise ValueError(f"{where}.children: at most {MAX_CHILDREN} links, got {len(node.children)}")
    for k, c in enumerate(node.children):
        w = f"{where}.children[{k}]"
        if not isinstance(c, ChildLink):
            raise TypeError(f"{w}: expected a ChildLink, got {type(c).__name__}")
        if not _is_int(c.child) or not 0 <= c.child < n_nodes:
            raise ValueError(f"{w}.child: must be a node id in [0, {n_nodes}), got {c.child!r}")
        _vec(c.pos, f"{w}.pos")
        _rot(c.rot, f"{w}.rot")
        if not _is_real(c.scale) or not SCALE_RANGE[0] <= c.scale <= SCALE_RANGE[1]:
            raise ValueError(f"{w}.scale: must be in {list(SCALE_RANGE)}, got {c.scale!r}")
        if not isinstance(c.terminal_only, bool):
            raise TypeError(f"{w}.terminal_only: expected a bool, got {c.terminal_only!r}")
        if not _is_int(c.reflect) or c.reflect not in (-1, 0, 1, 2):
            raise ValueError(f"{w}.reflect: must be -1 (none), 0, 1 or 2, got {c.reflect!r}")
    if len(node.recursion) > MAX_RECURSION_ENTRIES:
        raise ValueError(f"{where}.recursion: at most {MAX_RECURSION_ENTRIES} entries, got {len(node.recursion)}")
    for k, r in enumerate(node.recursion):
        w = f"{where}.recursion[{k}]"
        if not isinstance(r, Recursion):
            raise TypeError(f"{w}: expected a Recursion, got {type(r).__name__}")
        _vec(r.pos, f"{w}.pos")
        _rot(r.rot, f"{w}.rot")
        if not _is_real(r.scale) or not SCALE_RANGE[0] <= r.scale <= SCALE_RANGE[1]:
            raise ValueError(f"{w}.scale: must be in {list(SCALE_RANGE)}, got {r.scale!r}")
    if len(node.symmetry) > MAX_SYMMETRY:
        raise ValueError(f"{where}.symmetry: at most {MAX_SYMMETRY} entries, got {len(node.symmetry)}")
    linked = {c.child for c in node.children}
    for k, s in enumerate(node.symmetry):
        w = f"{where}.symmetry[{k}]"
        if not isinstance(s, Symmetry):
            raise TypeError(f"{w}: expected a Symmetry, got {type(s).__name__}")
        if not _is_int(s.child) or s.child not in linked:
            raise ValueError(f"{w}.child: must name a node this node links to ({sorted(linked)}), got {s.child!r}")
        if not _is_int(s.axis) or s.axis not in (0, 1, 2):
            raise ValueError(f"{w}.axis: must be 0, 1 or 2, got {s.axis!r}")
    if len(node.neurons) > MAX_NEURONS:
        raise ValueError(f"{where}.neurons: at most {MAX_NEURONS} neurons, got {len(node.neurons)}")
    n_local = N_SENSORS + len(node.neurons)
    for k, n in enumerate(node.neurons):
        validate_neuron(n, f"{where}.neurons[{k}]", brain=False, n_local=n_local, n_brain=n_brain)
    if len(node.effectors) != node.dof:
        raise ValueError(f"{where}.effectors: need one per DOF ({node.dof}), got {len(node.effectors)}")
    for k, e in enumerate(node.effectors):
        if e is not None:
            validate_input(e, f"{where}.effectors[{k}]", brain=False, n_local=n_local, n_brain=n_brain)


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


@dataclass
class Creature:
    """A creature's genotype: morphology nodes (root first) and the central brain."""

    nodes: list
    brain: list = field(default_factory=list)

    def __post_init__(self) -> None:
        self.validate()

    # ------------------------------------------------------------------------ validity
    def validate(self) -> None:
        """Raise ``ValueError``/``TypeError`` naming the field when the genotype is invalid."""
        if not isinstance(self.nodes, list) or not 1 <= len(self.nodes) <= MAX_NODES:
            raise ValueError(f"Creature.nodes: need a list of 1..{MAX_NODES} nodes, got {self.nodes!r:.80}")
        if not isinstance(self.brain, list) or len(self.brain) > MAX_BRAIN_NEURONS:
            raise ValueError(f"Creature.brain: need a list of at most {MAX_BRAIN_NEURONS} neurons")
        for k, n in enumerate(self.brain):
            validate_neuron(n, f"Creature.brain[{k}]", brain=True, n_local=len(self.brain), n_brain=len(self.brain))
        for i, node in enumerate(self.nodes):
            validate_node(node, f"Creature.nodes[{i}]", len(self.nodes), len(self.brain))
        if has_cycle(self.nodes):
            raise ValueError("Creature.nodes: the child links form a cycle; use the recursion attribute for repetition")
        reach = preorder(self.nodes)
        if len(reach) != len(self.nodes):
            missing = sorted(set(range(len(self.nodes))) - set(reach))
            raise ValueError(f"Creature.nodes: nodes {missing} are unreachable from the root (collect garbage first)")

    def copy(self) -> "Creature":
        return copy.deepcopy(self)

    def unwired(self) -> "Creature":
        """A copy with the body alone: no neurons, no brain, every effector off (exercise 06 wires it)."""
        out = self.copy()
        for node in out.nodes:
            node.neurons = []
            node.effectors = [None] * node.dof
        out.brain = []
        return out

    # ------------------------------------------------------------------------ display
    #: (width, height) of the picture a notebook shows for a creature, in pixels.
    REPR_SIZE = (400, 300)

    def summary(self) -> dict:
        """What a person wants to know first, from the expanded body: ``parts``, ``joints``,
        ``dof`` (the joints' degrees of freedom; the free root adds 6 more), ``mass`` (kg),
        ``neurons`` (expanded, central brain included), and the genotype's ``nodes``.

        >>> Creature.figure1_snake().summary()["parts"]
        6
        """
        ph = self.expand()
        body = ph.body
        dof = sum(JOINT_DOF[self.nodes[int(i)].joint_type] for i in body.node_id[1:]) if body.node_id is not None else body.n_joints
        return {"parts": body.n_bodies, "joints": body.n_joints, "dof": int(dof), "mass": float(body.mass.sum()),
                "neurons": int(ph.brain.n_neurons), "nodes": len(self.nodes)}

    def __repr__(self) -> str:
        """Short: the genotype's size (``to_json`` has everything).

        >>> Creature.figure1_snake()
        Creature(2 nodes, 1 brain neuron)
        """
        n, k = len(self.nodes), len(self.brain)
        return f"Creature({n} node{'s' * (n != 1)}, {k} brain neuron{'s' * (k != 1)})"

    def _repr_png_(self) -> bytes:
        """Its rendering (``REPR_SIZE``), for notebooks."""
        return self._repr_mimebundle_()["image/png"]

    def _repr_html_(self) -> str:
        """Its rendering with a one-line summary (parts, joints, DOF, mass, neurons), for notebooks."""
        return self._repr_mimebundle_()["text/html"]

    def _repr_mimebundle_(self, include=None, exclude=None) -> dict:
        """PNG, HTML (the PNG with its summary below) and text, from one rendering."""
        import base64
        import html

        from coursekit.pictures.gallery import png_bytes

        from .render import render

        png = png_bytes(render(self, size=self.REPR_SIZE) / 255.0)
        s = self.summary()
        caption = (f"{s['parts']} parts, {s['joints']} joints, {s['dof']} DOF (+6 free root), "
                   f"{s['mass']:.3g} kg, {s['neurons']} neurons; genotype of {s['nodes']} nodes")
        data = base64.b64encode(png).decode("ascii")
        page = (f'<figure style="margin:0"><img src="data:image/png;base64,{data}" width="{self.REPR_SIZE[0]}" '
                f'alt="{html.escape(repr(self))}"><figcaption style="font-size:smaller">{html.escape(caption)}'
                "</figcaption></figure>")
        return {"image/png": png, "text/html": page, "text/plain": repr(self)}

    # --------------------------------------------------------------------------- files
    def to_dict(self) -> dict:
        return {"format": FORMAT, "nodes": [n.to_dict() for n in self.nodes], "brain": [n.to_dict() for n in self.brain]}

    def to_json(self) -> str:
        """Versioned JSON text (``"format": "coursekit.creature/1"``)."""
        return json.dumps(self.to_dict(), indent=1)

    @classmethod
    def from_dict(cls, d) -> "Creature":
        if not isinstance(d, dict):
            raise TypeError(f"creature: expected a JSON object, got {type(d).__name__}")
        if d.get("format") != FORMAT:
            raise ValueError(f"creature.format: expected {FORMAT!r}, got {d.get('format')!r} (not a coursekit creature file?)")
        _need_keys(d, ("nodes", "brain"), "creature")
        if not isinstance(d["nodes"], list) or not isinstance(d["brain"], list):
            raise TypeError("creature.nodes / creature.brain: expected lists")
        nodes = [_node_from_dict(n, f"creature.nodes[{i}]") for i, n in enumerate(d["nodes"])]
        brain = [Neuron.from_dict(n, f"creature.brain[{k}]") for k, n in enumerate(d["brain"])]
        return cls(nodes, brain)

    @classmethod
    def from_json(cls, text: str) -> "Creature":
        """Parse :meth:`to_json` output; truncated or foreign text raises ``ValueError``."""
        if not isinstance(text, (str, bytes)):
            raise TypeError(f"Creature.from_json: expected str, got {type(text).__name__}")
        try:
            d = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"Creature.from_json: not valid JSON (truncated file?): {e}") from None
        return cls.from_dict(d)

    def save(self, path) -> None:
        """Write the JSON atomically (temporary file in the same folder, then ``os.replace``)."""
        atomic_write(path, self.to_json())

    @classmethod
    def load(cls, path) -> "Creature":
        """Read a file written by :meth:`save`."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError:
            raise ValueError(f"Creature.load: {path} is not a text creature file") from None
        return cls.from_json(text)

    # ---------------------------------------------------------------------- phenotype
    def expand(self, max_parts: int | None = None):
        """The phenotype (body tree + flat brain); see :func:`coursekit.creatures.phenotype.expand`."""
        from .phenotype import MAX_PARTS, expand

        return expand(self, MAX_PARTS if max_parts is None else max_parts)

    # ------------------------------------------------------------------------- makers
    @classmethod
    def random(cls, rng: np.random.Generator, *, n_nodes: int | tuple = (1, 5), max_children: int = 3,
               neurons: tuple = (0, 3), brain_neurons: tuple = (0, 3), p_recursion: float = 0.3,
               p_symmetry: float = 0.4, max_parts: int | None = None) -> "Creature":
        """A random valid creature.

        Args:
            rng: the random generator.
            n_nodes: node count, an int or an inclusive range ``(lo, hi)`` within [1, MAX_NODES].
            max_children: most child links per node (<= MAX_CHILDREN).
            neurons: inclusive range of local neurons per node (within [0, MAX_NEURONS]).
            brain_neurons: inclusive range of brain neurons (within [0, MAX_BRAIN_NEURONS]).
            p_recursion, p_symmetry: chance a node recurses / a link gets a symmetric copy.
            max_parts: the expansion must fit this many parts without truncation (default
                ``phenotype.MAX_PARTS``); recursion and symmetry entries are pruned at random
                until it does.

        Returns:
            A :class:`Creature` (nodes numbered in LR pre-order, all reachable, acyclic).
        """
        if not isinstance(rng, np.random.Generator):
            raise TypeError(f"Creature.random: rng must be a numpy.random.Generator, got {type(rng).__name__}")
        lo, hi = (n_nodes, n_nodes) if _is_int(n_nodes) else tuple(n_nodes)
        if not 1 <= lo <= hi <= MAX_NODES:
            raise ValueError(f"Creature.random.n_nodes: need 1 <= lo <= hi <= {MAX_NODES}, got {n_nodes!r}")
        if not _is_int(max_children) or not 1 <= max_children <= MAX_CHILDREN:
            raise ValueError(f"Creature.random.max_children: must be in [1, {MAX_CHILDREN}], got {max_children!r}")
        for name, (a, b), cap in (("neurons", neurons, MAX_NEURONS), ("brain_neurons", brain_neurons, MAX_BRAIN_NEURONS)):
            if not 0 <= a <= b <= cap:
                raise ValueError(f"Creature.random.{name}: need 0 <= lo <= hi <= {cap}, got {(a, b)!r}")
        for name, p in (("p_recursion", p_recursion), ("p_symmetry", p_symmetry)):
            if not 0.0 <= p <= 1.0:
                raise ValueError(f"Creature.random.{name}: must be a probability in [0, 1], got {p!r}")
        from .phenotype import MAX_PARTS

        max_parts = MAX_PARTS if max_parts is None else max_parts
        if not _is_int(max_parts) or max_parts < hi:
            raise ValueError(f"Creature.random.max_parts: must be an int >= the largest node count {hi}, got {max_parts!r}")
        count = int(rng.integers(lo, hi + 1))
        nodes = [random_node(rng) for _ in range(count)]
        # A random tree over the nodes (parent id < child id keeps the graph acyclic), then a few
        # extra links to later nodes (shared subgraphs, as Sims' graphs allow).
        for i in range(1, count):
            # i nodes hold i - 1 tree links so far, so one always has room
            cands = [j for j in range(i) if len(nodes[j].children) < max_children]
            j = cands[int(rng.integers(len(cands)))]
            nodes[j].children.append(random_link(rng, i, nodes[j], nodes[i]))
        for i in range(count - 1):
            if rng.random() < 0.15 and len(nodes[i].children) < max_children:
                j = int(rng.integers(i + 1, count))
                nodes[i].children.append(random_link(rng, j, nodes[i], nodes[j]))
        for node in nodes:
            if rng.random() < p_recursion:
                node.recursion.append(random_recursion(rng, node))
                node.recursive_limit = int(rng.integers(1, 4))
            for c in node.children:
                if rng.random() < p_symmetry and len(node.symmetry) < MAX_SYMMETRY and all(s.child != c.child for s in node.symmetry):
                    axis = mirror_axis(rng, node, c.child)
                    if axis is not None:
                        node.symmetry.append(Symmetry(c.child, axis))
        brain = []
        nb = int(rng.integers(brain_neurons[0], brain_neurons[1] + 1))
        for _ in range(nb):
            brain.append(random_neuron(rng, brain=True, n_local=nb, n_brain=nb, n_children=1))
        for node in nodes:
            k = int(rng.integers(neurons[0], neurons[1] + 1))
            n_local = N_SENSORS + k
            nc = max(1, len(node.children) + len(node.recursion))
            node.neurons = [random_neuron(rng, brain=False, n_local=n_local, n_brain=nb, n_children=nc) for _ in range(k)]
            node.effectors = [random_input(rng, brain=False, n_local=n_local, n_brain=nb, n_children=nc) for _ in range(node.dof)]
        creature = cls(renumber(nodes), brain)
        # Sims discards creatures over the part cap; we prune multipliers until it fits.
        from .phenotype import expand

        while expand(creature, max_parts).body.meta["truncated"]:
            _prune_one(creature, rng)
            creature.nodes = renumber(creature.nodes)
        return creature

    @classmethod
    def figure1_snake(cls, segments: int = 4) -> "Creature":
        """The paper's Figure 1: a snake with two legs at the last limb, from exactly two nodes.

        Node 0 (a body segment) repeats itself ``segments - 1`` times through its recursion
        attribute; its link to node 1 (a leg) is terminal-only, so it appears on the last
        segment only, and a symmetry entry mirrors it across the segment's y plane.

        Args:
            segments: number of body segments (1..MAX_RECURSIVE_LIMIT + 1).
        """
        if not _is_int(segments) or not 1 <= segments <= MAX_RECURSIVE_LIMIT + 1:
            raise ValueError(f"figure1_snake.segments: must be an int in [1, {MAX_RECURSIVE_LIMIT + 1}], got {segments!r}")
        brain = [Neuron("oscillate_wave", [Input(None, 0, 0.0)], 1.0)]
        # Slender-body (resistive-force) theory for a travelling wave in a viscous medium gives a
        # speed of about (r - 1) (A k)^2 / 2 times the wave speed (reference/creatures.md section
        # 7), r being the drag across the body over the drag along it -- for Sims' per-face drag
        # on a box, the side area over the end area, here L / w = 0.4 / 0.08 = 5 -- so the snake
        # is slender, bends +-1 rad (amplitude counts squared) and beats at 3 Hz (speed grows
        # with frequency) with about 0.7 wavelengths on its body, like an eel.
        segment = Node(
            size=(0.2, 0.04, 0.06), joint_type="revolute", joint_pos=(-1.0, 0.0, 0.0), joint_axis=(0.0, 0.0, 1.0),
            limits=(-1.0, 1.0), force=1.0, recursive_limit=segments - 1,
            children=[ChildLink(1, pos=(0.5, 1.0, 0.0), terminal_only=True)],
            recursion=[Recursion(pos=(1.0, 0.0, 0.0), scale=1.0)],
            symmetry=[Symmetry(1, axis=1)],
            # A travelling wave: neuron 0 accumulates a phase along the spine (its parent's
            # phase minus 1.5 rad; the root has no parent and reads 0), neuron 1 oscillates at
            # 3 Hz with that phase and drives the segment's joint.
            neurons=[Neuron("sum", [Input(-1, N_SENSORS, 1.0), Input(None, 0, -1.5)]),
                     Neuron("oscillate_wave", [Input(0, N_SENSORS, 1.0)], 3.0)],
            effectors=[Input(0, N_SENSORS + 1, 1.0)],
        )
        leg = Node(
            size=(0.04, 0.15, 0.04), joint_type="revolute", joint_pos=(0.0, -1.0, 0.0), joint_axis=(1.0, 0.0, 0.0),
            limits=(-0.8, 0.8), force=-1.0, effectors=[Input(-2, 0, 1.0)],
        )
        return cls([segment, leg], brain)

    @classmethod
    def paddle_turtle(cls) -> "Creature":
        """A second hand-designed swimmer with a different stroke: a flat body rowing two paddles.

        Node 0 is the body; its link to node 1 (an arm, swinging fore and aft about the body's
        vertical axis) is mirrored by a symmetry entry, and each arm carries node 2 (a blade that
        turns about the arm's long axis). In viscous water a reciprocal stroke gets nowhere
        (Purcell's scallop theorem: the recovery undoes the power stroke), so the blades
        *feather*: two central oscillators at 1.5 Hz, the blades' a quarter period ahead of the
        arms', hold each blade broadside to the water on the power stroke and edge-on on the
        recovery. A positive force coefficient makes both sides row together, like a turtle.
        """
        brain = [Neuron("oscillate_wave", [Input(None, 0, 0.0)], 1.5), Neuron("oscillate_wave", [Input(None, 0, math.pi / 2)], 1.5)]
        body = Node(size=(0.25, 0.15, 0.06), children=[ChildLink(1, pos=(0.3, 1.0, 0.0))], symmetry=[Symmetry(1, axis=1)], effectors=[None])
        arm = Node(size=(0.04, 0.12, 0.03), joint_type="revolute", joint_pos=(0.0, -1.0, 0.0), joint_axis=(0.0, 0.0, 1.0),
                   limits=(-0.9, 0.9), force=1.0, children=[ChildLink(2, pos=(0.0, 1.0, 0.0))], effectors=[Input(-2, 0, 1.0)])
        blade = Node(size=(0.15, 0.1, 0.025), joint_type="revolute", joint_pos=(0.0, -1.0, 0.0), joint_axis=(0.0, 1.0, 0.0),
                     limits=(-1.2, 1.2), force=1.0, effectors=[Input(-2, 1, 1.0)])
        return cls([body, arm, blade], brain)


# ----------------------------------------------------------------------- random elements


def _prune_one(creature: Creature, rng) -> None:
    """Remove one random multiplier (a recursion step, a symmetry entry or a shared link)."""
    options = []
    for i, node in enumerate(creature.nodes):
        if node.recursion and node.recursive_limit > 0:
            options.append(("limit", i))
        if node.symmetry:
            options.append(("symmetry", i))
    seen = set()
    for i, node in enumerate(creature.nodes):  # links beyond each node's first incoming one
        for k, c in enumerate(node.children):
            if c.child in seen:
                options.append(("link", (i, k)))
            seen.add(c.child)
    kind, where = _choice(rng, options)
    if kind == "limit":
        creature.nodes[where].recursive_limit -= 1
    elif kind == "symmetry":
        creature.nodes[where].symmetry.pop(int(rng.integers(len(creature.nodes[where].symmetry))))
    else:
        i, k = where
        node = creature.nodes[i]
        child = node.children.pop(k).child
        if all(c.child != child for c in node.children):
            node.symmetry = [s for s in node.symmetry if s.child != child]


def _choice(rng, seq):
    return seq[int(rng.integers(len(seq)))]


def random_face_point(rng) -> tuple:
    """A point on the unit box surface from the predefined coordinates (one component ±1)."""
    k = int(rng.integers(3))
    p = [_choice(rng, COORDS) for _ in range(3)]
    p[k] = _choice(rng, (-1.0, 1.0))
    return tuple(p)


def facing_rotation(rng, parent_pos, child_joint_pos) -> tuple:
    """A cube rotation turning the child's joint face towards the parent's attachment face."""
    pn = np.asarray(parent_pos, float)
    cn = np.asarray(child_joint_pos, float)
    pn = np.where(np.abs(pn) == np.abs(pn).max(), np.sign(pn), 0.0)
    cn = np.where(np.abs(cn) == np.abs(cn).max(), np.sign(cn), 0.0)
    # Want R @ cn ≈ -pn: the joint face of the child points back at the parent.
    good = np.nonzero(np.abs(_ROTATION_ARRAY @ cn + pn).max(axis=1) < 1e-9)[0]
    return ROTATIONS[int(_choice(rng, good))] if good.size else _choice(rng, ROTATIONS)


def mirror_axis(rng, node: Node, child: int) -> int | None:
    """A random axis that moves every link to ``child`` when mirrored (so copies don't
    coincide), or None when there is none."""
    links = [c.pos for c in node.children if c.child == child]
    axes = [k for k in range(3) if all(abs(p[k]) > 0 for p in links)]
    return _choice(rng, axes) if links and axes else None


def random_node(rng) -> Node:
    """A random node with no links and no neurons (effector: constant 0 until wired)."""
    jt = _choice(rng, ("revolute", "revolute", "revolute", "prismatic"))
    lim = _choice(rng, REVOLUTE_LIMITS if jt == "revolute" else PRISMATIC_LIMITS)
    lim2 = _choice(rng, REVOLUTE_LIMITS if jt == "revolute" else PRISMATIC_LIMITS)
    node = Node(
        size=tuple(_choice(rng, SIZES[2:]) for _ in range(3)), joint_type=jt, joint_pos=_choice(rng, FACES),
        joint_axis=_choice(rng, AXES), limits=(-lim, lim2), force=_choice(rng, FORCES),
    )
    node.effectors = [None] * node.dof
    return node


def random_link(rng, child: int, parent_node: Node, child_node: Node) -> ChildLink:
    """A random link to ``child`` whose orientation faces the child's joint to the parent."""
    pos = random_face_point(rng)
    return ChildLink(child, pos, facing_rotation(rng, pos, child_node.joint_pos), _choice(rng, SCALES),
                     bool(rng.random() < 0.2), -1)


def random_recursion(rng, node: Node) -> Recursion:
    """A recursion entry; usually on the face opposite the node's joint, so that the copies form
    a chain (a snake, a tail) rather than folding back onto themselves."""
    jp = np.asarray(node.joint_pos, dtype=float)
    if rng.random() < 0.7 and np.abs(jp).max() > 0:
        k = int(np.argmax(np.abs(jp)))
        p = [0.0, 0.0, 0.0]
        p[k] = -float(np.sign(jp[k]))
        pos = tuple(p)
    else:
        pos = random_face_point(rng)
    return Recursion(pos, _choice(rng, SCALES), facing_rotation(rng, pos, node.joint_pos))
