"""Checks for exercise 02 (genetic pictures: decoding and the four mutations).

The grading rationale both picture exercises share -- the job gates, the false-failure rates of
the statistical properties, how genomes travel and the case genomes -- is in
:mod:`~coursekit.grading.checks.picture_genomes`.
"""

from __future__ import annotations

import json

from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.picture_genomes import (
    MAX_JSON, N_STAT, REPEAT_SEEDS, REPEATS, Bad, both_occur, changes, diff, distinct_pair, each, lib, obj, one_string,
    operator_props, reaching_tail, region, repeat_genomes, results, row_name, rows, valid)
from coursekit.grading.checks.properties import RNG, point, repeated, seeds


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


def _decode_bare(ctx):
    for cid in ctx.cases:
        tree = _tree(ctx, cid)
        if _bare(tree) != tree:
            return False, (f"decode({ctx.case(cid)['symbols']}) gave {json.dumps(tree)}: a terminal is its bare name "
                           "(\"x\"), not a list of one name ([\"x\"])")
    return True, "every terminal is its bare name"


def _decode_karva(ctx):
    """The reading order, judged on the tree with terminals as bare names (how they are written is
    :func:`_decode_bare`'s business)."""
    for cid in ctx.cases:
        syms = ctx.case(cid)["symbols"]
        if _bare(_tree(ctx, cid)) != karva(syms):
            return False, (f"decode({syms}) gave {json.dumps(_tree(ctx, cid))}, which is not the breadth-first "
                           f"reading: the children of one level are the next chromosomes of the string, "
                           f"left to right, level after level")
    return True, f"reads breadth-first (Karva) on {len(ctx.cases)} strings, non-coding tails ignored"


_DECODE = (
    ("returns a nested-list tree", _decode_form),
    ("builds a tree below the root", _decode_builds),
    ("every node has its arity's children", _decode_arity),
    ("the root is the first chromosome", _decode_root),
    ("a terminal is its bare name", _decode_bare),
    ("reads breadth-first (Karva)", _decode_karva),
)


register(Check(
    hints=HINTS.get("pictures.decode", ()),
    name="pictures.decode", function="decode", params=("symbols",), points=2.0,
    title="Karva decoding of a chromosome string", output="json", cases=_decode_cases, gates=2,
    reference=('coursekit.pictures.genome:karva', 'coursekit.grading.checks.ex02_picture_mutations:karva'),
    library_uses=('coursekit.pictures.genome:karva',),
    props=_DECODE,
    weights=point("reads breadth-first (Karva)", _DECODE),  # depth-first kept 83 % before
))


# -- mutations (section 3.3.1) -------------------------------------------------------------------

MUT_CASES = ("basic", "many", "single")
#: What transposition, root transposition and rotation judge first: a valid genome (gate), changed (the job,
#: a gate), in one string only.
_IN_ONE_STRING = (
    ("returns a valid genome of the same shape", valid(MUT_CASES)),
    ("changes the genome", changes(MUT_CASES)),
    ("changes one string only", each(MUT_CASES, one_string, "only one string changes")),
)


