"""Evolution of the genotype: recombination, grafting and mutation (paper section 2.2).

- :func:`crossover` is the paper's recombination (section 2.2.1): both parents' nodes are
  numbered in LR (pre-order) traversal; with random ``n`` and ``m``, the child takes positions
  ``[0, n)`` from the first parent (dropping the second's), the next ``m`` positions from the
  second (dropping the first's), and so on, alternating, until no nodes are left. A taken node
  keeps its position (its children's ids are positions too, so a leg stays a leg). Then repair
  (:func:`repair`): links whose target position is empty are removed and nodes left unreachable
  get a new random link from a node that was their parent position, so every node taken is kept.
  It returns **one** child; call it twice (or with the parents swapped) for two.
- :func:`graft` is Sims' grafting: copy the first parent, re-point one of its links (a new one if
  it has none) to a random node of the second, append that node's subgraph, drop orphans.
- :func:`mutate` follows section 2.2.2 and Sims: for every node, with probabilities scaled by
  1 / (number of nodes), delete it (removing every reference), add a child, or modify it in the
  paper's six steps (joint axis and position, body size, mobility, force coefficient, recursion,
  symmetry), drawing from the predefined value lists of :mod:`.genotype`; link parameters change
  too; then the neural networks mutate (weights, parameters, functions, connections, neurons
  added or deleted, rates scaled by 1 / network size); unreachable nodes are collected.

Every operator takes an explicit ``rng``, never modifies its inputs, and returns a valid
:class:`~coursekit.creatures.genotype.Creature`. The three are plain functions with the same
signatures students implement in the exercises, so theirs plug in wherever these do.
"""

from __future__ import annotations

import copy
from collections.abc import Sequence

import numpy as np

from .generation import (
    AXES,
    COORDS,
    FORCES,
    ROTATIONS,
    SCALES,
    SIZES,
    choice,
    joint_types_arg,
    limit_values,
    mirror_axis,
    random_face_point,
    random_limits,
    random_link,
    random_node,
    random_recursion,
)
from .genotype import Creature
from .morphology import (
    MAX_CHILDREN,
    MAX_NODES,
    MAX_RECURSION_ENTRIES,
    MAX_RECURSIVE_LIMIT,
    MAX_SYMMETRY,
    Node,
    Symmetry,
    preorder,
    renumber,
)
from .neural import (
    DOF_SENSOR_BASE,
    FUNCTION_NAMES,
    MAX_BRAIN_NEURONS,
    MAX_INPUTS,
    MAX_NEURONS,
    N_SENSORS,
    PARAM_RANGE,
    WEIGHT_LIMIT,
    random_input,
    random_neuron,
    random_param,
)


def _check(c, name: str) -> None:
    if not isinstance(c, Creature):
        raise TypeError(f"{name}: expected a Creature, got {type(c).__name__}")


def _check_rng(rng) -> None:
    if not isinstance(rng, np.random.Generator):
        raise TypeError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")


# ------------------------------------------------------------------------------- repair


