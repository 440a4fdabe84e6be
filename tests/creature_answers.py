"""Answers to exercise 05 as a student might write them from the notebook's text: buggy ones that get
an operator's definition (or a detail) wrong, and correct ones that differ from the solution.

Each function uses only names the exercise notebook has (its imports and its helper cells
``reaches``, ``pick``, ``STEPS``), so its source can stand in for the notebook's cell as it is
(:func:`as_cell`); here those names come from the solution notebook.
"""

import copy
import inspect

import numpy as np

from coursekit.creatures import Creature
from coursekit.creatures.genotype import MAX_CHILDREN, MAX_NODES, SIZES, preorder, random_link, random_node, renumber
from solution_cells import solution_functions

SOL = solution_functions("05_creature_operators.ipynb", imports=True)
reaches, pick, STEPS = SOL["reaches"], SOL["pick"], SOL["STEPS"]


def as_cell(fn, name: str) -> str:
    """``fn``'s source as the notebook cell defining ``name``, after the helpers of this module it calls."""
    helpers = [globals()[h] for h in fn.__code__.co_names if h in HELPERS]
    src = inspect.getsource(fn).replace(f"def {fn.__name__}(", f"def {name}(", 1)
    return "\n\n".join([inspect.getsource(h) for h in helpers] + [src])


# -- expansion -------------------------------------------------------------------------------------


def expand_with(creature, max_parts, *, terminal=None, link_depth=None, twin_mirrored=None, terminal_only=True,
                recursion_first=False, twin_first=False):
    """The solution's depth-first expansion; each buggy answer passes one rule of its own."""
    terminal = terminal or (lambda node, depth: depth >= node.recursive_limit or not node.recursion)
    link_depth = link_depth or (lambda depth: 0)
    twin_mirrored = twin_mirrored or (lambda mirrored, flip: mirrored == flip)
    nodes, parts = creature.nodes, []

    def grow(node_id, parent, depth, scale, mirrored):
        me = len(parts)
        node = nodes[node_id]
        parts.append({"node": node_id, "parent": parent, "depth": depth, "scale": scale, "mirrored": mirrored,
                      "gain": node.force if mirrored else abs(node.force)})
        term = terminal(node, depth)
        todo = []
        for link in node.children:
            if terminal_only and link.terminal_only and not term:
                continue
            flip = link.reflect >= 0
            own = [(link.child, link_depth(depth), scale * link.scale, mirrored != flip)]
            twins = [(link.child, link_depth(depth), scale * link.scale, twin_mirrored(mirrored, flip))
                     for s in node.symmetry if s.child == link.child]
            todo += twins + own if twin_first else own + twins
        if not term:
            copies = [(node_id, depth + 1, scale * r.scale, mirrored) for r in node.recursion]
            todo = copies + todo if recursion_first else todo + copies
        for child, d, s, m in todo:
            if len(parts) >= max_parts:
                return
            grow(child, me, d, s, m)

    grow(0, -1, 0, 1.0, False)
    return parts


def expand_limit_ignored(creature, max_parts=64):
    """A node with recursion entries repeats until the part cap stops it (recursive_limit never read)."""
    return expand_with(creature, max_parts, terminal=lambda node, depth: not node.recursion)


def expand_limit_off_by_one(creature, max_parts=64):
    """``depth > recursive_limit`` for terminal: one recursive copy too many."""
    return expand_with(creature, max_parts, terminal=lambda node, depth: depth > node.recursive_limit or not node.recursion)


def expand_depth_kept(creature, max_parts=64):
    """A part reached through a link keeps its parent's depth instead of starting at 0."""
    return expand_with(creature, max_parts, link_depth=lambda depth: depth)


def expand_terminal_only_ignored(creature, max_parts=64):
    """Every link is followed, terminal-only or not."""
    return expand_with(creature, max_parts, terminal_only=False)


def expand_twins_not_mirrored(creature, max_parts=64):
    """The symmetric twin gets the same ``mirrored`` as the original: a twin on the same side."""
    return expand_with(creature, max_parts, twin_mirrored=lambda mirrored, flip: mirrored != flip)


def expand_one_over_the_cap(creature, max_parts=64):
    """The cap tested with ``>``: one part more than max_parts wherever the genotype grows past it."""
    return expand_with(creature, max_parts + 1)


def expand_recursion_first(creature, max_parts=64):
    """Depth first and every part right, but a part grows its recursion copies before the children of its
    links (the notebook: links, each with its symmetric twins, then the recursion copies): the parts are
    numbered differently, and under the cap other parts survive."""
    return expand_with(creature, max_parts, recursion_first=True)


