"""Checks for exercise 05 (the creature operators: expansion, recombination, mutation).

Seed paper sections 2.3 (phenotype expansion), 2.2.1 (recombination with LR numbering) and
2.2.2 (mutation), checked as properties of the student's results -- never against one
reference output:

- ``creatures.expand``: the student's expansion returns one record per part
  (``node``, ``parent``, ``depth``, ``scale``, ``mirrored``, ``gain``). Every part's children
  are compared with what its genotype node implies (links, terminal-only links, symmetric
  copies, recursion up to the limit); the part total with an independent count by the
  recursion formula; scales, mirror parity and the force sign locally; and the part cap.
- ``creatures.crossover``: every node of the child is identified (by its body attributes) as
  the node at some LR position of a parent; the positions must follow alternating blocks
  ``[0, n)`` from ``a``, the next ``m`` from ``b``, ...; every taken node is kept; links
  between taken nodes survive; ``n`` and ``m`` vary between calls.
- ``creatures.mutate``: valid children, values only from the predefined lists, a change rate
  scaled by the creature's size and by ``rate``, all six modification steps plus deletion and
  addition seen over many calls.

Each check's second property is its *job*, a gate: more than the root is expanded wherever the
genotype has links; in at least a quarter of the calls the child of a recombination holds nodes
found only in ``a`` and nodes found only in ``b``; at least a quarter of the mutations at rate 1
change the creature. Until it holds nothing else is judged, so an expansion that returns the
root alone and deep copies score 0.

All three also check determinism for a seed and that inputs stay unmodified. Expansion and
recombination are checked exactly. The mutation statistics (changed nodes per call at rate 1
and 0.1, over 160 calls each, and every kind of change at least once) use wide bounds, set out
at :data:`MEAN_CHANGED`: an implementation that follows the notebook's rule fails them only by
a deviation of many standard deviations.
"""

from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np

from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.properties import COPY_OBJECT, RNG, deterministic, seeds, unmodified

CREATURE = "coursekit.creatures.genotype:Creature"
MAX_JSON = 2_000_000


#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
HINTS = {
    "creatures.expand": (
        ("expands more than the root", (
            "Expanding follows the genotype's links from the root: each link makes a child part of the node it points to.",
            "Walk the graph depth-first from node 0, one part record per visit, until the recursion limits stop it.")),
    ),
    "creatures.crossover": (
        ("the child holds nodes of both parents", (
            "The child takes nodes from a and from b in alternating blocks, not all from one parent.",
            "Draw the block lengths with the rng, then copy the nodes of the current parent for each block.")),
    ),
    "creatures.mutate": (
        ("changes the creature", (
            "Mutation must change something: a node's value, a link, a new or deleted node.",
            "Work on a copy of the creature and change each value with a probability that grows with rate.")),
    ),
}


def _obj(creature):
    return {"object": CREATURE, "json": creature.to_json()}


def _creature_cls():
    from coursekit.creatures.genotype import Creature

    return Creature


def _random(rng, **kw):
    """A random creature drawn from the library's generator, seeded from ``rng``."""
    return _creature_cls().random(np.random.default_rng(int(rng.integers(2**31))), **kw)


def _parse(text):
    """A student's result as a Creature (validated by the library), or raise ValueError/TypeError."""
    return _creature_cls().from_json(text)


def _valid_creatures(cids):
    def prop(ctx):
        for cid in cids:
            for k, text in enumerate(ctx.out(cid)):
                try:
                    _parse(text)
                except (ValueError, TypeError) as exc:
                    return False, f"call {k + 1} on test input {cid!r} returned an invalid creature: {exc}"
        return True, "every result is a valid Creature"

    return prop


# ============================================================================ expansion

_PART_KEYS = {"node": int, "parent": int, "depth": int, "scale": float, "mirrored": bool, "gain": float}


def _terminal(node, depth):
    return depth >= node.recursive_limit or not node.recursion