def repair(nodes: list, brain: list, rng: np.random.Generator, *, reattach: bool = True) -> Creature:
    """Make a valid creature from possibly broken parts (used by every operator).

    Args:
        nodes: list of :class:`Node` or ``None`` (an empty position); node 0 must exist.
        brain: brain neurons.
        rng: for the random elements repair adds.
        reattach: re-link unreachable nodes (recombination) instead of collecting them.

    Links to empty or out-of-range positions are removed; links closing a cycle are removed;
    nodes left unreachable are re-attached by a new random link (from their old parent position
    when it can take one, else from any reachable node with room); symmetry entries without a
    matching link are dropped; nodes are renumbered in pre-order (garbage past ``MAX_NODES`` is
    collected); neural references the new networks cannot hold are redrawn at random.
    """
    nodes = list(nodes)
    n = len(nodes)
    old_parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        if node is None:
            continue
        for c in node.children:
            if 0 <= c.child < n and nodes[c.child] is not None:
                old_parent.setdefault(c.child, i)
        node.children = [c for c in node.children if 0 <= c.child < n and nodes[c.child] is not None]
    _break_cycles(nodes)
    # Re-attach orphans (a taken node keeps its place in the child when it can).
    while reattach:
        reach = set(preorder(nodes))
        orphans = [i for i in range(n) if nodes[i] is not None and i not in reach]
        if not orphans:
            break
        i = orphans[0]
        hosts = [h for h in reach if len(nodes[h].children) < MAX_CHILDREN and not _reaches(nodes, i, h)]
        p = old_parent.get(i)
        host = p if p in hosts else (choice(rng, sorted(hosts)) if hosts else None)
        if host is None:
            nodes[i] = None  # nowhere to hang it: collected
            continue
        nodes[host].children.append(random_link(rng, i, nodes[host], nodes[i]))
    # Garbage collection, pre-order renumbering and the node cap.
    kept = preorder(nodes)[:MAX_NODES]
    keep = set(kept)
    for i in kept:
        node = nodes[i]
        node.children = [c for c in node.children if c.child in keep]
        linked, seen, sym = {c.child for c in node.children}, set(), []
        for s in node.symmetry:
            if s.child in linked and s.child not in seen:
                sym.append(s)
                seen.add(s.child)
        node.symmetry = sym[:MAX_SYMMETRY]
    out = renumber([nodes[i] if i in keep else None for i in range(n)])
    brain = brain[:MAX_BRAIN_NEURONS]
    _repair_neural(out, brain, rng)
    return Creature(out, brain)


def _reaches(nodes: list, a: int, b: int) -> bool:
    """True when ``b`` is reachable from ``a`` (so a link b -> a would close a cycle)."""
    seen, stack = set(), [a]
    while stack:
        i = stack.pop()
        if i == b:
            return True
        if i in seen:
            continue
        seen.add(i)
        stack.extend(c.child for c in nodes[i].children)
    return False


def _break_cycles(nodes: list) -> None:
    """Remove every link that closes a directed cycle (depth-first back edges)."""
    state = {}

    def visit(i):
        state[i] = 1
        keep = []
        for c in nodes[i].children:
            s = state.get(c.child, 0)
            if s == 1:
                continue  # back edge
            keep.append(c)
            if s == 0:
                visit(c.child)
        nodes[i].children = keep
        state[i] = 2

    for i in range(len(nodes)):
        if nodes[i] is not None and i not in state:
            visit(i)


def _fix_input(inp, rng, *, brain: bool, n_local: int, n_brain: int, n_children: int, dof: int = 1):
    if inp is None:
        return None
    m = inp.morph
    bad = False
    if m is not None:
        if m == -2 or (brain and m == 0):
            bad = inp.ctrl >= n_brain
        elif m == 0:  # a further DOF's sensor stays valid while the joint has that DOF
            bad = inp.ctrl >= n_local and not DOF_SENSOR_BASE <= inp.ctrl < DOF_SENSOR_BASE + 2 * (dof - 1)
    if bad:
        return random_input(rng, brain=brain, n_local=n_local, n_brain=n_brain, n_children=n_children, dof=dof)
    return inp


def _repair_neural(nodes: list, brain: list, rng) -> None:
    nb = len(brain)
    for neuron in brain:
        neuron.inputs = [_fix_input(i, rng, brain=True, n_local=nb, n_brain=nb, n_children=1) for i in neuron.inputs]
    for node in nodes:
        node.neurons = node.neurons[:MAX_NEURONS]
        n_local = N_SENSORS + len(node.neurons)
        nc = max(1, len(node.children) + len(node.recursion))
        kw = dict(brain=False, n_local=n_local, n_brain=nb, n_children=nc, dof=node.dof)
        for neuron in node.neurons:
            neuron.inputs = [_fix_input(i, rng, **kw) for i in neuron.inputs]
        node.effectors = [_fix_input(e, rng, **kw) for e in node.effectors][: node.dof]
        node.effectors += [None] * (node.dof - len(node.effectors))


# ---------------------------------------------------------------------------- crossover


