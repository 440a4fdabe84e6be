"""Checks for exercise 02 (genetic pictures: decoding and the four mutations).

The grading rationale both picture exercises share -- the job gates, the false-failure rates of
the statistical properties, how genomes travel and the case genomes -- is in
:mod:`~coursekit.grading.checks.picture_genomes`.
"""

from __future__ import annotations

import json

from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.picture_genomes import (
    MAX_JSON, N_STAT, REPEATS, Bad, both_occur, changes, diff, distinct_pair, each, lib, obj, one_string, reaching_tail,
    region, results, row_name, rows, valid)
from coursekit.grading.checks.properties import NEW_GENOME, RNG, deterministic, seeds, unmodified


#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
_CHANGES = ("A mutation must change the genome: return a new genome with one change, not the input or a copy of it.",
            "Pick a string at random with the rng, then a position (or two) in it, then build the changed string.",
            "Genomes are immutable: build new chromosome tuples and a new ChromosomeString / Genome from them.")
HINTS = {
    "pictures.decode": (
        ("builds a tree below the root", (
            "A function symbol takes as many children as its arity (P.arity(name)); read them from the string.",
            "Read breadth-first: the root's children are the next symbols, then their children, level by level.",
            "A queue (collections.deque) of nodes still waiting for their children does it in one pass.")),
    ),
    "pictures.transposition": (("changes the genome", _CHANGES),),
    "pictures.root_transposition": (("changes the genome", _CHANGES),),
    "pictures.substitution": (("changes a chromosome", _CHANGES),),
    "pictures.head_tail_rotation": (("changes the genome", _CHANGES),),
}


# -- decoding (section 3.1) ----------------------------------------------------------------------


def karva(symbols):
    """The grader's own breadth-first (Karva) reading: the tree as a nested list."""
    _, P = lib()
    kids, level, nxt = [()] * len(symbols), [0], 1
    while level:
        new = []
        for i in level:
            a = P.arity(symbols[i])
            kids[i] = tuple(range(nxt, nxt + a))
            new += kids[i]
            nxt += a
        level = new

    def build(i):
        return [symbols[i]] + [build(j) for j in kids[i]] if kids[i] else symbols[i]

    return build(0)


def _random_symbols(rng, h, function_rate=0.75):
    _, P = lib()
    funcs, terms = P.functions(), P.terminals()
    head = [str(rng.choice(funcs)) if rng.random() < function_rate else str(rng.choice(terms)) for _ in range(h)]
    return head + [str(rng.choice(terms)) for _ in range(h + 1)]


def _decode_cases(rng):
    _, P = lib()
    unary = [n for n in P.functions() if P.arity(n) == 1]
    binary = [n for n in P.functions() if P.arity(n) == 2]
    terms = P.terminals()
    fixed = {
        "example": ["plus", "sin", "x", "y", "const"],
        "terminal_root": [str(rng.choice(terms))] + _random_symbols(rng, 4)[1:],
        "all_binary": [str(s) for s in rng.choice(binary, size=4)] + [str(s) for s in rng.choice(terms, size=5)],
        "unary_chain": [str(s) for s in rng.choice(unary, size=5)] + [str(s) for s in rng.choice(terms, size=6)],
        "mixed": [str(rng.choice(unary)), str(rng.choice(binary)), str(rng.choice(unary)), str(rng.choice(binary)),
                  str(rng.choice(binary)), str(rng.choice(unary))] + [str(s) for s in rng.choice(terms, size=7)],
    }
    fixed.update({f"random{i}": _random_symbols(rng, int(rng.integers(1, 9))) for i in range(12)})
    # long heads: too many shapes to have been tabulated with the library's karva before grading began
    # (red team: a lookup table over every head of up to 8 symbols, built in a cell, earned 2/2)
    fixed.update({f"long{i}": _random_symbols(rng, int(rng.integers(20, 33))) for i in range(3)})
    # "symbols" is the grader's own copy: a function that consumes its argument list in place must
    # not change what the properties compare with (formative checks may run in threads)
    return [{"id": cid, "args": [syms], "symbols": list(syms), "seeds": [0], "max_len": 50_000}
            for cid, syms in fixed.items()]


