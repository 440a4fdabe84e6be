"""The properties of LR recombination (seed paper section 2.2.1), for exercise 05's ``crossover``.

See :mod:`~coursekit.grading.checks.ex05_creature_operators` for the rationale. Every node of
the child is identified (by its body attributes, :func:`~.creature_cases.body_signature`) as
the node at some LR position of a parent; the positions must follow alternating blocks, every
taken node is kept, links between taken nodes survive, the block lengths vary between calls and
the blocks alternate (:func:`alternates`: over the 40 calls of "many" and the 30 of "long", whose
parents have 10-12 nodes, some child takes nodes of ``a`` again after a block of ``b``; with ``n``
and ``m`` uniform in ``1..L`` a correct recombination misses that in every call with probability
below 1e-6, see the sweep in benchmarks/NOTES.md).
"""

from __future__ import annotations

import json
from collections import Counter

from coursekit.grading.checks.creature_cases import MAX_JSON, body_signature, obj, parse, random_creature
from coursekit.grading.checks.properties import RNG, seeds



def _forward_only(c):
    """Stored in LR order, every link pointing to a later position (so no mix of two can cycle)."""
    from coursekit.creatures.genotype import preorder

    return preorder(c.nodes) == list(range(len(c.nodes))) and \
        all(lk.child > i for i, n in enumerate(c.nodes) for lk in n.children)


def _parent_pair(rng, lo, hi):
    """Two random parents (same brain size) whose links all point forward in LR order and whose
    nodes are all distinguishable, so a child's nodes can be traced to their positions."""
    while True:
        a, b = (random_creature(rng, n_nodes=(lo, hi), brain_neurons=(2, 2), p_symmetry=0.5) for _ in range(2))
        sigs = [body_signature(n) for n in a.nodes + b.nodes]
        if _forward_only(a) and _forward_only(b) and len(set(sigs)) == len(sigs):
            return a, b


def _cycle_prone_pair(rng):
    """Two random parents such that a child can close a loop: ``a`` links LR position ``i`` to a later
    ``j`` and ``b`` links ``j`` back to ``i`` (a child taking ``i`` from ``a`` and ``j`` from ``b``
    holds both links unless its repair removes one)."""
    while True:
        a, b = (random_creature(rng, n_nodes=(3, 6), brain_neurons=(2, 2), p_symmetry=0.5) for _ in range(2))
        forward = {(i, lk.child) for i, n in enumerate(a.nodes) for lk in n.children if lk.child > i}
        if _forward_only(a) and any((lk.child, j) in forward for j, n in enumerate(b.nodes) for lk in n.children):
            return a, b


def make_cases(rng):
    s = seeds(rng, 80)
    cases = []
    a, b = _parent_pair(rng, 4, 6)
    cases.append({"id": "basic", "args": [obj(a), obj(b), RNG], "seeds": [s[0]] * 4})
    a, b = _parent_pair(rng, 6, 8)
    cases.append({"id": "many", "args": [obj(a), obj(b), RNG], "seeds": s[1:41]})
    for k in range(6):
        a, b = _parent_pair(rng, 2, 7)
        cases.append({"id": f"pair{k}", "args": [obj(a), obj(b), RNG], "seeds": s[41 + 3 * k:44 + 3 * k]})
    more = seeds(rng, 3 * LOOP_SEEDS)  # drawn last: the other cases of a seed stay what they were
    for k in range(3):
        a, b = _cycle_prone_pair(rng)
        cases.append({"id": f"loop{k}", "args": [obj(a), obj(b), RNG], "seeds": more[k * LOOP_SEEDS:(k + 1) * LOOP_SEEDS]})
    a, b = _parent_pair(rng, 10, 12)  # long parents: three blocks or more in most calls (drawn after the rest)
    cases.append({"id": "long", "args": [obj(a), obj(b), RNG], "seeds": seeds(rng, LONG_SEEDS)})
    for case in cases:
        case["max_len"] = MAX_JSON
    return cases


CASES = ("basic", "many") + tuple(f"pair{k}" for k in range(6)) + ("long",)
LOOP_SEEDS = 12
LONG_SEEDS = 30
LOOP_CASES = tuple(f"loop{k}" for k in range(3))