def crossover(a: Creature, b: Creature, rng: np.random.Generator) -> Creature:
    """The paper's recombination (section 2.2.1); returns one child (see the module docstring).

    The brain travels with the root: it is taken from the parent that gives position 0.
    """
    _check(a, "crossover.a")
    _check(b, "crossover.b")
    _check_rng(rng)
    pa = [a.nodes[i] for i in preorder(a.nodes)]  # already pre-order for valid creatures
    pb = [b.nodes[i] for i in preorder(b.nodes)]
    L = max(len(pa), len(pb))
    n = int(rng.integers(1, L + 1))
    m = int(rng.integers(1, L + 1))
    child, pos, take_first = [], 0, True
    while pos < L:
        span = n if take_first else m
        src = pa if take_first else pb
        for k in range(pos, min(pos + span, L)):
            child.append(copy.deepcopy(src[k]) if k < len(src) else None)
        pos += span
        take_first = not take_first
    while child and child[-1] is None:
        child.pop()
    brain = copy.deepcopy(a.brain)
    return repair(child, brain, rng)


# -------------------------------------------------------------------------------- graft


def graft(a: Creature, b: Creature, rng: np.random.Generator) -> Creature:
    """Sims' grafting: ``a`` with one link re-pointed into a random subgraph of ``b``.

    The subgraph (every node of ``b`` reachable from the chosen one) is appended to ``a``'s
    nodes; nodes of ``a`` that lose their last link are dropped. The brain is ``a``'s; neural
    references of the appended nodes that ``a``'s brain cannot hold are redrawn. Nodes past
    ``MAX_NODES`` in LR order are collected.
    """
    _check(a, "graft.a")
    _check(b, "graft.b")
    _check_rng(rng)
    nodes = copy.deepcopy(a.nodes)
    start = int(rng.integers(len(b.nodes)))
    sub = _reachable(b.nodes, start)
    base = len(nodes)
    remap = {old: base + k for k, old in enumerate(sub)}
    for old in sub:
        node = copy.deepcopy(b.nodes[old])
        for c in node.children:
            c.child = remap[c.child]
        for s in node.symmetry:
            s.child = remap[s.child]
        nodes.append(node)
    links = [(i, k) for i, node in enumerate(nodes[:base]) for k in range(len(node.children))]
    if links:
        i, k = links[int(rng.integers(len(links)))]
        old_target = nodes[i].children[k].child
        nodes[i].children[k].child = base
        if not any(c.child == old_target for c in nodes[i].children):
            nodes[i].symmetry = [s for s in nodes[i].symmetry if s.child != old_target]
    else:
        i = int(rng.integers(base))
        nodes[i].children.append(random_link(rng, base, nodes[i], nodes[base]))
    return repair(nodes, copy.deepcopy(a.brain), rng, reattach=False)


def _reachable(nodes: list, start: int) -> list[int]:
    order, seen, stack = [], set(), [start]
    while stack:
        i = stack.pop()
        if i in seen:
            continue
        seen.add(i)
        order.append(i)
        stack.extend(c.child for c in reversed(nodes[i].children))
    return order


# ----------------------------------------------------------------------------- mutation


def _step(rng, values: tuple, current) -> float:
    """Move to a neighbour of ``current`` in the sorted value list (or a random entry)."""
    vals = list(values)
    if current in vals:
        k = vals.index(current) + choice(rng, (-1, 1))
        return vals[min(max(k, 0), len(vals) - 1)]
    return choice(rng, vals)


def _mutate_joint(node: Node, rng, joint_types=None) -> None:
    """Step 1: joint axis and joint position (rarely the joint type: revolute and prismatic
    swap, or with ``joint_types`` another of those; the effectors follow the DOFs in repair)."""
    r = rng.random()
    if r < 0.4:
        node.joint_axis = choice(rng, AXES)
    elif r < 0.8:
        node.joint_pos = random_face_point(rng)
    else:
        if joint_types is None:
            node.joint_type = "prismatic" if node.joint_type == "revolute" else "revolute"
        else:
            others = [t for t in joint_types if t != node.joint_type]
            node.joint_type = choice(rng, others) if others else node.joint_type
        _mutate_limits(node, rng, redraw=True)