def _tree(ctx, cid):
    return json.loads(ctx.out(cid)[0])


def _nodes(tree):
    """``[(symbol, children)]`` in any order; Bad for anything but the nested-list form."""
    _, P = lib()
    out, stack = [], [tree]
    while stack:
        t = stack.pop()
        if isinstance(t, str):
            sym, kids = t, []
        elif isinstance(t, list) and t and isinstance(t[0], str):
            sym, kids = t[0], t[1:]
        else:
            raise Bad(f"found {json.dumps(t)[:80]} in the tree; a terminal is its name (a str) and a function "
                      f"a list [name, child, ...]")
        if sym not in P.PRIMITIVES:
            raise Bad(f"found {sym!r} in the tree, which is not a primitive name")
        out.append((sym, kids))
        stack += kids
    return out


def _decode_form(ctx):
    for cid in ctx.cases:
        try:
            _nodes(_tree(ctx, cid))
        except Bad as exc:
            return False, f"decode({ctx.case(cid)['symbols']}): {exc}"
    return True, "returns a nested-list tree of primitive names"


def _decode_builds(ctx):
    _, P = lib()
    for cid in ctx.cases:
        syms, tree = ctx.case(cid)["symbols"], _tree(ctx, cid)
        if P.arity(syms[0]) > 0 and not (isinstance(tree, list) and len(tree) > 1):
            return False, (f"decode({syms}) returned {json.dumps(tree)[:80]}, with nothing below the root; the root "
                           f"{syms[0]!r} takes {P.arity(syms[0])} argument(s), so the tree goes on. Nothing else is "
                           "judged until it does")
    return True, "builds a tree below every function root"


def _decode_arity(ctx):
    _, P = lib()
    for cid in ctx.cases:
        for sym, kids in _nodes(_tree(ctx, cid)):
            if len(kids) != P.arity(sym):
                return False, (f"decode({ctx.case(cid)['symbols']}): node {sym!r} has {len(kids)} children, "
                               f"but its arity is {P.arity(sym)}")
    return True, "every node has as many children as its arity"


def _decode_root(ctx):
    for cid in ctx.cases:
        syms, tree = ctx.case(cid)["symbols"], _tree(ctx, cid)
        root = tree if isinstance(tree, str) else tree[0]
        if root != syms[0]:
            return False, f"decode({syms}): the root is {root!r}, but the root is always the first chromosome ({syms[0]!r})"
    return True, "the root is the first chromosome"


def _bare(tree):
    """``tree`` with one-element lists (a terminal written ``["x"]``) made bare names."""
    if isinstance(tree, list):
        return tree[0] if len(tree) == 1 else [_bare(t) for t in tree]
    return tree


def _decode_karva(ctx):
    for cid in ctx.cases:
        syms = ctx.case(cid)["symbols"]
        if _tree(ctx, cid) != karva(syms):
            if _bare(_tree(ctx, cid)) == karva(syms):
                return False, (f"decode({syms}) gave {json.dumps(_tree(ctx, cid))}: the reading order is right, but a "
                               "terminal is its bare name (\"x\"), not a list of one name ([\"x\"])")
            return False, (f"decode({syms}) gave {json.dumps(_tree(ctx, cid))}, which is not the breadth-first "
                           f"reading: the children of one level are the next chromosomes of the string, "
                           f"left to right, level after level")
    return True, f"reads breadth-first (Karva) on {len(ctx.cases)} strings, non-coding tails ignored"


register(Check(
    hints=HINTS.get("pictures.decode", ()),
    name="pictures.decode", function="decode", params=("symbols",), points=2.0,
    title="Karva decoding of a chromosome string", output="json", cases=_decode_cases, gates=2,
    reference=('coursekit.pictures.genome:karva', 'coursekit.grading.checks.ex02_picture_mutations:karva'),
    library_uses=('coursekit.pictures.genome:karva',),
    props=(
        ("returns a nested-list tree", _decode_form),
        ("builds a tree below the root", _decode_builds),
        ("every node has its arity's children", _decode_arity),
        ("the root is the first chromosome", _decode_root),
        ("reads breadth-first (Karva)", _decode_karva),
    ),
))


# -- mutations (section 3.3.1) -------------------------------------------------------------------

