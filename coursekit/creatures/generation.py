"""Making genotypes: the predefined value lists, random elements, random creatures and the
hand-designed swimmers (paper sections 2.1.1 and 2.2.2).

Random genomes and mutation draw from "a predefined list of valid values" (section 2.2.2): the
value lists below (sizes, face coordinates, forces, limits, scales, joint axes, the 24 cube
rotations of a link). :func:`random_genotype` draws a whole creature (a random tree over its
nodes, a few shared links, recursion and symmetry entries, neurons, a rhythm: oscillators of one
frequency driving some of its effectors, :func:`add_rhythm`), pruned until its expansion fits the
part cap; :func:`figure1_snake` and :func:`paddle_turtle` build the paper's Figure 1
and a second, rowing swimmer. :class:`~coursekit.creatures.genotype.Creature` offers them as
``Creature.random``, ``Creature.figure1_snake`` and ``Creature.paddle_turtle``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from typing import NamedTuple, TypeVar

import numpy as np

from .morphology import (
    IDENTITY,
    JOINT_AXES,
    limit_bound,
    MAX_CHILDREN,
    MAX_NODES,
    MAX_RECURSIVE_LIMIT,
    MAX_SYMMETRY,
    ChildLink,
    Node,
    Recursion,
    Symmetry,
    renumber,
)
from .neural import MAX_BRAIN_NEURONS, MAX_NEURONS, N_SENSORS, Input, Neuron, is_int, is_real, random_input, random_neuron
from .phenotype import MAX_PARTS, expand

T = TypeVar("T")

__all__ = ["SIZES", "COORDS", "FORCES", "REVOLUTE_LIMITS", "PRISMATIC_LIMITS", "DEFAULT_JOINT_TYPES",
           "joint_types_arg", "limit_values", "random_limits", "SCALES", "AXES", "ROTATIONS", "FACES",
           "choice", "random_face_point", "facing_rotation", "mirror_axis", "random_node", "random_link",
           "random_recursion", "random_genotype", "RHYTHM", "RHYTHM_HZ", "add_rhythm", "figure1_snake", "paddle_turtle"]

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


#: The default chance that a random creature's effector is driven by an oscillator.
RHYTHM = 0.5
#: The frequencies (Hz) a random creature's oscillators share: one stroke every 2 s to 0.4 s.
RHYTHM_HZ = (0.5, 2.5)


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


#: The 24 rotations of the cube: the predefined orientations of links (the first is the identity).
ROTATIONS = _cube_rotations()
assert ROTATIONS[0] == IDENTITY
_ROTATION_ARRAY = np.array(ROTATIONS)
FACES = tuple(tuple(float(v) for v in f) for f in [(-1, 0, 0), (1, 0, 0), (0, -1, 0), (0, 1, 0), (0, 0, -1), (0, 0, 1)])


# ----------------------------------------------------------------------- random elements

def choice(rng: np.random.Generator, seq: Sequence[T]) -> T:
    """One element of ``seq``, uniformly (one ``rng.integers`` draw)."""
    return seq[int(rng.integers(len(seq)))]


def random_face_point(rng: np.random.Generator) -> tuple:
    """A point on the unit box surface from the predefined coordinates (one component ±1)."""
    k = int(rng.integers(3))
    p = [choice(rng, COORDS) for _ in range(3)]
    p[k] = choice(rng, (-1.0, 1.0))
    return tuple(p)


def facing_rotation(rng, parent_pos, child_joint_pos) -> tuple:
    """A cube rotation turning the child's joint face towards the parent's attachment face."""
    pn = np.asarray(parent_pos, float)
    cn = np.asarray(child_joint_pos, float)
    pn = np.where(np.abs(pn) == np.abs(pn).max(), np.sign(pn), 0.0)
    cn = np.where(np.abs(cn) == np.abs(cn).max(), np.sign(cn), 0.0)
    # Want R @ cn ≈ -pn: the joint face of the child points back at the parent.
    good = np.nonzero(np.abs(_ROTATION_ARRAY @ cn + pn).max(axis=1) < 1e-9)[0]
    return ROTATIONS[int(choice(rng, good))] if good.size else choice(rng, ROTATIONS)


def mirror_axis(rng: np.random.Generator, node: Node, child: int) -> int | None:
    """A random axis that moves every link to ``child`` when mirrored (so copies don't
    coincide), or None when there is none."""
    links = [c.pos for c in node.children if c.child == child]
    axes = [k for k in range(3) if all(abs(p[k]) > 0 for p in links)]
    return choice(rng, axes) if links and axes else None


#: The joint types random creatures and mutation draw from by default (as many revolute draws as
#: before multi-DOF joints existed, so seeds give the same creatures).
DEFAULT_JOINT_TYPES = ("revolute", "revolute", "revolute", "prismatic")


def joint_types_arg(joint_types: Sequence[str] | None, where: str) -> tuple:
    """``joint_types`` checked: a non-empty sequence of names of :data:`~.morphology.JOINT_AXES`
    (repeats weight the draw); None gives :data:`DEFAULT_JOINT_TYPES`."""
    if joint_types is None:
        return DEFAULT_JOINT_TYPES
    if isinstance(joint_types, str) or not isinstance(joint_types, Sequence) or not joint_types:
        raise ValueError(f"{where}.joint_types: need a non-empty list of joint type names from {list(JOINT_AXES)}, got {joint_types!r}")
    bad = [t for t in joint_types if t not in JOINT_AXES]
    if bad:
        raise ValueError(f"{where}.joint_types: unknown joint type(s) {bad}; allowed: {list(JOINT_AXES)}")
    return tuple(joint_types)


def limit_values(joint_type: str, dof: int = 0) -> tuple:
    """The predefined limit magnitudes of DOF ``dof`` of a joint type (within
    :func:`~.morphology.limit_bound`: a spherical joint's bend is kept from gimbal lock)."""
    vals = PRISMATIC_LIMITS if joint_type == "prismatic" else REVOLUTE_LIMITS
    bound = limit_bound(joint_type, dof)
    return tuple(v for v in vals if v <= bound)


def random_limits(rng: np.random.Generator, joint_type: str, dof: int = 0) -> tuple:
    """A random ``(lo, hi)`` for DOF ``dof`` from :func:`limit_values` (two draws)."""
    vals = limit_values(joint_type, dof)
    lim = choice(rng, vals)
    return (-lim, choice(rng, vals))


def random_node(rng: np.random.Generator, joint_types: Sequence[str] | None = None) -> Node:
    """A random node with no links and no neurons (effector: constant 0 until wired); its joint
    type is drawn from ``joint_types`` (default :data:`DEFAULT_JOINT_TYPES`)."""
    jt = choice(rng, joint_types_arg(joint_types, "random_node"))
    limits = random_limits(rng, jt)
    node = Node(
        size=tuple(choice(rng, SIZES[2:]) for _ in range(3)), joint_type=jt, joint_pos=choice(rng, FACES),
        joint_axis=choice(rng, AXES), limits=limits, force=choice(rng, FORCES),
    )
    node.extra_limits = [random_limits(rng, jt, d) for d in range(1, node.dof)]
    node.effectors = [None] * node.dof
    return node


def random_link(rng: np.random.Generator, child: int, parent_node: Node, child_node: Node) -> ChildLink:
    """A random link to ``child`` whose orientation faces the child's joint to the parent."""
    pos = random_face_point(rng)
    return ChildLink(child, pos, facing_rotation(rng, pos, child_node.joint_pos), choice(rng, SCALES),
                     bool(rng.random() < 0.2), -1)


def random_recursion(rng: np.random.Generator, node: Node) -> Recursion:
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
    return Recursion(pos, choice(rng, SCALES), facing_rotation(rng, pos, node.joint_pos))


# ------------------------------------------------------------------------- creatures

class _Draft(NamedTuple):
    """Nodes and brain being drawn (not yet a validated ``Creature``); :func:`.phenotype.expand` reads both."""

    nodes: list
    brain: list


def _int_range(pair) -> tuple:
    """``(lo, hi)`` of an inclusive range of ints, or ``(1, 0)`` (an empty range, refused by the caller)."""
    try:
        a, b = pair
    except (TypeError, ValueError):
        return 1, 0
    return (a, b) if is_int(a) and is_int(b) else (1, 0)


def random_genotype(rng: np.random.Generator, *, n_nodes: int | tuple = (1, 5), max_children: int = 3,
                    neurons: tuple = (0, 3), brain_neurons: tuple = (0, 3), p_recursion: float = 0.3,
                    p_symmetry: float = 0.4, max_parts: int | None = None,
                    joint_types: Sequence[str] | None = None, rhythm: float = RHYTHM) -> tuple[list, list]:
    """The nodes and brain of a random valid creature (``Creature.random`` wraps them).

    Args:
        rng: the random generator.
        n_nodes: node count, an int or an inclusive range ``(lo, hi)`` within [1, MAX_NODES].
        max_children: most child links per node (<= MAX_CHILDREN).
        neurons: inclusive range of randomly wired local neurons per node (within [0, MAX_NEURONS];
            ``rhythm`` adds its oscillators to them, within the cap).
        brain_neurons: inclusive range of brain neurons (within [0, MAX_BRAIN_NEURONS]).
        p_recursion, p_symmetry: chance a node recurses / a link gets a symmetric copy.
        max_parts: the expansion must fit this many parts without truncation (default
            ``phenotype.MAX_PARTS``); recursion and symmetry entries are pruned at random
            until it does.
        joint_types: the joint types nodes draw from (names of
            :data:`~.morphology.JOINT_AXES`, repeats weighting the draw; default
            :data:`DEFAULT_JOINT_TYPES`, 1-DOF joints only).
        rhythm: the chance that an effector is driven by an oscillator (:func:`add_rhythm`); 0
            draws the creatures of the kit before rhythm existed, number for number.

    Returns:
        ``(nodes, brain)``: nodes numbered in LR pre-order, all reachable, acyclic.
    """
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"Creature.random: rng must be a numpy.random.Generator, got {type(rng).__name__}")
    lo, hi = (n_nodes, n_nodes) if is_int(n_nodes) else _int_range(n_nodes)
    if not 1 <= lo <= hi <= MAX_NODES:
        raise ValueError(f"Creature.random.n_nodes: need 1 <= lo <= hi <= {MAX_NODES}, got {n_nodes!r}")
    if not is_int(max_children) or not 1 <= max_children <= MAX_CHILDREN:
        raise ValueError(f"Creature.random.max_children: must be in [1, {MAX_CHILDREN}], got {max_children!r}")
    for name, pair, cap in (("neurons", neurons, MAX_NEURONS), ("brain_neurons", brain_neurons, MAX_BRAIN_NEURONS)):
        a, b = _int_range(pair)
        if not 0 <= a <= b <= cap:
            raise ValueError(f"Creature.random.{name}: need 0 <= lo <= hi <= {cap}, got {pair!r}")
    for name, p in (("p_recursion", p_recursion), ("p_symmetry", p_symmetry)):
        if not (is_real(p) and 0.0 <= p <= 1.0):
            raise ValueError(f"Creature.random.{name}: must be a probability in [0, 1], got {p!r}")
    if not (is_real(rhythm) and 0.0 <= rhythm <= 1.0):
        raise ValueError(f"Creature.random.rhythm: must be a probability in [0, 1], got {rhythm!r}")
    max_parts = MAX_PARTS if max_parts is None else max_parts
    if not is_int(max_parts) or max_parts < hi:
        raise ValueError(f"Creature.random.max_parts: must be an int >= the largest node count {hi}, got {max_parts!r}")
    joint_types = joint_types_arg(joint_types, "Creature.random")
    count = int(rng.integers(lo, hi + 1))
    nodes = [random_node(rng, joint_types) for _ in range(count)]
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
        kw = dict(brain=False, n_local=n_local, n_brain=nb, n_children=nc, dof=node.dof)
        node.neurons = [random_neuron(rng, **kw) for _ in range(k)]
        node.effectors = [random_input(rng, **kw) for _ in range(node.dof)]
    if rhythm > 0:
        add_rhythm(rng, nodes, rhythm)
    draft = _Draft(renumber(nodes), brain)
    # Sims discards creatures over the part cap; we prune multipliers until it fits.
    while expand(draft, max_parts).body.meta["truncated"]:
        _prune_one(draft, rng)
        draft = _Draft(renumber(draft.nodes), draft.brain)
    return draft.nodes, draft.brain