def _expected_children(node, node_id, depth):
    """[(child node, mirrored relative to the parent)] for one instance of ``node`` at ``depth``."""
    out = []
    term = _terminal(node, depth)
    for link in node.children:
        if link.terminal_only and not term:
            continue
        own = link.reflect >= 0
        out.append((link.child, own))
        out += [(link.child, not own) for s in node.symmetry if s.child == link.child]
    if not term:
        out += [(node_id, False) for _ in node.recursion]
    return out


def _full_count(creature):
    """Parts of the uncapped expansion, by the recursion formula
    N(i, d) = 1 + sum over applicable links (1 + symmetry copies) N(child, 0) + [d < limit] |recursion| N(i, d + 1)."""
    memo = {}

    def N(i, d):
        if (i, d) not in memo:
            node = creature.nodes[i]
            term = _terminal(node, d)
            total = 1
            for link in node.children:
                if link.terminal_only and not term:
                    continue
                total += (1 + sum(s.child == link.child for s in node.symmetry)) * N(link.child, 0)
            if not term:
                total += len(node.recursion) * N(i, d + 1)
            memo[i, d] = total
        return memo[i, d]

    return N(0, 0)


def _figure1(rng):
    return _creature_cls().figure1_snake(int(rng.integers(3, 6)))


def _reflected(rng):
    """A random creature with a mirrored link (``reflect``) and negative forces on its symmetric parts."""
    for _ in range(200):
        c = _random(rng, n_nodes=(3, 5), p_recursion=0.5, p_symmetry=0.9, max_parts=40)
        if any(n.symmetry for n in c.nodes) and len(c.nodes) > 2:
            links = [lk for n in c.nodes for lk in n.children]
            links[int(rng.integers(len(links)))].reflect = int(rng.integers(3))
            for n in c.nodes[1:]:
                n.force = -abs(n.force)
            c.validate()
            return c
    raise RuntimeError("could not draw a creature with symmetry")  # pragma: no cover


def _expand_cases(rng):
    snake = _creature_cls().figure1_snake(5)  # 5 segments + 2 legs at the last one
    cases = [
        {"id": "figure1", "args": [_obj(_figure1(rng)), 64], "seeds": [0]},
        {"id": "reflected", "args": [_obj(_reflected(rng)), 64], "seeds": [0]},
        {"id": "capped", "args": [_obj(snake), 4], "seeds": [0]},
    ]
    k = 0
    while k < 6:  # random creatures rich in recursion and symmetry, fully expanded
        c = _random(rng, n_nodes=(2, 6), p_recursion=0.7, p_symmetry=0.7, max_parts=48)
        if any(n.recursion and n.recursive_limit for n in c.nodes):
            cases.append({"id": f"random{k}", "args": [_obj(c), 64], "seeds": [0]})
            k += 1
    while True:  # a random creature whose expansion exceeds a small cap
        c = _random(rng, n_nodes=(3, 6), p_recursion=0.8, p_symmetry=0.8, max_parts=60)
        full = _full_count(c)
        if full >= 12:
            cases.append({"id": "capped_random", "args": [_obj(c), int(rng.integers(5, full - 3))], "seeds": [0]})
            break
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


_EXPAND_CASES = ("figure1", "reflected", "capped", "random0", "random1", "random2", "random3", "random4", "random5",
                 "capped_random")


def _parts(ctx, cid):
    return json.loads(ctx.out(cid)[0])


def _where(cid, idx, p):
    return f"on test input {cid!r}, part {idx} (node {p['node']}, recursion depth {p['depth']})"


def _expand_valid(ctx):
    for cid in _EXPAND_CASES:
        parts = _parts(ctx, cid)
        n_nodes = len(ctx.arg(cid, 0).nodes)
        if not isinstance(parts, list) or not parts:
            return False, f"on test input {cid!r} returned {type(parts).__name__}; expected a non-empty list of part dicts"
        for i, p in enumerate(parts):
            if not isinstance(p, dict) or set(p) != set(_PART_KEYS):
                got = sorted(p) if isinstance(p, dict) else type(p).__name__
                return False, f"on test input {cid!r}, part {i} is {got}; expected a dict with exactly the keys {sorted(_PART_KEYS)}"
            for key, typ in _PART_KEYS.items():
                v = p[key]
                ok = isinstance(v, bool) if typ is bool else (
                    isinstance(v, int) and not isinstance(v, bool) if typ is int else
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v))
                if not ok:
                    return False, f"on test input {cid!r}, part {i}[{key!r}] = {v!r}; expected {typ.__name__}"
            if not 0 <= p["node"] < n_nodes:
                return False, f"on test input {cid!r}, part {i} names node {p['node']}; the genotype has nodes 0..{n_nodes - 1}"
    return True, "returns a list of part records"


