"""The properties of phenotype expansion (seed paper section 2.3), for exercise 05's ``expand``.

See :mod:`~coursekit.grading.checks.ex05_creature_operators` for the rationale. The student's
expansion returns one record per part; every part's children are compared with what its
genotype node implies (links, terminal-only links, symmetric copies, recursion up to the limit),
the part total with an independent count by the recursion formula (:func:`full_count`), scales,
mirror parity and the force sign locally, the depth-first order (:func:`depth_first`, on the
student's own list: a pre-order walk, cut by the cap only on the path to its last part), the order
of one part's children (:func:`children_in_order`: links with their twins, then recursion copies),
and the part cap.
"""

from __future__ import annotations

import json
import math
from collections import Counter

from coursekit.grading.checks.creature_cases import MAX_JSON, creature_cls, obj, random_creature


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


def full_count(creature):
    """Parts of the uncapped expansion, by the recursion formula
    N(i, d) = 1 + sum over applicable links (1 + symmetry copies) N(child, 0) + [d < limit] ``|recursion|`` N(i, d + 1)."""
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
    return creature_cls().figure1_snake(int(rng.integers(3, 6)))


def _reflected(rng):
    """A random creature with a mirrored link (``reflect``) and negative forces on its symmetric parts."""
    for _ in range(200):
        c = random_creature(rng, n_nodes=(3, 5), p_recursion=0.5, p_symmetry=0.9, max_parts=40)
        if any(n.symmetry for n in c.nodes) and len(c.nodes) > 2:
            links = [lk for n in c.nodes for lk in n.children]
            links[int(rng.integers(len(links)))].reflect = int(rng.integers(3))
            for n in c.nodes[1:]:
                n.force = -abs(n.force)
            c.validate()
            return c
    raise RuntimeError("could not draw a creature with symmetry")  # pragma: no cover


def make_cases(rng):
    snake = creature_cls().figure1_snake(5)  # 5 segments + 2 legs at the last one
    cases = [
        {"id": "figure1", "args": [obj(_figure1(rng)), 64], "seeds": [0]},
        {"id": "reflected", "args": [obj(_reflected(rng)), 64], "seeds": [0]},
        {"id": "capped", "args": [obj(snake), 4], "seeds": [0]},
    ]
    k = 0
    while k < 6:  # random creatures rich in recursion and symmetry, fully expanded
        c = random_creature(rng, n_nodes=(2, 6), p_recursion=0.7, p_symmetry=0.7, max_parts=48)
        if any(n.recursion and n.recursive_limit for n in c.nodes):
            cases.append({"id": f"random{k}", "args": [obj(c), 64], "seeds": [0]})
            k += 1
    while True:  # a random creature whose expansion exceeds a small cap
        c = random_creature(rng, n_nodes=(3, 6), p_recursion=0.8, p_symmetry=0.8, max_parts=60)
        full = full_count(c)
        if full >= 12:
            cases.append({"id": "capped_random", "args": [obj(c), int(rng.integers(5, full - 3))], "seeds": [0]})
            break
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


CASES = ("figure1", "reflected", "capped", "random0", "random1", "random2", "random3", "random4", "random5",
                 "capped_random")


def _parts(ctx, cid):
    return json.loads(ctx.out(cid)[0])


def _where(cid, idx, p):
    return f"on test input {cid!r}, part {idx} (node {p['node']}, recursion depth {p['depth']})"


def valid(ctx):
    for cid in CASES:
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


def grows(ctx):
    for cid in CASES:
        full, cap = full_count(ctx.arg(cid, 0)), ctx.arg(cid, 1)
        n = len(_parts(ctx, cid))
        if min(full, cap) > 1 and n <= 1:
            return False, (f"on test input {cid!r} returned {n} part(s), but the genotype's links make it grow into more "
                           "than the root; expansion follows the links from the root. Nothing else is judged until it does")
    return True, "expands more than the root wherever the genotype has links"


def in_order(ctx):
    for cid in CASES:
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


def depth_first(ctx):
    """The parts come in depth-first pre-order, judged on the student's own list: every part after the root
    hangs under the part just before it or one of that part's ancestors (the walk's current path). Where the
    cap cuts the expansion short, the walk stopped on the path to its last part, so every other part has all
    the children its genotype node implies: the parts kept are the first ``max_parts`` of the full walk (a
    walk that keeps the shallow parts under the cap, in pre-order or not, fails here). The order of one
    part's children is not judged here (:func:`children_in_order`), nor the part count (:func:`capped`)."""
    for cid in CASES:
        parts = _parts(ctx, cid)
        path = [0]  # the part just before and its ancestors
        for i, p in enumerate(parts[1:], 1):
            if p["parent"] not in path:
                shown = ("..., " if len(path) > 6 else "") + ", ".join(map(str, path[-6:]))
                return False, (f"{_where(cid, i, p)} hangs under part {p['parent']}, which is neither the part just "
                               f"before it nor one of that part's ancestors (parts {shown}): depth first, a part's "
                               "whole subtree is listed before the walk goes back up to the part's next sibling, so every "
                               "part's parent is on the path to the part before it (a queue walks breadth first, "
                               "level by level)")
            del path[path.index(p["parent"]) + 1:]
            path.append(i)
        creature, cap = ctx.arg(cid, 0), ctx.arg(cid, 1)
        full = full_count(creature)
        if full <= cap:
            continue
        on_path = set(path)
        for j, kids in enumerate(_children_of(parts)):
            q = parts[j]
            want = len(_expected_children(creature.nodes[q["node"]], q["node"], q["depth"]))
            if j not in on_path and len(kids) < want:
                return False, (f"on test input {cid!r} (the genotype expands to {full} parts, max_parts is {cap}), "
                               f"part {j} (node {q['node']}, recursion depth {q['depth']}) has {len(kids)} of the "
                               f"{want} children its genotype node implies, but it is not on the path to your last "
                               f"part ({len(parts) - 1}): a depth-first walk that the cap stops has finished every "
                               "other part's subtree, so the parts kept are the first max_parts of the full walk")
    return True, "the parts come depth first, and the cap keeps the first parts of the walk"