def expand_twin_first(creature, max_parts=64):
    """Depth first and every part right, but each link's mirrored twins come before its own child."""
    return expand_with(creature, max_parts, twin_first=True)


def expand_breadth_first(creature, max_parts=64):
    """The solution's rules for every part, but a queue instead of the recursion: the parts come level by
    level (breadth first), and under the cap the shallow parts survive instead of the first subtrees."""
    parts = []
    queue = [(0, -1, 0, 1.0, False)]
    while queue and len(parts) < max_parts:
        node_id, parent, depth, scale, mirrored = queue.pop(0)
        node = creature.nodes[node_id]
        me = len(parts)
        parts.append({"node": node_id, "parent": parent, "depth": depth, "scale": scale, "mirrored": mirrored,
                      "gain": node.force if mirrored else abs(node.force)})
        terminal = depth >= node.recursive_limit or not node.recursion
        for link in node.children:
            if link.terminal_only and not terminal:
                continue
            flip = link.reflect >= 0
            queue.append((link.child, me, 0, scale * link.scale, mirrored != flip))
            queue += [(link.child, me, 0, scale * link.scale, mirrored == flip)
                      for s in node.symmetry if s.child == link.child]
        if not terminal:
            queue += [(node_id, me, depth + 1, scale * r.scale, mirrored) for r in node.recursion]
    return parts


def expand_cap_keeps_shallow_parts(creature, max_parts=64):
    """The whole expansion in depth-first order, then the cap keeps the max_parts parts nearest the root (the
    body's first levels), still in depth-first order: under the cap, not the first parts of the walk."""
    parts = expand_with(creature, 10**6)
    level = []
    for p in parts:
        level.append(level[p["parent"]] + 1 if p["parent"] >= 0 else 0)
    keep = sorted(sorted(range(len(parts)), key=lambda i: (level[i], i))[:max_parts])
    new_index = {old: k for k, old in enumerate(keep)}
    return [dict(parts[i], parent=new_index.get(parts[i]["parent"], -1)) for i in keep]


def expand_iterative(creature, max_parts=64):
    """Correct: an explicit stack instead of recursion, the same order."""
    parts = []
    stack = [(0, -1, 0, 1.0, False)]
    while stack and len(parts) < max_parts:
        node_id, parent, depth, scale, mirrored = stack.pop()
        node = creature.nodes[node_id]
        me = len(parts)
        parts.append({"node": node_id, "parent": parent, "depth": depth, "scale": scale, "mirrored": mirrored,
                      "gain": node.force if mirrored else abs(node.force)})
        terminal = depth >= node.recursive_limit or len(node.recursion) == 0
        kids = []
        for link in node.children:
            if link.terminal_only and not terminal:
                continue
            m = not mirrored if link.reflect >= 0 else mirrored
            kids.append((link.child, me, 0, scale * link.scale, m))
            for s in node.symmetry:
                if s.child == link.child:
                    kids.append((link.child, me, 0, scale * link.scale, not m))
        if not terminal:
            for r in node.recursion:
                kids.append((node_id, me, depth + 1, scale * r.scale, mirrored))
        stack.extend(reversed(kids))
    return parts


def expand_cap_first(creature, max_parts=64):
    """Correct: a recursive helper that checks the cap when it is entered and returns nothing."""
    parts = []

    def grow(node_id, parent, depth, scale, mirrored):
        if len(parts) >= max_parts:
            return
        node = creature.nodes[node_id]
        me = len(parts)
        gain = node.force if mirrored else abs(node.force)
        parts.append(dict(node=node_id, parent=parent, depth=depth, scale=scale, mirrored=mirrored, gain=gain))
        terminal = not node.recursion or depth >= node.recursive_limit
        for link in node.children:
            if link.terminal_only and not terminal:
                continue
            reflected = link.reflect >= 0
            grow(link.child, me, 0, scale * link.scale, mirrored ^ reflected)
            for s in node.symmetry:
                if s.child == link.child:
                    grow(link.child, me, 0, scale * link.scale, mirrored ^ (not reflected))
        if not terminal:
            for r in node.recursion:
                grow(node_id, me, depth + 1, scale * r.scale, mirrored)

    grow(0, -1, 0, 1.0, False)
    return parts


# -- recombination ---------------------------------------------------------------------------------