def no_loops(ctx):
    """On parents whose links can close a loop in a child, every child is a valid creature."""
    for cid in LOOP_CASES:
        rec = ctx.records.get(cid) or {"status": "no result"}
        if rec.get("status") != "ok":
            return False, (f"on parents whose links can close a loop (test input {cid!r}) it failed: "
                           f"{str(rec.get('error', rec.get('status')))[:200]}. The repair removes a link that would close a "
                           "cycle, and a new link for an orphan must not close one either")
        for k, text in enumerate(ctx.out(cid)):
            try:
                parse(text)
            except (ValueError, TypeError) as exc:
                return False, f"on parents whose links can close a loop (test input {cid!r}), call {k + 1} gave an invalid creature: {exc}"
    return True, f"no loop in {LOOP_SEEDS * len(LOOP_CASES)} children of parents whose links could close one"


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
            yield cid, k, a, b, parse(text)


def blocks(ctx):
    for cid, k, a, b, child in _each_child(ctx, CASES):
        locs, why = _trace(a, b, child)
        if locs is None:
            return False, f"on test input {cid!r} (call {k + 1}): {why}"
        got = set(locs)
        if not any(got <= taken for taken in _patterns(a, b).values()):
            shown = ", ".join(f"{'ab'[s]}[{p}]" for s, p in sorted(locs, key=lambda t: (t[1], t[0])))
            return False, (f"on test input {cid!r} (call {k + 1}) the child holds the LR positions {shown}; that is not "
                           "positions [0, n) of a, the next m of b, the next n of a, ... for any n, m >= 1")
    return True, "the child's nodes come from alternating LR blocks of a and b, at their positions"


def kept(ctx):
    for cid, k, a, b, child in _each_child(ctx, CASES):
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


def links_kept(ctx):
    for cid, k, a, b, child in _each_child(ctx, CASES):
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


def mixes(ctx):
    n = mixed = 0
    for cid, _, a, b, child in _each_child(ctx, CASES):
        only_a = set(map(body_signature, a.nodes)) - set(map(body_signature, b.nodes))
        only_b = set(map(body_signature, b.nodes)) - set(map(body_signature, a.nodes))
        mine = set(map(body_signature, child.nodes))
        n += 1
        mixed += bool(mine & only_a) and bool(mine & only_b)
    if mixed >= n / 4:
        return True, f"in {mixed} of {n} calls the child holds nodes of both parents"
    return False, (f"in only {mixed} of {n} calls did the child hold nodes of both parents; recombination takes "
                   "alternating blocks from a and b. Nothing else is judged until it does")


def random_blocks(ctx):
    a, b = ctx.arg("many", 0), ctx.arg("many", 1)
    sets = []
    for text in ctx.out("many"):
        locs, _ = _trace(a, b, parse(text))
        if locs is None:
            return False, "not checked until the child's nodes can be traced to LR blocks"
        sets.append(frozenset(locs))
    if not any(s for t in sets for s, _ in t if s == 1):
        return False, f"in {len(sets)} calls the child never took a node from b; n and m are random, so b's nodes appear"
    if len(set(sets)) < 3:
        return False, f"in {len(sets)} calls with different seeds the child took the same LR blocks almost every time; draw n and m at random in every call"
    return True, f"{len(set(sets))} different block patterns in {len(sets)} calls"


def alternates(ctx):
    """Some child goes back to ``a`` after a block of ``b``: the blocks alternate, not one cut."""
    n = 0
    for cid in ("many", "long"):
        a, b = ctx.arg(cid, 0), ctx.arg(cid, 1)
        for text in ctx.out(cid):
            locs, _ = _trace(a, b, parse(text))
            if locs is None:
                return False, "not checked until the child's nodes can be traced to LR blocks"
            n += 1
            first_b = min((pos for src, pos in locs if src == 1), default=None)
            if first_b is not None and any(src == 0 and pos > first_b for src, pos in locs):
                return True, "the blocks alternate: a, b, a, ..."
    return False, (f"in {n} calls no child took nodes of a again after a block of b; the blocks alternate until the "
                   "positions run out: n from a, m from b, n from a again, m from b again, ...")