def _expand_grows(ctx):
    for cid in _EXPAND_CASES:
        full, cap = _full_count(ctx.arg(cid, 0)), ctx.arg(cid, 1)
        n = len(_parts(ctx, cid))
        if min(full, cap) > 1 and n <= 1:
            return False, (f"on test input {cid!r} returned {n} part(s), but the genotype's links make it grow into more "
                           "than the root; expansion follows the links from the root. Nothing else is judged until it does")
    return True, "expands more than the root wherever the genotype has links"


def _expand_order(ctx):
    for cid in _EXPAND_CASES:
        parts = _parts(ctx, cid)
        r = parts[0]
        if (r["node"], r["parent"], r["depth"], r["mirrored"]) != (0, -1, 0, False) or abs(r["scale"] - 1) > 1e-9:
            return False, (f"on test input {cid!r} the first part is {r}; it must be the root: node 0, parent -1, "
                           "depth 0, scale 1, not mirrored")
        for i, p in enumerate(parts[1:], 1):
            if not 0 <= p["parent"] < i:
                return False, (f"on test input {cid!r}, part {i} has parent {p['parent']}; every part's parent must be "
                               "an earlier part (index 0..i-1)")
    return True, "the root comes first and parents precede their children"


def _children_of(parts):
    kids = [[] for _ in parts]
    for i, p in enumerate(parts[1:], 1):
        if 0 <= p["parent"] < i:
            kids[p["parent"]].append(i)
    return kids


def _expand_counts(ctx):
    for cid in _EXPAND_CASES:
        if cid.startswith("capped"):
            continue
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, kids in enumerate(_children_of(parts)):
            p = parts[i]
            exp = Counter(c[0] for c in _expected_children(creature.nodes[p["node"]], p["node"], p["depth"]))
            got = Counter(parts[k]["node"] for k in kids)
            if got != exp:
                node = next(n for n in sorted(set(exp) | set(got)) if exp[n] != got[n])
                return False, (f"{_where(cid, i, p)} has {got[node]} children made from node {node}; its genotype node "
                               f"implies {exp[node]} (count its links, terminal-only links, symmetry copies and "
                               "recursion copies)")
        full = _full_count(creature)
        if len(parts) != full:
            return False, f"on test input {cid!r} returned {len(parts)} parts; the genotype expands to {full}"
    return True, "every part has the children its genotype node implies; part totals match the recursion formula"


def _expand_depth(ctx):
    for cid in _EXPAND_CASES:
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, p in enumerate(parts[1:], 1):
            q = parts[p["parent"]] if 0 <= p["parent"] < i else None
            if q is None:
                continue
            want = q["depth"] + 1 if q["node"] == p["node"] else 0
            if p["depth"] != want:
                how = "a recursive copy is one level deeper than its parent" if want else "a part reached through a link starts at depth 0"
                return False, f"{_where(cid, i, p)}: depth should be {want} ({how})"
            limit = creature.nodes[p["node"]].recursive_limit
            if p["depth"] > limit:
                return False, f"{_where(cid, i, p)}: node {p['node']} has recursive_limit {limit}; no copy may be deeper"
    return True, "recursion depths count the copies and stop at the limit"


def _expand_scale(ctx):
    for cid in _EXPAND_CASES:
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, p in enumerate(parts[1:], 1):
            q = parts[p["parent"]] if 0 <= p["parent"] < i else None
            if q is None:
                continue
            nq = creature.nodes[q["node"]]
            allowed = [r.scale for r in nq.recursion] if q["node"] == p["node"] else \
                [lk.scale for lk in nq.children if lk.child == p["node"]]
            if not any(abs(p["scale"] - q["scale"] * s) <= 1e-9 * max(1.0, q["scale"]) for s in allowed):
                return False, (f"{_where(cid, i, p)} has scale {p['scale']:g}; a child's scale is its parent's scale "
                               f"({q['scale']:g}) times the scale of the link or recursion entry that made it")
    return True, "scales multiply along every chain"