def _mutate_limits(node: Node, rng, redraw: bool = False) -> None:
    """Step 3: joint mobility (of one DOF, drawn when the joint has several)."""
    if redraw:
        vals = limit_values(node.joint_type)
        node.limits = (-choice(rng, vals), choice(rng, vals))
        node.extra_limits = [random_limits(rng, node.joint_type, d) for d in range(1, node.dof)]
        return
    d = int(rng.integers(node.dof)) if node.dof > 1 else 0
    vals = limit_values(node.joint_type, d)
    lim = node.dof_limits[d]
    lo, hi = -lim[0], lim[1]
    new = (-_step(rng, vals, lo), hi) if rng.random() < 0.5 else (-lo, _step(rng, vals, hi))
    if d == 0:
        node.limits = new
    else:
        node.extra_limits = [new if k == d - 1 else e for k, e in enumerate(node.extra_limits)]


def _mutate_size(node: Node, rng) -> None:
    """Step 2: body size (one dimension steps through the size list)."""
    k = int(rng.integers(3))
    size = list(node.size)
    size[k] = _step(rng, SIZES, size[k])
    node.size = tuple(size)


def _mutate_force(node: Node, rng) -> None:
    """Step 4: force coefficient (a step, or a sign flip)."""
    node.force = -node.force if rng.random() < 0.3 else _step(rng, FORCES, node.force)


def _mutate_recursion(node: Node, rng) -> None:
    """Step 5: recursion entries and the recursive limit."""
    r = rng.random()
    if not node.recursion or (r < 0.3 and len(node.recursion) < MAX_RECURSION_ENTRIES):
        node.recursion.append(random_recursion(rng, node))
        node.recursive_limit = max(node.recursive_limit, 1)
    elif r < 0.5:
        node.recursion.pop(int(rng.integers(len(node.recursion))))
    elif r < 0.8:
        node.recursive_limit = int(min(max(node.recursive_limit + choice(rng, (-1, 1)), 0), MAX_RECURSIVE_LIMIT))
    else:
        e = node.recursion[int(rng.integers(len(node.recursion)))]
        e.scale = _step(rng, SCALES, e.scale)
        e.pos = random_face_point(rng)


def _mutate_symmetry(node: Node, rng) -> None:
    """Step 6: symmetry entries (add, remove, change the mirror axis)."""
    linked = sorted({c.child for c in node.children} - {s.child for s in node.symmetry})
    r = rng.random()
    if linked and len(node.symmetry) < MAX_SYMMETRY and (r < 0.5 or not node.symmetry):
        child = choice(rng, linked)
        axis = mirror_axis(rng, node, child)
        if axis is not None:
            node.symmetry.append(Symmetry(child, axis))
    elif node.symmetry and r < 0.75:
        node.symmetry.pop(int(rng.integers(len(node.symmetry))))
    elif node.symmetry:
        s = node.symmetry[int(rng.integers(len(node.symmetry)))]
        axis = mirror_axis(rng, node, s.child)
        if axis is not None:
            s.axis = axis


MODIFY_STEPS = (_mutate_joint, _mutate_size, _mutate_limits, _mutate_force, _mutate_recursion, _mutate_symmetry)


def _mutate_link(link, n_nodes: int, rng) -> None:
    """Sims' connection mutation: position, orientation, scale, flags, or re-pointing."""
    r = rng.random()
    if r < 0.25:
        link.pos = tuple(_step(rng, COORDS, v) if rng.random() < 0.5 else v for v in link.pos)
        if max(abs(v) for v in link.pos) < 1.0:
            link.pos = random_face_point(rng)
    elif r < 0.45:
        link.rot = choice(rng, ROTATIONS)
    elif r < 0.6:
        link.scale = _step(rng, SCALES, link.scale)
    elif r < 0.7:
        link.terminal_only = not link.terminal_only
    elif r < 0.8:
        link.reflect = choice(rng, (-1, 0, 1, 2))
    else:
        link.child = int(rng.integers(n_nodes))  # repair drops it if it closes a cycle


