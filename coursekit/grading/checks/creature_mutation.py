"""The properties of creature mutation (seed paper section 2.2.2), for exercise 05's ``mutate``.

See :mod:`~coursekit.grading.checks.ex05_creature_operators` for the rationale. Children must be
valid, with values only from the predefined lists, a change rate scaled by the creature's size
and by ``rate``, and all six modification steps plus deletion and addition seen over many calls
(bounds: :data:`MEAN_CHANGED`).
"""

from __future__ import annotations

import json
from collections import Counter

import numpy as np

from coursekit.grading.checks.creature_cases import MAX_JSON, body_signature, obj, parse, random_creature
from coursekit.grading.checks.properties import RNG, seeds



def _value_lists():
    from coursekit.creatures import genotype as g

    return g


def _near(v, values):
    return any(abs(v - w) <= 1e-9 for w in values)


def _off_list(c):
    """The first attribute of ``c`` outside the predefined value lists, as a message, or ''."""
    g = _value_lists()
    for i, n in enumerate(c.nodes):
        w = f"node {i}"
        if not all(_near(s, g.SIZES) for s in n.size):
            return f"{w}.size = {list(n.size)}; sizes come from {list(g.SIZES)}"
        if not _near(n.force, g.FORCES):
            return f"{w}.force = {n.force!r}; forces come from {list(g.FORCES)}"
        for k, lim in enumerate(n.dof_limits):  # every DOF of a multi-DOF joint draws from its list
            lims = g.limit_values(n.joint_type, k)
            if not (_near(-lim[0], lims) and _near(lim[1], lims)):
                field = "limits" if k == 0 else f"extra_limits[{k - 1}]"
                return f"{w}.{field} = {list(lim)}; {n.joint_type} limits are ±values from {list(lims)}"
        if not any(np.allclose(n.joint_axis, a, atol=1e-9) for a in g.AXES):
            return f"{w}.joint_axis = {list(n.joint_axis)}; joint axes come from genotype.AXES"
        if not all(_near(v, g.COORDS) for v in n.joint_pos):
            return f"{w}.joint_pos = {list(n.joint_pos)}; coordinates come from {list(g.COORDS)}"
        for k, r in enumerate(n.recursion):
            if not _near(r.scale, g.SCALES) or not all(_near(v, g.COORDS) for v in r.pos):
                return f"{w}.recursion[{k}] = {r.to_dict()}; scales come from {list(g.SCALES)} and positions from {list(g.COORDS)}"
        for k, lk in enumerate(n.children):
            if not _near(lk.scale, g.SCALES) or not all(_near(v, g.COORDS) for v in lk.pos):
                return f"{w}.children[{k}] has pos {list(lk.pos)} and scale {lk.scale!r}; positions come from {list(g.COORDS)} and scales from {list(g.SCALES)}"
            if not any(np.allclose(lk.rot, R, atol=1e-9) for R in g.ROTATIONS):
                return f"{w}.children[{k}].rot is not one of the 24 cube rotations (genotype.ROTATIONS)"
    return ""


def _mutation_parent(rng, lo, hi):
    while True:
        c = random_creature(rng, n_nodes=(lo, hi), brain_neurons=(2, 2), p_recursion=0.4, p_symmetry=0.5)
        if not _off_list(c):
            return c


N_FREQ = 4


def make_cases(rng):
    s = seeds(rng, 2 + 2 * N_FREQ * 40 + 3)
    # "basic" mutates heavily (rate=3), so that a function working on the input itself is caught.
    cases = [{"id": "basic", "args": [obj(_mutation_parent(rng, 3, 5)), RNG], "kwargs": {"rate": 3.0},
              "seeds": [s[0], s[0]]}]
    for k in range(N_FREQ):
        c = obj(_mutation_parent(rng, 5, 7))
        cases.append({"id": f"rate1_{k}", "args": [c, RNG], "seeds": s[2 + 80 * k:42 + 80 * k]})
        cases.append({"id": f"rate01_{k}", "args": [c, RNG], "kwargs": {"rate": 0.1}, "seeds": s[42 + 80 * k:82 + 80 * k]})
    cases.append({"id": "rate0", "args": [obj(_mutation_parent(rng, 3, 6)), RNG], "kwargs": {"rate": 0.0},
                  "seeds": s[-3:]})
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