def _mutation_cases(rng):
    s = seeds(rng, REPEAT_SEEDS + N_STAT + N_STAT // 2)
    g6, g5 = repeat_genomes(rng)[0], distinct_pair(rng, 5, 3)[0]
    g1 = reaching_tail(lambda *a: distinct_pair(*a)[0], rng, 5)
    r = REPEAT_SEEDS
    return [
        {"id": "basic", "args": [obj(g6), RNG], "seeds": repeated(s[:r], REPEATS), "max_len": MAX_JSON},
        {"id": "many", "args": [obj(g5), RNG], "seeds": s[r:r + N_STAT], "max_len": MAX_JSON},
        {"id": "single", "args": [obj(g1), RNG], "seeds": s[r + N_STAT:], "max_len": MAX_JSON},
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


_TRANSPOSITION = operator_props(
    _IN_ONE_STRING,
    # the point: what changes (never the root, both chromosomes in one region, an interchange or a clone), and
    # that both outcomes occur
    "interchange or clone in one region, never the root",
    each(MUT_CASES, _no_root, "the root of every string stays"),
    each(MUT_CASES, _same_region, "both chromosomes lie in the head or both in the tail"),
    each(MUT_CASES, _swap_or_clone(_transposition_kind, "an interchange of two of its chromosomes nor one replaced "
                                   "by a clone of another"), "each result is an interchange or a clone"),
    _swaps_and_clones(_transposition_kind, "transposition either interchanges the two chromosomes or replaces the "
                                           "first by a clone of the second, and both should happen"))

register(Check(
    hints=HINTS.get("pictures.transposition", ()),
    name="pictures.transposition", function="transposition", params=("genome", "rng"), points=2.0,
    title="transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:transposition',),
    props=_TRANSPOSITION,
    weights=point(_TRANSPOSITION[3][0], _TRANSPOSITION),  # the root moved, or never a clone: 80-90 % before
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


_ROOT_TRANSPOSITION = operator_props(
    _IN_ONE_STRING,
    # the point: the root and one head chromosome change, by an interchange or a clone, and both outcomes occur
    "the root interchanged with a head chromosome or cloned from one",
    each(MUT_CASES, _root_only, "only the root and one head chromosome change"),
    each(MUT_CASES, _swap_or_clone(_root_kind, "the root interchanged with another head chromosome nor the root "
                                   "replaced by a clone of one"), "each result is an interchange or a clone"),
    _swaps_and_clones(_root_kind, "the root is either interchanged with a second head chromosome or replaced by a "
                                  "clone of it, and both should happen"))

register(Check(
    hints=HINTS.get("pictures.root_transposition", ()),
    name="pictures.root_transposition", function="root_transposition", params=("genome", "rng"), points=2.0,
    title="root transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:root_transposition',),
    props=_ROOT_TRANSPOSITION,
    weights=point(_ROOT_TRANSPOSITION[3][0], _ROOT_TRANSPOSITION),  # never a clone: 89 % before
))


def _at_most_one(parent, child):
    d = diff(parent, child)
    n = sum(len(p) for _, p in d)
    if n > 1:
        return f"{n} chromosomes changed ({', '.join(f'{row_name(k)} at {p}' for k, p in d)}); substitution replaces one"
    return None


#: The substitution's cases: the mutations' and ``"ring"``, whose PreHeader is a fifth of the genome.
SUB_CASES = MUT_CASES + ("ring",)


def _substitution_cases(rng):
    """The mutations' cases, and 4 strings of head 1 (tail 2) joined by a PreHeader of 3 (15 chromosomes),
    called with :data:`N_STAT` seeds, so that a correct substitution reaches the PreHeader
    (:func:`_substitution_anywhere`)."""
    cases = _mutation_cases(rng)
    cases.append({"id": "ring", "args": [obj(distinct_pair(rng, 4, 1)[0]), RNG], "seeds": seeds(rng, N_STAT),
                  "max_len": MAX_JSON})
    return cases


def _substituted(ctx):
    """``[(seed, key, position, head_length, the string's chromosomes before, new chromosome)]`` of every
    call that changed one chromosome."""
    out = []
    for cid in SUB_CASES:
        for seed, parent, child in results(ctx, cid):
            d = diff(parent, child)
            if len(d) == 1 and len(d[0][1]) == 1:
                k, [i] = d[0]
                old, h = rows(parent)[k]
                out.append((seed, k, i, h, old, rows(child)[k][0][i]))
    return out


def _substitution_changes(ctx):
    n = sum(len(ctx.out(cid)) for cid in SUB_CASES)
    changed = len(_substituted(ctx))
    if changed < n / 2:
        return False, (f"only {changed} of {n} calls changed a chromosome; substitution replaces one by a new "
                       f"random chromosome, which almost always differs. Nothing else is judged until it does")
    return True, f"{changed} of {n} calls replaced a chromosome"


def _substitution_random(ctx):
    _, P = lib()
    subs = _substituted(ctx)
    for seed, k, i, h, _, c in subs:
        for spec, v in zip(P.get(c.symbol).params, c.params):
            if not spec.low <= v <= spec.high:
                return False, (f"with rng seed {seed} the new chromosome {c.label()} has {spec.name} = {v:g}, outside "
                               f"the range {spec.low:g}..{spec.high:g} its random values are drawn from")
    symbols = {c.symbol for *_, c in subs}
    if len(symbols) < 8:
        return False, (f"over {len(subs)} substitutions the new chromosomes used only {len(symbols)} different "
                       f"primitives ({', '.join(sorted(symbols))}); the new chromosome is randomly generated")
    return True, f"new chromosomes are random ({len(symbols)} primitives, parameters in range)"


def _substitution_fresh(ctx):
    """Not a copy strategy: a new chromosome equal to another one of its string in fewer than half the
    ~160 substitutions. The case strings hold no chromosome twice, and a random chromosome with
    parameters never equals one of them; a parameterless one (x, plus, sin ...) does when its
    primitive is drawn again: in 6.5 % of the calls on average, at most 14 % in one grading (the
    library's and the solution's substitution, 100 gradings each), and never with probability above
    1/3 in one call (a tail holding all five parameterless terminals). Half or more is then below
    exp(-2 * 160 * 0.35^2) < 1e-16 (Hoeffding, at a mean of 15 %). Copying another chromosome of the
    string (a transposition's clone) does it every time."""
    subs = _substituted(ctx)
    copies = [(seed, k, i, c) for seed, k, i, _, old, c in subs if any(c == x for j, x in enumerate(old) if j != i)]
    if len(copies) >= len(subs) / 2:
        seed, k, i, c = copies[0]
        return False, (f"in {len(copies)} of {len(subs)} substitutions the new chromosome equals another chromosome of "
                       f"the same string (with rng seed {seed}: {c.label()} at position {i} of {row_name(k)}); the new "
                       f"chromosome is randomly generated, and a random one repeats one already in the string only "
                       f"now and then")
    return True, f"{len(subs) - len(copies)} of {len(subs)} new chromosomes differ from every chromosome of their string"


def _substitution_functions(ctx):
    """A head position may receive a function: a correct substitution draws one at 75 % (library) or ~69 %
    (uniform over the primitives) of the head positions it replaces, about 70 of them per grading, so
    none in 15 or more happens with probability below 0.31^15 < 3e-8."""
    _, P = lib()
    heads = [c for _, k, i, h, _, c in _substituted(ctx) if region(k, i, h) == "head"]
    if len(heads) >= 15 and not any(P.arity(c.symbol) for c in heads):
        return False, (f"over {len(heads)} substitutions at head positions the new chromosome was a terminal every "
                       f"time; a head position may receive any primitive, a function as well as a terminal")
    functions = sum(P.arity(c.symbol) > 0 for c in heads)
    return True, f"head positions received functions ({functions} of {len(heads)}) and terminals"


def _substitution_anywhere(ctx):
    """Head and tail positions of several strings, and the PreHeader (a string, all head, in the
    exercise's text). Picking the string uniformly (as coursekit's own does, among those that code), a
    correct substitution misses the PreHeader in every call with probability (6/7)^3 (basic: 3 seeds,
    7 strings) x (5/6)^60 (many) x (4/5)^60 (ring) = 1.7e-11; picking a chromosome uniformly over the
    genome, (66/71)^3 x (35/39)^60 x (12/15)^60 = 1.9e-9 (60 calls of "many" alone: 1.5e-3, one
    grading in ~650)."""
    subs = _substituted(ctx)
    regions = {region(k, i, h) for _, k, i, h, *_ in subs}
    strings = {k for _, k, *_ in subs}
    if regions != {"head", "tail"} or len(strings) < 2:
        return False, (f"over {len(subs)} substitutions the replaced chromosomes were in {' and '.join(sorted(regions)) or 'no region'} "
                       f"of {len(strings)} string(s); any chromosome of a randomly chosen string may be replaced")
    if "pre" not in strings:
        return False, (f"over {len(subs)} substitutions none replaced a chromosome of the PreHeader; the PreHeader "
                       f"counts as a string (all head), and any chromosome of a randomly chosen string may be replaced")
    return True, f"replaces chromosomes in head and tail of {len(strings)} different strings, the PreHeader too"


_SUBSTITUTION = operator_props(
    (
        ("returns a valid genome of the same shape", valid(SUB_CASES)),
        ("changes a chromosome", _substitution_changes),
        ("changes at most one chromosome", each(SUB_CASES, _at_most_one, "at most one chromosome changes")),
    ),
    # the point: a random new chromosome (not one of the string's), valid for its place (functions at head
    # positions too), at any position of any string
    "any chromosome replaced by a random one for its place",
    _substitution_random, _substitution_fresh, _substitution_functions, _substitution_anywhere)

register(Check(
    hints=HINTS.get("pictures.substitution", ()),
    name="pictures.substitution", function="substitution", params=("genome", "rng"), points=2.0,
    title="substitution", output="json", cases=_substitution_cases, gates=2,
    reference=('coursekit.pictures.operators:substitution',),
    props=_SUBSTITUTION,
    # a copy of the string's chromosomes, terminals only, never the PreHeader: 100 % before
    weights=point(_SUBSTITUTION[3][0], _SUBSTITUTION),
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


_ROTATION = operator_props(
    _IN_ONE_STRING,
    # the point: each result shifts one region cyclically, and heads and tails are rotated by several step counts
    "the head or the tail shifted cyclically, several steps",
    each(MUT_CASES, _rotation_shift, "each result rotates the head or the tail of one string"),
    _rotation_varies)

register(Check(
    hints=HINTS.get("pictures.head_tail_rotation", ()),
    name="pictures.head_tail_rotation", function="head_tail_rotation", params=("genome", "rng"), points=2.0,
    title="head/tail rotation", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:head_tail_rotation',),
    props=_ROTATION,
    weights=point(_ROTATION[3][0], _ROTATION),  # both regions rotated, or the head only: 75-88 % before
))

exercise("02_picture_mutations", ["pictures.decode", "pictures.transposition", "pictures.root_transposition",
                                  "pictures.substitution", "pictures.head_tail_rotation"])