def _expand_mirror(ctx):
    for cid in _EXPAND_CASES:
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, p in enumerate(parts):
            force = creature.nodes[p["node"]].force
            want = force if p["mirrored"] else abs(force)
            if i > 0 and abs(p["gain"] - want) > 1e-9:
                return False, (f"{_where(cid, i, p)} has gain {p['gain']:g}; node {p['node']} has force {force:g}: an "
                               "unmirrored part gets |force| and a mirrored one the signed force")
        for i, kids in enumerate(_children_of(parts)):
            q = parts[i]
            exp = _expected_children(creature.nodes[q["node"]], q["node"], q["depth"])
            for node in {c for c, _ in exp}:
                want = Counter(m for c, m in exp if c == node)
                got = Counter(parts[k]["mirrored"] != q["mirrored"] for k in kids if parts[k]["node"] == node)
                if sum(got.values()) == sum(want.values()) and got != want:
                    return False, (f"{_where(cid, i, q)}: of its {sum(want.values())} children from node {node}, "
                                   f"{want[True]} should be mirrored relative to it and {got[True]} are (a symmetric "
                                   "copy or a reflect link flips the parity; a mirrored parent's children inherit it)")
    return True, "symmetric copies are mirrored and carry the signed force"


def _expand_cap(ctx):
    for cid in _EXPAND_CASES:
        cap = ctx.arg(cid, 1)
        full = _full_count(ctx.arg(cid, 0))
        n = len(_parts(ctx, cid))
        if n != min(cap, full):
            what = f"the genotype expands to {full} parts" + (f" and max_parts is {cap}" if full > cap else "")
            return False, f"on test input {cid!r} returned {n} parts; {what}, so expect {min(cap, full)}"
    return True, "stops at max_parts"


register(Check(
    hints=HINTS.get("creatures.expand", ()),
    name="creatures.expand", function="expand", params=("creature", "max_parts"), points=4.0,
    title="phenotype expansion", output="json", cases=_expand_cases, gates=2,
    reference=('coursekit.creatures.phenotype:expand', 'coursekit.creatures.genotype:Creature.expand'),
    props=(
        ("returns a list of part records", _expand_valid),
        ("expands more than the root", _expand_grows),
        ("parents precede children", _expand_order),
        ("children match the genotype (links, symmetry, recursion)", _expand_counts),
        ("recursion depth and limit", _expand_depth),
        ("scales multiply", _expand_scale),
        ("mirrored copies and force sign", _expand_mirror),
        ("part cap respected", _expand_cap),
    ),
))


# ========================================================================== recombination


def body_signature(node) -> str:
    """A node's own attributes (not its links or networks): what recombination must keep."""
    d = node.to_dict()
    return json.dumps([d[k] for k in ("size", "joint_type", "joint_pos", "joint_axis", "limits", "force",
                                      "recursive_limit", "recursion")])


def _forward_only(c):
    """Stored in LR order, every link pointing to a later position (so no mix of two can cycle)."""
    from coursekit.creatures.genotype import preorder

    return preorder(c.nodes) == list(range(len(c.nodes))) and \
        all(lk.child > i for i, n in enumerate(c.nodes) for lk in n.children)


def _parent_pair(rng, lo, hi):
    """Two random parents (same brain size) whose links all point forward in LR order and whose
    nodes are all distinguishable, so a child's nodes can be traced to their positions."""
    while True:
        a, b = (_random(rng, n_nodes=(lo, hi), brain_neurons=(2, 2), p_symmetry=0.5) for _ in range(2))
        sigs = [body_signature(n) for n in a.nodes + b.nodes]
        if _forward_only(a) and _forward_only(b) and len(set(sigs)) == len(sigs):
            return a, b