def take_blocks(pa, pb, n, m):
    """The LR slots of a child: n positions of ``pa``, m of ``pb``, alternating (None where empty)."""
    L = max(len(pa), len(pb))
    slots, pos, from_a = [], 0, True
    while pos < L:
        src, span = (pa, n) if from_a else (pb, m)
        slots += [copy.deepcopy(src[k]) if k < len(src) else None for k in range(pos, min(pos + span, L))]
        pos += span
        from_a = not from_a
    return slots


def repair(slots, rng, brain):
    """The solution's repair: links to empty positions or closing a cycle go; orphans get a new link."""
    for i, node in enumerate(slots):
        if node is not None:
            node.children = [lk for lk in node.children if slots[lk.child] is not None and not reaches(slots, lk.child, i)]
            node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    while True:
        reach = set(preorder(slots))
        orphans = [i for i, node in enumerate(slots) if node is not None and i not in reach]
        if not orphans:
            return Creature(renumber(slots), copy.deepcopy(brain))
        i = orphans[0]
        hosts = sorted(h for h in reach if len(slots[h].children) < MAX_CHILDREN and not reaches(slots, i, h))
        host = hosts[int(rng.integers(len(hosts)))]
        slots[host].children.append(random_link(rng, i, slots[host], slots[i]))


def crossover_copies_a(a, b, rng):
    """The child is a copy of one parent (the repair only ever sees a)."""
    return repair([copy.deepcopy(nd) for nd in a.nodes], rng, a.brain)


def crossover_one_cut(a, b, rng):
    """One crossing point: the first n positions from a, all the rest from b (never back to a)."""
    L = max(len(a.nodes), len(b.nodes))
    n = int(rng.integers(1, L + 1))
    return repair(take_blocks(a.nodes, b.nodes, n, L), rng, a.brain)


def crossover_no_remap(a, b, rng):
    """The empty positions are dropped by hand, but the links keep naming the old positions (those past the
    end, backwards or closing a loop are dropped so that the child is valid)."""
    L = max(len(a.nodes), len(b.nodes))
    n, m = (int(v) for v in rng.integers(1, L + 1, size=2))
    nodes = [nd for nd in take_blocks(a.nodes, b.nodes, n, m) if nd is not None]
    for i, node in enumerate(nodes):
        node.children = [lk for lk in node.children if i < lk.child < len(nodes)]
        node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    return repair(nodes, rng, a.brain)


def crossover_orphans_dropped(a, b, rng):
    """Links to empty positions removed, but the nodes left without a parent are not re-attached."""
    L = max(len(a.nodes), len(b.nodes))
    n, m = (int(v) for v in rng.integers(1, L + 1, size=2))
    slots = take_blocks(a.nodes, b.nodes, n, m)
    for i, node in enumerate(slots):
        if node is not None:
            node.children = [lk for lk in node.children if slots[lk.child] is not None and not reaches(slots, lk.child, i)]
            node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    return Creature(renumber(slots), copy.deepcopy(a.brain))


def crossover_in_place(a, b, rng):
    """The blocks are a's and b's own nodes (no copies), so the repair edits the parents' links."""
    L = max(len(a.nodes), len(b.nodes))
    n, m = (int(v) for v in rng.integers(1, L + 1, size=2))
    slots, pos, from_a = [], 0, True
    while pos < L:
        src, span = (a.nodes, n) if from_a else (b.nodes, m)
        slots += [src[k] if k < len(src) else None for k in range(pos, min(pos + span, L))]
        pos += span
        from_a = not from_a
    return repair(slots, rng, a.brain)


def crossover_own_lengths(a, b, rng):
    """Correct: n drawn up to a's node count and m up to b's, the blocks' slots built position by position."""
    n, m = int(rng.integers(1, len(a.nodes) + 1)), int(rng.integers(1, len(b.nodes) + 1))
    L = max(len(a.nodes), len(b.nodes))
    slots = []
    for pos in range(L):
        src = a.nodes if pos % (n + m) < n else b.nodes
        slots.append(copy.deepcopy(src[pos]) if pos < len(src) else None)
    return repair(slots, rng, a.brain)


# -- mutation --------------------------------------------------------------------------------------