MUT_CASES = ("basic", "many", "single")


def _mutation_cases(rng):
    s = seeds(rng, 2 + N_STAT + N_STAT // 2)
    g3, g5 = distinct_pair(rng, 3, 4)[0], distinct_pair(rng, 5, 3)[0]
    g1 = reaching_tail(lambda *a: distinct_pair(*a)[0], rng, 5)
    return [
        {"id": "basic", "args": [obj(g3), RNG], "seeds": [s[0]] * REPEATS, "max_len": MAX_JSON},
        {"id": "many", "args": [obj(g5), RNG], "seeds": s[2:2 + N_STAT], "max_len": MAX_JSON},
        {"id": "single", "args": [obj(g1), RNG], "seeds": s[2 + N_STAT:], "max_len": MAX_JSON},
    ]


def _one_string_change(parent, child):
    """The change of a mutation that should touch one string: ``"none"``, None (more than one string
    changed), or ``(changed positions, old chromosomes, new chromosomes, head length)``."""
    d = diff(parent, child)
    if not d:
        return "none"
    if len(d) > 1:
        return None
    k, pos = d[0]
    old, h = rows(parent)[k]
    return pos, old, rows(child)[k][0], h


def _transposition_kind(parent, child):
    """'swap', 'clone', 'none' or None (not a transposition) -- for one changed string."""
    change = _one_string_change(parent, child)
    if change in ("none", None):
        return change
    pos, old, new, _ = change
    if len(pos) == 2 and new[pos[0]] == old[pos[1]] and new[pos[1]] == old[pos[0]]:
        return "swap"
    if len(pos) == 1 and any(new[pos[0]] == old[j] for j in range(len(old)) if j != pos[0]):
        return "clone"
    return None


def _swap_or_clone(kind, neither):
    """A per-result judge: ``kind`` (a ``*_kind`` above) recognises the change, else it is ``neither``."""
    def judge_one(parent, child):
        if kind(parent, child) is None:
            d = diff(parent, child)
            return f"{row_name(d[0][0])} changed at positions {d[0][1]}, which is neither {neither}"
        return None

    return judge_one


def _swaps_and_clones(kind, what):
    """The property that ``kind`` sees both a swap and a clone over the calls with different seeds."""
    return lambda ctx: both_occur(ctx, MUT_CASES, kind, ("swap", "clone"), what)


def _no_root(parent, child):
    for k, pos in diff(parent, child):
        if 0 in pos:
            return (f"the root (position 0) of {row_name(k)} changed; transposition picks both chromosomes "
                    f"without the root")
    return None


def _same_region(parent, child):
    for k, pos in diff(parent, child):
        h = rows(parent)[k][1]
        regions = {region(k, i, h) for i in pos}
        if len(pos) > 2:
            return f"{len(pos)} chromosomes of {row_name(k)} changed; a transposition changes at most two"
        old = rows(parent)[k][0]
        new = rows(child)[k][0]
        if len(pos) == 1:  # a clone: where did it come from?
            if old[0] == new[pos[0]]:
                return f"position {pos[0]} of {row_name(k)} received a clone of the root; transposition never uses the root"
            regions |= {region(k, j, h) for j in range(1, len(old)) if old[j] == new[pos[0]] and j != pos[0]}
        if len(regions) > 1:
            return (f"in {row_name(k)} (head length {h}) a chromosome moved between head and tail; both chromosomes "
                    f"must lie in the head or both in the tail")
    return None


register(Check(
    hints=HINTS.get("pictures.transposition", ()),
    name="pictures.transposition", function="transposition", params=("genome", "rng"), points=2.0,
    title="transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:transposition',),
    props=(
        ("returns a valid genome of the same shape", valid(MUT_CASES)),
        ("changes the genome", changes(MUT_CASES)),
        ("changes one string only", each(MUT_CASES, one_string, "only one string changes")),
        ("never moves the root", each(MUT_CASES, _no_root, "the root of every string stays")),
        ("both chromosomes in the same region", each(MUT_CASES, _same_region, "both chromosomes lie in the head or both in the tail")),
        ("interchange or clone", each(MUT_CASES, _swap_or_clone(_transposition_kind, "an interchange of two of its "
                                      "chromosomes nor one replaced by a clone of another"),
                                      "each result is an interchange or a clone")),
        ("both interchange and clone occur", _swaps_and_clones(
            _transposition_kind, "transposition either interchanges the two chromosomes or replaces the first by a "
                                 "clone of the second, and both should happen")),
        ("deterministic for a seed", deterministic("basic")),
        ("input unchanged", unmodified({0: "genome"}, NEW_GENOME, what="the genome {name}")),
    ),
))


def _root_kind(parent, child):
    change = _one_string_change(parent, child)
    if change in ("none", None):
        return change
    pos, old, new, h = change
    if len(pos) == 2 and pos[0] == 0 and pos[1] < h and new[0] == old[pos[1]] and new[pos[1]] == old[0]:
        return "swap"
    if pos == [0] and any(new[0] == old[j] for j in range(1, h)):
        return "clone"
    return None


def _root_only(parent, child):
    for k, pos in diff(parent, child):
        h = rows(parent)[k][1]
        if 0 not in pos or len(pos) > 2 or any(i >= h for i in pos):
            return (f"{row_name(k)} (head length {h}) changed at positions {pos}; root transposition changes the root "
                    f"(position 0) and at most one other head chromosome")
    return None


register(Check(
    hints=HINTS.get("pictures.root_transposition", ()),
    name="pictures.root_transposition", function="root_transposition", params=("genome", "rng"), points=2.0,
    title="root transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:root_transposition',),
    props=(
        ("returns a valid genome of the same shape", valid(MUT_CASES)),
        ("changes the genome", changes(MUT_CASES)),
        ("changes one string only", each(MUT_CASES, one_string, "only one string changes")),
        ("changes the root and one head chromosome", each(MUT_CASES, _root_only, "only the root and one head chromosome change")),
        ("interchange or clone", each(MUT_CASES, _swap_or_clone(_root_kind, "the root interchanged with another head "
                                      "chromosome nor the root replaced by a clone of one"),
                                      "each result is an interchange or a clone")),
        ("both interchange and clone occur", _swaps_and_clones(
            _root_kind, "the root is either interchanged with a second head chromosome or replaced by a clone of it, "
                        "and both should happen")),
        ("deterministic for a seed", deterministic("basic")),
        ("input unchanged", unmodified({0: "genome"}, NEW_GENOME, what="the genome {name}")),
    ),
))


def _at_most_one(parent, child):
    d = diff(parent, child)
    n = sum(len(p) for _, p in d)
    if n > 1:
        return f"{n} chromosomes changed ({', '.join(f'{row_name(k)} at {p}' for k, p in d)}); substitution replaces one"
    return None


def _substituted(ctx):
    """``[(seed, key, position, head_length, new chromosome)]`` of every call that changed one chromosome."""
    out = []
    for cid in MUT_CASES:
        for seed, parent, child in results(ctx, cid):
            d = diff(parent, child)
            if len(d) == 1 and len(d[0][1]) == 1:
                k, [i] = d[0]
                out.append((seed, k, i, rows(parent)[k][1], rows(child)[k][0][i]))
    return out


def _substitution_changes(ctx):
    n = sum(len(ctx.out(cid)) for cid in MUT_CASES)
    changed = len(_substituted(ctx))
    if changed < n / 2:
        return False, (f"only {changed} of {n} calls changed a chromosome; substitution replaces one by a new "
                       f"random chromosome, which almost always differs. Nothing else is judged until it does")
    return True, f"{changed} of {n} calls replaced a chromosome"


def _substitution_random(ctx):
    _, P = lib()
    subs = _substituted(ctx)
    for seed, k, i, h, c in subs:
        for spec, v in zip(P.get(c.symbol).params, c.params):
            if not spec.low <= v <= spec.high:
                return False, (f"with rng seed {seed} the new chromosome {c.label()} has {spec.name} = {v:g}, outside "
                               f"the range {spec.low:g}..{spec.high:g} its random values are drawn from")
    symbols = {c.symbol for *_, c in subs}
    if len(symbols) < 8:
        return False, (f"over {len(subs)} substitutions the new chromosomes used only {len(symbols)} different "
                       f"primitives ({', '.join(sorted(symbols))}); the new chromosome is randomly generated")
    return True, f"new chromosomes are random ({len(symbols)} primitives, parameters in range)"


def _substitution_anywhere(ctx):
    subs = _substituted(ctx)
    regions = {region(k, i, h) for _, k, i, h, _ in subs}
    strings = {k for _, k, *_ in subs}
    if regions != {"head", "tail"} or len(strings) < 2:
        return False, (f"over {len(subs)} substitutions the replaced chromosomes were in {' and '.join(sorted(regions)) or 'no region'} "
                       f"of {len(strings)} string(s); any chromosome of a randomly chosen string may be replaced")
    return True, f"replaces chromosomes in head and tail of {len(strings)} different strings"


register(Check(
    hints=HINTS.get("pictures.substitution", ()),
    name="pictures.substitution", function="substitution", params=("genome", "rng"), points=2.0,
    title="substitution", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:substitution',),
    props=(
        ("returns a valid genome of the same shape", valid(MUT_CASES)),
        ("changes a chromosome", _substitution_changes),
        ("changes at most one chromosome", each(MUT_CASES, _at_most_one, "at most one chromosome changes")),
        ("the new chromosome is random", _substitution_random),
        ("any position can be replaced", _substitution_anywhere),
        ("deterministic for a seed", deterministic("basic")),
        ("input unchanged", unmodified({0: "genome"}, NEW_GENOME, what="the genome {name}")),
    ),
))


def _rotation(parent, child):
    """``(region, steps)`` of a head or tail rotation, or a message saying why it is not one."""
    d = diff(parent, child)
    if not d:
        return None, "nothing changed; one region is rotated by 1 to len-1 steps, which always changes it"
    if len(d) > 1:
        return None, f"changed {len(d)} strings; a rotation works on one string"
    k, _ = d[0]
    old, h = rows(parent)[k]
    new = rows(child)[k][0]
    parts = [("head", 0, h)] + ([] if k == "pre" else [("tail", h, len(old))])
    for part, lo, hi in parts:
        o, n = list(old[lo:hi]), list(new[lo:hi])
        rest_equal = list(old[:lo]) + list(old[hi:]) == list(new[:lo]) + list(new[hi:])
        for s in range(1, len(o)):
            if rest_equal and n == o[s:] + o[:s]:
                return (part, s), None
    return None, (f"{row_name(k)} (head length {h}) is not its head or its tail cyclically shifted with the other "
                  f"part unchanged")


def _rotation_shift(parent, child):
    return _rotation(parent, child)[1]


def _rotation_varies(ctx):
    seen = [_rotation(p, c)[0] for cid in MUT_CASES for _, p, c in results(ctx, cid)]
    if None in seen:
        return False, "not checked: not every result is a rotation"
    regions = {r for r, _ in seen}
    steps = {s for _, s in seen}
    if regions != {"head", "tail"} or len(steps) < 2:
        return False, (f"over {len(seen)} calls the rotations were of the {' and '.join(sorted(regions))} only, by "
                       f"{sorted(steps)} steps; the head or the tail (either) is rotated several steps")
    return True, f"rotates heads and tails by {len(steps)} different step counts"


register(Check(
    hints=HINTS.get("pictures.head_tail_rotation", ()),
    name="pictures.head_tail_rotation", function="head_tail_rotation", params=("genome", "rng"), points=2.0,
    title="head/tail rotation", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:head_tail_rotation',),
    props=(
        ("returns a valid genome of the same shape", valid(MUT_CASES)),
        ("changes the genome", changes(MUT_CASES)),
        ("changes one string only", each(MUT_CASES, one_string, "only one string changes")),
        ("a cyclic shift of exactly one region", each(MUT_CASES, _rotation_shift, "each result rotates the head or the tail of one string")),
        ("head and tail, several steps", _rotation_varies),
        ("deterministic for a seed", deterministic("basic")),
        ("input unchanged", unmodified({0: "genome"}, NEW_GENOME, what="the genome {name}")),
    ),
))

exercise("02_picture_mutations", ["pictures.decode", "pictures.transposition", "pictures.root_transposition",
                                  "pictures.substitution", "pictures.head_tail_rotation"])