def mutate(c: Creature, rng: np.random.Generator, *, rate: float = 1.0, p_delete: float = 0.15,
           p_add: float = 0.25, p_modify: float = 1.0, p_link: float = 0.5, p_neural: float = 1.0,
           joint_types: Sequence[str] | None = None) -> Creature:
    """Mutate a copy of ``c`` (paper section 2.2.2; see the module docstring).

    Args:
        c: the parent (not modified).
        rng: the random generator.
        rate: multiplies every probability (Sims mutates mated offspring at reduced rates).
        p_delete, p_add, p_modify: per-node chances, each divided by the node count.
        p_link: per-link chance of a connection mutation, divided by the node count.
        p_neural: per-element chance of a neural mutation, divided by the network's size.
        joint_types: the joint types new nodes and joint-type changes draw from (names of
            :data:`~.morphology.JOINT_AXES`); default revolute and prismatic, as Sims' 1-DOF runs.

    Returns:
        A new valid :class:`Creature`.
    """
    _check(c, "mutate.c")
    _check_rng(rng)
    for name, p in (("rate", rate), ("p_delete", p_delete), ("p_add", p_add), ("p_modify", p_modify),
                    ("p_link", p_link), ("p_neural", p_neural)):
        if not (isinstance(p, (int, float)) and 0.0 <= p <= 10.0):
            raise ValueError(f"mutate.{name}: must be a number in [0, 10], got {p!r}")
    types = None if joint_types is None else joint_types_arg(joint_types, "mutate")
    nodes: list = copy.deepcopy(c.nodes)
    brain = copy.deepcopy(c.brain)
    n0 = len(nodes)
    scale = rate / n0
    # Morphology first (Sims: the outer graph before the inner neural graphs).
    for i in range(n0):
        node = nodes[i]
        r = rng.random()
        if i > 0 and r < p_delete * scale:
            nodes[i] = None  # repair removes every link and symmetry entry naming it
            continue
        if rng.random() < p_add * scale and len(node.children) < MAX_CHILDREN:
            if len(nodes) < MAX_NODES and rng.random() < 0.7:
                new = random_node(rng, types)
                nodes.append(new)
                node.children.append(random_link(rng, len(nodes) - 1, node, new))
            else:
                j = int(rng.integers(len(nodes)))
                if nodes[j] is not None:
                    node.children.append(random_link(rng, j, node, nodes[j]))
        if rng.random() < p_modify * scale:
            picked = [f for f in MODIFY_STEPS if rng.random() < 1.0 / 3.0] or [choice(rng, MODIFY_STEPS)]
            for f in picked:
                if f is _mutate_joint:
                    f(node, rng, types)
                else:
                    f(node, rng)
        for link in node.children:
            if rng.random() < p_link * scale:
                _mutate_link(link, len(nodes), rng)
    for node in nodes:
        if node is not None:
            node.children = [k for k in node.children if 0 <= k.child < len(nodes)]
    creature = repair(nodes, brain, rng, reattach=False)
    # Then the neural networks.
    _mutate_networks(creature, rng, p_neural * rate)
    return repair(creature.nodes, creature.brain, rng, reattach=False)


def _mutate_weight(w: float, rng) -> float:
    if rng.random() < 0.1:
        w = -w
    w = w + rng.normal(0.0, 0.3 * max(abs(w), 0.1))
    return float(np.clip(round(w, 4), -WEIGHT_LIMIT, WEIGHT_LIMIT))