def add_rhythm(rng: np.random.Generator, nodes: list, p: float) -> None:
    """Drive each effector, with probability ``p``, by an oscillator (in place).

    A creature moves its joints back and forth, but reciprocal strokes barely move it through
    viscous water: it swims when joints beat at one frequency with different phases (a wave
    along a body, paddles a quarter stroke apart). Random sensor-and-neuron wiring rarely does
    that: in 200 random creatures (seed 0, at most 16 parts) the fastest covered 0.007 body
    lengths a second over 10 s, and evolution at a lecture's size (40 creatures, 12 generations)
    bred 0.014-0.084. So every oscillator of a random creature beats at one frequency drawn from
    :data:`RHYTHM_HZ`, with its own random phase and weight. Each is a neuron added to the
    effector's own part (within :data:`~.neural.MAX_NEURONS`; the parts made from one node beat in
    step); the brain is left as drawn, so ``brain_neurons`` still bounds it and ``neurons``
    counts the randomly wired neurons of a part. Mutation and mating then work on them as on any
    neuron: this only changes where evolution starts (``benchmarks/NOTES.md``, "Rhythm").
    """
    hz = float(np.round(rng.uniform(*RHYTHM_HZ), 3))
    for node in nodes:
        for e in range(node.dof):
            if rng.random() >= p or len(node.neurons) >= MAX_NEURONS:
                continue
            phase = float(np.round(rng.uniform(-math.pi, math.pi), 3))
            node.neurons.append(Neuron("oscillate_wave", [Input(None, 0, phase)], hz))
            node.effectors[e] = Input(0, N_SENSORS + len(node.neurons) - 1, float(np.round(rng.choice((-1.0, 1.0)) * rng.uniform(0.5, 2.0), 3)))


def _prune_one(creature: _Draft, rng) -> None:
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
    kind, where = choice(rng, options)
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



def figure1_snake(segments: int = 4) -> tuple[list, list]:
    """The paper's Figure 1: a snake with two legs at the last limb, from exactly two nodes.

    Node 0 (a body segment) repeats itself ``segments - 1`` times through its recursion
    attribute; its link to node 1 (a leg) is terminal-only, so it appears on the last
    segment only, and a symmetry entry mirrors it across the segment's y plane.

    Args:
        segments: number of body segments (1..MAX_RECURSIVE_LIMIT + 1).
    """
    if not is_int(segments) or not 1 <= segments <= MAX_RECURSIVE_LIMIT + 1:
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
    return [segment, leg], brain


def paddle_turtle() -> tuple[list, list]:
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
    return [body, arm, blade], brain