_RATE1 = tuple(f"rate1_{k}" for k in range(N_FREQ))
_RATE01 = tuple(f"rate01_{k}" for k in range(N_FREQ))
CASES = ("basic",) + _RATE1 + _RATE01 + ("rate0",)


def _changed_nodes(parent, child):
    """How many of the parent's nodes no longer appear (by their own attributes) in the child."""
    return sum((Counter(map(body_signature, parent.nodes)) - Counter(map(body_signature, child.nodes))).values())


def _mean_changed(ctx, cids):
    vals = [_changed_nodes(ctx.arg(cid, 0), parse(t)) for cid in cids for t in ctx.out(cid)]
    sizes = [len(ctx.arg(cid, 0).nodes) for cid in cids]
    return float(np.mean(vals)), float(np.mean(sizes))


def changes(ctx):
    n = changed = 0
    for cid in _RATE1:
        parent = json.loads(ctx.case(cid)["args"][0]["json"])
        for text in ctx.out(cid):
            n += 1
            changed += json.loads(text) != parent
    if changed >= n / 4:
        return True, f"{changed} of {n} calls at rate=1 changed the creature"
    return False, (f"only {changed} of {n} calls at rate=1 changed the creature; on average a mutation changes about "
                   "one node per call. Nothing else is judged until it does")


def in_lists(ctx):
    for cid in CASES:
        for k, text in enumerate(ctx.out(cid)):
            bad = _off_list(parse(text))
            if bad:
                return False, f"on test input {cid!r} (call {k + 1}) the child has {bad} (the predefined list of valid values)"
    return True, "every value comes from the predefined lists"


# Bounds on the mean number of changed nodes per call at rate=1 (parents of 5..7 nodes; 160
# calls). Per-node probabilities rate/len(nodes) give about 1 (Sims: "on average at least one
# mutation per graph"); 0.25 and 2.5 leave room for any reasonable mix of probabilities
# while rejecting "never changes a node" and "mutates every node".
MEAN_CHANGED = (0.25, 2.5)


def frequency(ctx):
    mean, size = _mean_changed(ctx, _RATE1)
    lo, hi = MEAN_CHANGED
    if mean < lo:
        return False, (f"at rate=1 only {mean:.2f} nodes changed per call on average (creatures of about {size:.0f} "
                       "nodes); with probabilities scaled by 1/len(nodes), about one node should change per call")
    if mean > hi:
        return False, (f"at rate=1 {mean:.2f} of about {size:.0f} nodes changed per call on average; scale the "
                       "probabilities by 1/len(nodes) so that about one node changes per call, not every node")
    return True, f"{mean:.2f} nodes changed per call at rate=1 (creatures of about {size:.0f} nodes)"


def rate(ctx):
    for k, text in enumerate(ctx.out("rate0")):
        if json.loads(text) != json.loads(ctx.case("rate0")["args"][0]["json"]):
            return False, f"with rate=0 call {k + 1} changed the creature; rate multiplies every probability, so nothing may change"
    m1, _ = _mean_changed(ctx, _RATE1)
    m01, _ = _mean_changed(ctx, _RATE01)
    if not m01 <= 0.5 * m1:
        return False, (f"{m01:.2f} nodes changed per call at rate=0.1 and {m1:.2f} at rate=1; rate multiplies every "
                       "probability, so rate=0.1 should change about a tenth as much")
    return True, f"rate=0 changes nothing; {m01:.2f} vs {m1:.2f} nodes changed per call at rate 0.1 vs 1"