def _crossover_cases(rng):
    s = seeds(rng, 80)
    cases = []
    a, b = _parent_pair(rng, 4, 6)
    cases.append({"id": "basic", "args": [_obj(a), _obj(b), RNG], "seeds": [s[0]] * 4})
    a, b = _parent_pair(rng, 6, 8)
    cases.append({"id": "many", "args": [_obj(a), _obj(b), RNG], "seeds": s[1:41]})
    for k in range(6):
        a, b = _parent_pair(rng, 2, 7)
        cases.append({"id": f"pair{k}", "args": [_obj(a), _obj(b), RNG], "seeds": s[41 + 3 * k:44 + 3 * k]})
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


_CROSS_CASES = ("basic", "many") + tuple(f"pair{k}" for k in range(6))


def _trace(a, b, child):
    """Map the child's nodes to (parent 0/1, LR position), or (None, message)."""
    where = {}
    for src, parent in enumerate((a, b)):
        for pos, node in enumerate(parent.nodes):
            where[body_signature(node)] = (src, pos)
    out = []
    for k, node in enumerate(child.nodes):
        loc = where.get(body_signature(node))
        if loc is None:
            return None, f"node {k} of the child is not a node of either parent (a taken node keeps all its own attributes)"
        out.append(loc)
    if len(set(out)) != len(out):
        return None, "the child contains the same parent node twice; each LR position is taken at most once"
    return out, ""


def _patterns(a, b):
    """Every alternating block pattern: {(n, m): set of (parent, position) the child takes}."""
    L = max(len(a.nodes), len(b.nodes))
    sizes = (len(a.nodes), len(b.nodes))
    pats = {}
    for n in range(1, L + 1):
        for m in range(1, L + 1):
            taken, pos, src = set(), 0, 0
            while pos < L:
                span = n if src == 0 else m
                taken |= {(src, k) for k in range(pos, min(pos + span, sizes[src]))}
                pos += span
                src = 1 - src
            pats[n, m] = taken
    return pats


def _each_child(ctx, cids):
    for cid in cids:
        a, b = ctx.arg(cid, 0), ctx.arg(cid, 1)
        for k, text in enumerate(ctx.out(cid)):
            yield cid, k, a, b, _parse(text)


def _blocks(ctx):
    for cid, k, a, b, child in _each_child(ctx, _CROSS_CASES):
        locs, why = _trace(a, b, child)
        if locs is None:
            return False, f"on test input {cid!r} (call {k + 1}): {why}"
        got = set(locs)
        if not any(got <= taken for taken in _patterns(a, b).values()):
            shown = ", ".join(f"{'ab'[s]}[{p}]" for s, p in sorted(locs, key=lambda t: (t[1], t[0])))
            return False, (f"on test input {cid!r} (call {k + 1}) the child holds the LR positions {shown}; that is not "
                           "positions [0, n) of a, the next m of b, the next n of a, ... for any n, m >= 1")
    return True, "the child's nodes come from alternating LR blocks of a and b, at their positions"


def _kept(ctx):
    for cid, k, a, b, child in _each_child(ctx, _CROSS_CASES):
        locs, _ = _trace(a, b, child)
        if locs is None:
            return False, "not checked until the child's nodes can be traced to LR blocks"
        got = set(locs)
        pats = [t for t in _patterns(a, b).values() if got <= t]
        if not pats:
            return False, "not checked until the child's nodes come from alternating LR blocks"
        if got not in pats:
            missing = min(len(t - got) for t in pats)
            return False, (f"on test input {cid!r} (call {k + 1}) the child lost {missing} of the nodes its blocks take; "
                           "repair must re-attach taken nodes whose parent position was dropped, not discard them")
    return True, "every taken node is kept (repair re-attaches orphans)"


def _link_key(lk):
    return json.dumps([lk.pos, lk.rot, lk.scale, lk.terminal_only, lk.reflect], default=list)