def _mutate_network(neurons: list, effectors: list | None, rng, p: float, *, brain: bool, n_brain: int,
                    n_children: int, cap: int, dof: int = 1) -> None:
    size = len(neurons) + (len(effectors) if effectors else 0) + 1
    q = p / size

    def kw():
        return dict(brain=brain, n_local=(0 if brain else N_SENSORS) + len(neurons), n_brain=n_brain,
                    n_children=n_children, dof=dof)

    for neuron in neurons:
        if rng.random() < q:
            r = rng.random()
            if r < 0.35:
                inp = neuron.inputs[int(rng.integers(len(neuron.inputs)))]
                inp.weight = _mutate_weight(inp.weight, rng)
            elif r < 0.5 and neuron.func in PARAM_RANGE:
                lo, hi = PARAM_RANGE[neuron.func]
                neuron.param = float(np.clip(neuron.param + rng.normal(0.0, 0.2 * (hi - lo)), lo, hi))
            elif r < 0.65:
                neuron.func = choice(rng, FUNCTION_NAMES)
                lo, hi = PARAM_RANGE.get(neuron.func, (0.0, 0.0))
                if not lo <= neuron.param <= hi:
                    neuron.param = random_param(neuron.func, rng)
            elif r < 0.8:
                neuron.inputs[int(rng.integers(len(neuron.inputs)))] = random_input(rng, **kw())
            elif r < 0.9 and len(neuron.inputs) < MAX_INPUTS:
                neuron.inputs.append(random_input(rng, **kw()))
            elif len(neuron.inputs) > 1:
                neuron.inputs.pop(int(rng.integers(len(neuron.inputs))))
    if effectors:
        for k, e in enumerate(effectors):
            if rng.random() < q:
                if e is None or rng.random() < 0.5:
                    effectors[k] = random_input(rng, **kw())
                else:
                    e.weight = _mutate_weight(e.weight, rng)
    if rng.random() < q and len(neurons) < cap:
        neurons.append(random_neuron(rng, **{**kw(), "n_local": kw()["n_local"] + 1,
                                             "n_brain": n_brain + (1 if brain else 0)}))


def _delete_neuron(creature: Creature, node: Node | None, k: int, rng) -> None:
    """Delete neuron ``k`` of ``node`` (None: the brain), fixing the references that can be
    tracked: same-network ids (and, for the brain, every ``-2`` id) shift down; those naming it
    are redrawn by repair."""
    gone = N_SENSORS + k if node is not None else k

    def shift(inp, hit_same: bool):
        if inp is None or inp.morph is None:
            return inp
        if hit_same:
            if inp.ctrl == gone:
                inp.ctrl = 10**6  # out of range: repair redraws it
            elif inp.ctrl > gone and (node is None or inp.ctrl < DOF_SENSOR_BASE):  # not a further DOF's sensor
                inp.ctrl -= 1
        return inp

    if node is not None:
        node.neurons.pop(k)
        for neuron in node.neurons:
            for inp in neuron.inputs:
                shift(inp, inp.morph == 0)
        for e in node.effectors:
            shift(e, e is not None and e.morph == 0)
    else:
        creature.brain.pop(k)
        for neuron in creature.brain:
            for inp in neuron.inputs:
                shift(inp, inp.morph in (-2, 0))
        for nd in creature.nodes:
            for neuron in nd.neurons:
                for inp in neuron.inputs:
                    shift(inp, inp.morph == -2)
            for e in nd.effectors:
                shift(e, e is not None and e.morph == -2)


def _mutate_networks(creature: Creature, rng, p: float) -> None:
    nb = len(creature.brain)
    for node in creature.nodes:
        nc = max(1, len(node.children) + len(node.recursion))
        _mutate_network(node.neurons, node.effectors, rng, p, brain=False, n_brain=nb, n_children=nc, cap=MAX_NEURONS,
                        dof=node.dof)
        if node.neurons and rng.random() < p / (len(node.neurons) + 2):
            _delete_neuron(creature, node, int(rng.integers(len(node.neurons))), rng)
    _mutate_network(creature.brain, None, rng, p, brain=True, n_brain=nb, n_children=1, cap=MAX_BRAIN_NEURONS)
    if creature.brain and rng.random() < p / (len(creature.brain) + 2):
        _delete_neuron(creature, None, int(rng.integers(len(creature.brain))), rng)