def mutate_with(c, rng, rate, *, p_of, kinds=("delete", "add", "modify"), nodes=None):
    """The solution's mutation with the per-node probability ``p_of(rate, n_nodes)`` and the kinds allowed."""
    nodes = copy.deepcopy(c.nodes) if nodes is None else nodes
    p = p_of(rate, len(nodes))
    for i in range(len(nodes)):
        node = nodes[i]
        r = rng.random()
        if i > 0 and r < 0.2 * p and "delete" in kinds:
            nodes[i] = None
        elif r < 0.5 * p and "add" in kinds and len(node.children) < MAX_CHILDREN and len(nodes) < MAX_NODES:
            new = random_node(rng)
            nodes.append(new)
            node.children.append(random_link(rng, len(nodes) - 1, node, new))
        elif r < 1.5 * p and "modify" in kinds:
            pick(rng, STEPS)(node, rng)
    for node in nodes:
        if node is not None:
            node.children = [lk for lk in node.children if nodes[lk.child] is not None]
            node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    return Creature(renumber(nodes), copy.deepcopy(c.brain))


def mutate_modify_only(c, rng, rate=1.0):
    """Only the six steps: no node is ever deleted or added."""
    return mutate_with(c, rng, rate, p_of=lambda r, n: r / n, kinds=("modify",))


def mutate_never_deletes(c, rng, rate=1.0):
    """Adds children and modifies, but never deletes a node."""
    return mutate_with(c, rng, rate, p_of=lambda r, n: r / n, kinds=("add", "modify"))


def mutate_every_node(c, rng, rate=1.0):
    """The probabilities are not scaled by the creature's size: every node mutates at rate 1."""
    return mutate_with(c, rng, rate, p_of=lambda r, n: r)


def mutate_rate_ignored(c, rng, rate=1.0):
    """``rate`` is never read: always about one change per call."""
    return mutate_with(c, rng, rate, p_of=lambda r, n: 1 / n)


def mutate_in_place(c, rng, rate=1.0):
    """Works on the parent's own nodes (no copy)."""
    return mutate_with(c, rng, rate, p_of=lambda r, n: r / n, nodes=c.nodes)


def mutate_one_kind_per_call(c, rng, rate=1.0):
    """Correct: one draw per node decides whether it mutates (probability rate / n), a second which way."""
    nodes = copy.deepcopy(c.nodes)
    n = len(nodes)
    for i in range(n):
        if rng.random() >= rate / n:
            continue
        kind = rng.choice(["delete", "add", "modify", "modify"])
        node = nodes[i]
        if kind == "delete" and i > 0:
            nodes[i] = None
        elif kind == "add" and len(node.children) < MAX_CHILDREN and len(nodes) < MAX_NODES:
            new = random_node(rng)
            nodes.append(new)
            node.children.append(random_link(rng, len(nodes) - 1, node, new))
        elif kind == "modify":
            STEPS[int(rng.integers(len(STEPS)))](node, rng)
    for node in nodes:
        if node is not None:
            node.children = [lk for lk in node.children if nodes[lk.child] is not None]
            node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    return Creature(renumber(nodes), copy.deepcopy(c.brain))


#: The helpers above that an answer's notebook cell needs too (:func:`as_cell`).
HELPERS = ("expand_with", "take_blocks", "repair", "mutate_with")

#: (check, answer, what it is): the buggy answers of the study, each with whether it gets the operator's
#: definition wrong ("point") or a detail ("detail").
BUGGY = [
    ("creatures.expand", expand_limit_ignored, "point"),
    ("creatures.expand", expand_limit_off_by_one, "point"),
    ("creatures.expand", expand_depth_kept, "point"),
    ("creatures.expand", expand_terminal_only_ignored, "point"),
    ("creatures.expand", expand_twins_not_mirrored, "point"),
    ("creatures.expand", expand_one_over_the_cap, "detail"),
    ("creatures.expand", expand_breadth_first, "detail"),
    ("creatures.expand", expand_recursion_first, "detail"),
    ("creatures.expand", expand_twin_first, "detail"),
    ("creatures.expand", expand_cap_keeps_shallow_parts, "detail"),
    ("creatures.crossover", crossover_copies_a, "point"),
    ("creatures.crossover", crossover_one_cut, "point"),
    ("creatures.crossover", crossover_no_remap, "point"),
    ("creatures.crossover", crossover_orphans_dropped, "point"),
    ("creatures.crossover", crossover_in_place, "detail"),
    ("creatures.mutate", mutate_modify_only, "point"),
    ("creatures.mutate", mutate_never_deletes, "point"),
    ("creatures.mutate", mutate_every_node, "point"),
    ("creatures.mutate", mutate_rate_ignored, "point"),
    ("creatures.mutate", mutate_in_place, "detail"),
]

#: (check, answer): correct answers that differ from the solution.
CORRECT = [
    ("creatures.expand", expand_iterative),
    ("creatures.expand", expand_cap_first),
    ("creatures.crossover", crossover_own_lengths),
    ("creatures.mutate", mutate_one_kind_per_call),
]