def _links_kept(ctx):
    for cid, k, a, b, child in _each_child(ctx, _CROSS_CASES):
        locs, _ = _trace(a, b, child)
        if locs is None:
            return False, "not checked until the child's nodes can be traced to LR blocks"
        at = {pos: i for i, (_, pos) in enumerate(locs)}
        for i, (src, pos) in enumerate(locs):
            orig = (a, b)[src].nodes[pos]
            want = Counter((at[lk.child], _link_key(lk)) for lk in orig.children if lk.child in at)
            have = Counter((lk.child, _link_key(lk)) for lk in child.nodes[i].children)
            lost = want - have
            if lost:
                j = next(iter(lost))[0]
                return False, (f"on test input {cid!r} (call {k + 1}): {'ab'[src]}[{pos}] linked to LR position "
                               f"{locs[j][1]}, which the child also holds, but the child lost that link (or changed its "
                               "attributes); links between taken positions stay, so a leg remains a leg")
    return True, "links between taken positions are kept with their attributes"


def _cross_mixes(ctx):
    n = mixed = 0
    for cid, _, a, b, child in _each_child(ctx, _CROSS_CASES):
        only_a = set(map(body_signature, a.nodes)) - set(map(body_signature, b.nodes))
        only_b = set(map(body_signature, b.nodes)) - set(map(body_signature, a.nodes))
        mine = set(map(body_signature, child.nodes))
        n += 1
        mixed += bool(mine & only_a) and bool(mine & only_b)
    if mixed >= n / 4:
        return True, f"in {mixed} of {n} calls the child holds nodes of both parents"
    return False, (f"in only {mixed} of {n} calls did the child hold nodes of both parents; recombination takes "
                   "alternating blocks from a and b. Nothing else is judged until it does")


def _random_blocks(ctx):
    a, b = ctx.arg("many", 0), ctx.arg("many", 1)
    sets = []
    for text in ctx.out("many"):
        locs, _ = _trace(a, b, _parse(text))
        if locs is None:
            return False, "not checked until the child's nodes can be traced to LR blocks"
        sets.append(frozenset(locs))
    if not any(s for t in sets for s, _ in t if s == 1):
        return False, f"in {len(sets)} calls the child never took a node from b; n and m are random, so b's nodes appear"
    if len(set(sets)) < 3:
        return False, f"in {len(sets)} calls with different seeds the child took the same LR blocks almost every time; draw n and m at random in every call"
    return True, f"{len(set(sets))} different block patterns in {len(sets)} calls"


register(Check(
    hints=HINTS.get("creatures.crossover", ()),
    name="creatures.crossover", function="crossover", params=("a", "b", "rng"), points=4.0,
    title="LR recombination", output="json", cases=_crossover_cases, gates=2,
    reference=('coursekit.creatures.operators:crossover',),
    props=(
        ("returns a valid creature", _valid_creatures(_CROSS_CASES)),
        ("the child holds nodes of both parents", _cross_mixes),
        ("nodes from alternating LR blocks at their positions", _blocks),
        ("every taken node is kept", _kept),
        ("links between taken nodes are kept", _links_kept),
        ("n and m are random", _random_blocks),
        ("deterministic for a seed", deterministic("basic", parse=json.loads)),
        ("inputs unchanged", unmodified({0: "a", 1: "b"}, COPY_OBJECT, what="the creature {name}")),
    ),
))


# ============================================================================== mutation


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
        lims = g.REVOLUTE_LIMITS if n.joint_type == "revolute" else g.PRISMATIC_LIMITS
        if not (_near(-n.limits[0], lims) and _near(n.limits[1], lims)):
            return f"{w}.limits = {list(n.limits)}; {n.joint_type} limits are ±values from {list(lims)}"
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
        c = _random(rng, n_nodes=(lo, hi), brain_neurons=(2, 2), p_recursion=0.4, p_symmetry=0.5)
        if not _off_list(c):
            return c


N_FREQ = 4


def _mutation_cases(rng):
    s = seeds(rng, 2 + 2 * N_FREQ * 40 + 3)
    # "basic" mutates heavily (rate=3), so that a function working on the input itself is caught.
    cases = [{"id": "basic", "args": [_obj(_mutation_parent(rng, 3, 5)), RNG], "kwargs": {"rate": 3.0},
              "seeds": [s[0], s[0]]}]
    for k in range(N_FREQ):
        c = _obj(_mutation_parent(rng, 5, 7))
        cases.append({"id": f"rate1_{k}", "args": [c, RNG], "seeds": s[2 + 80 * k:42 + 80 * k]})
        cases.append({"id": f"rate01_{k}", "args": [c, RNG], "kwargs": {"rate": 0.1}, "seeds": s[42 + 80 * k:82 + 80 * k]})
    cases.append({"id": "rate0", "args": [_obj(_mutation_parent(rng, 3, 6)), RNG], "kwargs": {"rate": 0.0},
                  "seeds": s[-3:]})
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