_PROJECTIONS = {
    "joint axis/position": lambda n: (tuple(n.joint_axis), tuple(n.joint_pos), n.joint_type),
    "body size": lambda n: tuple(n.size),
    "joint mobility": lambda n: tuple(n.limits),
    "force": lambda n: n.force,
    "recursion": lambda n: json.dumps([n.recursive_limit, [r.to_dict() for r in n.recursion]]),
    "symmetry": lambda n: tuple(sorted(s.axis for s in n.symmetry)),
}


def _kinds(old, new):
    """The kinds of change visible between parent and child.

    With the node count unchanged, nodes are compared at equal LR positions: a node that differs
    in one to three of the six attribute groups was modified in those steps; one that differs in
    more is a different node (a deletion plus an addition, or a re-pointed link moved it) and
    says nothing about modification.
    """
    if len(new.nodes) < len(old.nodes):
        return {"deletes nodes"}
    if len(new.nodes) > len(old.nodes):
        return {"adds children"}
    seen = set()
    for a, b in zip(old.nodes, new.nodes):
        diff = {name for name, f in _PROJECTIONS.items() if f(a) != f(b)}
        if len(diff) <= 3:
            seen |= diff
    return seen


_ALL_KINDS = ("deletes nodes", "adds children", "joint axis/position", "body size", "joint mobility", "force",
              "recursion", "symmetry")


def all_kinds(ctx):
    seen = set()
    n = 0
    for cid in _RATE1:
        parent = ctx.arg(cid, 0)
        for text in ctx.out(cid):
            seen |= _kinds(parent, parse(text))
            n += 1
    missing = [k for k in _ALL_KINDS if k not in seen]
    if missing:
        return False, (f"in {n} mutations at rate=1 these kinds of change never happened: {', '.join(missing)}; "
                       "each node may be deleted, get a new child, or be modified in the six steps")
    return True, f"all {len(_ALL_KINDS)} kinds of change seen in {n} mutations"


def _size_steps(old, new):
    """``(position, old size, new size)`` of the nodes whose size alone changed, at equal LR positions
    (the node count unchanged; every other attribute group and the links the same)."""
    if len(new.nodes) != len(old.nodes):
        return []
    out = []
    for i, (a, b) in enumerate(zip(old.nodes, new.nodes)):
        diff = {name for name, f in _PROJECTIONS.items() if f(a) != f(b)}
        if diff == {"body size"} and [lk.child for lk in a.children] == [lk.child for lk in b.children]:
            out.append((i, tuple(a.size), tuple(b.size)))
    return out


def _size_index(v, sizes):
    return min(range(len(sizes)), key=lambda k: abs(sizes[k] - v))


def neighbouring_size(ctx):
    """Step 2 moves one half extent to a neighbouring value in SIZES (the exercise's mutate_size)."""
    sizes = tuple(_value_lists().SIZES)
    seen = 0
    for cid in _RATE1 + _RATE01:
        parent = ctx.arg(cid, 0)
        for k, text in enumerate(ctx.out(cid)):
            for i, a, b in _size_steps(parent, parse(text)):
                seen += 1
                moved = [(axis, x, y) for axis, (x, y) in enumerate(zip(a, b)) if abs(x - y) > 1e-12]
                jumps = [abs(_size_index(x, sizes) - _size_index(y, sizes)) for _, x, y in moved]
                if len(moved) != 1 or jumps[0] != 1:
                    axis, x, y = moved[0]
                    return False, (f"on test input {cid!r} (call {k + 1}) node {i}'s size went from {list(a)} to {list(b)}"
                                   + (f": half extent {axis} jumped from {x:g} to {y:g}" if len(moved) == 1 else "")
                                   + "; step 2 moves one of the three half extents to a neighbouring value in SIZES "
                                   "(the next smaller or the next larger)")
    if not seen:
        return True, "no node's size alone changed in these mutations (nothing to check)"
    return True, f"every size change moved one half extent to a neighbouring value ({seen} changes)"