def _child_kind(kind, node_id):
    child, flipped = kind
    return "recursion copy" if child == node_id else f"node {child}{' mirrored' if flipped else ''}"


def _kinds(kinds, node_id, at=None, most=8):
    shown = [(f"part {at[k]}: " if at else "") + _child_kind(kd, node_id) for k, kd in enumerate(kinds[:most])]
    return ", ".join(shown) + (f", ... ({len(kinds)} in all)" if len(kinds) > most else "")


def _in_order_of(got, want):
    """``got`` (a sub-multiset of ``want``) in ``want``'s order: ``want`` without what ``got`` lacks."""
    left = Counter(got)
    out = []
    for kind in want:
        if left[kind]:
            left[kind] -= 1
            out.append(kind)
    return out


def children_in_order(ctx):
    """Every part's children come in the order the exercise defines (its section 1, and the library's
    :mod:`~coursekit.creatures.phenotype`, where that order is what a relative id counts): for each link of
    ``node.children`` that applies, its child, then one mirrored copy per symmetry entry naming that child;
    the recursion copies last. Judged on the student's own list, one part's children at a time, each child as
    its node and whether it is mirrored relative to the part (a link's own child and its twins differ only
    there). Only the order is judged: a part whose children are not among those its node implies (a wrong
    count, twin or terminal-only link: :func:`counts`, :func:`mirrors`) is left to those properties, and
    missing children do not count here: the children listed must come in the same relative order as in the
    exercise's list. So a part the cap cut short is judged on the children it has; that they are the first
    ones is not judged here, since a part that lacks its first children looks the same as one whose node
    makes too few (the walk's order under the cap: :func:`depth_first`, and this order on the inputs the cap
    does not cut)."""
    for cid in CASES:
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, kids in enumerate(_children_of(parts)):
            q = parts[i]
            want = _expected_children(creature.nodes[q["node"]], q["node"], q["depth"])
            got = [(parts[k]["node"], parts[k]["mirrored"] != q["mirrored"]) for k in kids]
            if Counter(got) - Counter(want):
                continue  # not the children its node implies: counts and mirrors judge that
            order = _in_order_of(got, want)
            if got != order:
                return False, (f"{_where(cid, i, q)} lists its children as {_kinds(got, q['node'], kids)}; in the "
                               f"exercise's order the same children come as {_kinds(order, q['node'])} (for each "
                               "link in its node's children list that applies, the link's child, then one mirrored "
                               "copy per symmetry entry naming that child; the recursion copies last; 'mirrored' "
                               f"relative to part {i}): the order numbers the parts and decides which ones the cap keeps")
    return True, "every part's children come in the exercise's order: links with their twins, then recursion copies"


def _children_of(parts):
    kids = [[] for _ in parts]
    for i, p in enumerate(parts[1:], 1):
        if 0 <= p["parent"] < i:
            kids[p["parent"]].append(i)
    return kids


def counts(ctx):
    for cid in CASES:
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
        full = full_count(creature)
        if len(parts) != full:
            return False, f"on test input {cid!r} returned {len(parts)} parts; the genotype expands to {full}"
    return True, "every part has the children its genotype node implies; part totals match the recursion formula"


def _linked(ctx):
    """``(case id, creature, index, part, its parent part)`` for every part whose parent precedes it."""
    for cid in CASES:
        creature = ctx.arg(cid, 0)
        parts = _parts(ctx, cid)
        for i, p in enumerate(parts[1:], 1):
            if 0 <= p["parent"] < i:
                yield cid, creature, i, p, parts[p["parent"]]


def depths(ctx):
    for cid, creature, i, p, q in _linked(ctx):
        want = q["depth"] + 1 if q["node"] == p["node"] else 0
        if p["depth"] != want:
            how = "a recursive copy is one level deeper than its parent" if want else "a part reached through a link starts at depth 0"
            return False, f"{_where(cid, i, p)}: depth should be {want} ({how})"
        limit = creature.nodes[p["node"]].recursive_limit
        if p["depth"] > limit:
            return False, f"{_where(cid, i, p)}: node {p['node']} has recursive_limit {limit}; no copy may be deeper"
    return True, "recursion depths count the copies and stop at the limit"


def scales(ctx):
    for cid, creature, i, p, q in _linked(ctx):
        nq = creature.nodes[q["node"]]
        allowed = [r.scale for r in nq.recursion] if q["node"] == p["node"] else \
            [lk.scale for lk in nq.children if lk.child == p["node"]]
        if not any(abs(p["scale"] - q["scale"] * s) <= 1e-9 * max(1.0, q["scale"]) for s in allowed):
            return False, (f"{_where(cid, i, p)} has scale {p['scale']:g}; a child's scale is its parent's scale "
                           f"({q['scale']:g}) times the scale of the link or recursion entry that made it")
    return True, "scales multiply along every chain"


def mirrors(ctx):
    for cid in CASES:
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


def capped(ctx):
    for cid in CASES:
        cap = ctx.arg(cid, 1)
        full = full_count(ctx.arg(cid, 0))
        n = len(_parts(ctx, cid))
        if n != min(cap, full):
            what = f"the genotype expands to {full} parts" + (f" and max_parts is {cap}" if full > cap else "")
            return False, f"on test input {cid!r} returned {n} parts; {what}, so expect {min(cap, full)}"
    return True, "stops at max_parts"