_RATE1 = tuple(f"rate1_{k}" for k in range(N_FREQ))
_RATE01 = tuple(f"rate01_{k}" for k in range(N_FREQ))
_MUT_CASES = ("basic",) + _RATE1 + _RATE01 + ("rate0",)


def _changed_nodes(parent, child):
    """How many of the parent's nodes no longer appear (by their own attributes) in the child."""
    return sum((Counter(map(body_signature, parent.nodes)) - Counter(map(body_signature, child.nodes))).values())


def _mean_changed(ctx, cids):
    vals = [_changed_nodes(ctx.arg(cid, 0), _parse(t)) for cid in cids for t in ctx.out(cid)]
    sizes = [len(ctx.arg(cid, 0).nodes) for cid in cids]
    return float(np.mean(vals)), float(np.mean(sizes))


def _mutate_changes(ctx):
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


def _in_lists(ctx):
    for cid in _MUT_CASES:
        for k, text in enumerate(ctx.out(cid)):
            bad = _off_list(_parse(text))
            if bad:
                return False, f"on test input {cid!r} (call {k + 1}) the child has {bad} (the predefined list of valid values)"
    return True, "every value comes from the predefined lists"


# Bounds on the mean number of changed nodes per call at rate=1 (parents of 5..7 nodes; 160
# calls). Per-node probabilities rate/len(nodes) give about 1 (Sims: "on average at least one
# mutation per graph"); 0.25 and 2.5 leave room for any reasonable mix of probabilities
# while rejecting "never changes a node" and "mutates every node".
MEAN_CHANGED = (0.25, 2.5)


def _frequency(ctx):
    mean, size = _mean_changed(ctx, _RATE1)
    lo, hi = MEAN_CHANGED
    if mean < lo:
        return False, (f"at rate=1 only {mean:.2f} nodes changed per call on average (creatures of about {size:.0f} "
                       "nodes); with probabilities scaled by 1/len(nodes), about one node should change per call")
    if mean > hi:
        return False, (f"at rate=1 {mean:.2f} of about {size:.0f} nodes changed per call on average; scale the "
                       "probabilities by 1/len(nodes) so that about one node changes per call, not every node")
    return True, f"{mean:.2f} nodes changed per call at rate=1 (creatures of about {size:.0f} nodes)"


def _rate(ctx):
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


def _all_kinds(ctx):
    seen = set()
    n = 0
    for cid in _RATE1:
        parent = ctx.arg(cid, 0)
        for text in ctx.out(cid):
            seen |= _kinds(parent, _parse(text))
            n += 1
    missing = [k for k in _ALL_KINDS if k not in seen]
    if missing:
        return False, (f"in {n} mutations at rate=1 these kinds of change never happened: {', '.join(missing)}; "
                       "each node may be deleted, get a new child, or be modified in the six steps")
    return True, f"all {len(_ALL_KINDS)} kinds of change seen in {n} mutations"


register(Check(
    hints=HINTS.get("creatures.mutate", ()),
    name="creatures.mutate", function="mutate", params=("c", "rng"), points=4.0,
    title="creature mutation", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.creatures.operators:mutate',),
    props=(
        ("returns a valid creature", _valid_creatures(_MUT_CASES)),
        ("changes the creature", _mutate_changes),
        ("values from the predefined lists", _in_lists),
        ("about one node changes per call", _frequency),
        ("honours rate", _rate),
        ("deletes, adds and modifies in all six steps", _all_kinds),
        ("deterministic for a seed", deterministic("basic", parse=json.loads)),
        ("input unchanged", unmodified({0: "c"}, COPY_OBJECT, what="the creature {name}")),
    ),
))


exercise("05_creature_operators", ["creatures.expand", "creatures.crossover", "creatures.mutate"])
