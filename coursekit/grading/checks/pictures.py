"""Checks for exercises 02 and 03 (genetic pictures: decoding, the four mutations, the three recombinations).

Implements the grading side of the seed paper's section 3 operators: decoding a chromosome
string (3.1, Karva reading as in Gene Expression Programming), the mutations of section 3.3.1
(transposition, root transposition, substitution, head/tail rotation) and the recombinations of
section 3.3.2 (crossover, random copy, random interpolation), with the exact signatures of
:mod:`coursekit.pictures.operators`.

Statistical properties and their false-failure rates for a correct operator (every case
genome and seed comes from the grader's generator): "both outcomes occur" (interchange and
clone, head and tail) over 60-92 calls misses an outcome of probability >= 0.3 with
probability below 1e-8; "changes a chromosome" / "blends a pair" need half of the calls to
change something where a correct operator changes more than 90 %; "random" properties ask for
variety (8 of the 42 primitives over ~90 substitutions, 3 cut positions, u on both sides of
1/2) that a uniform random choice misses with probability far below 1e-8.

Each check's second property is its *job*, a gate (see :class:`~coursekit.grading.checks.Check`):
decoding builds a tree below a function root, a mutation changes the genome in at least half of
the calls, a recombination's children hold material of both parents in at least half of the
calls (correct operators: every call), interpolation blends a pair. Until it holds nothing else
is judged, so identity mutations, ``return a, b`` and deep copies score 0.

Genomes travel as JSON text (``Genome.to_json``) and come back as JSON text; every property
parses them with the grader's own import of the library and judges plain data. Properties are
the paper's definitions, never a comparison with one reference output: what may change and how
(one string, never the root, one region, an interchange or a clone, a cyclic shift, parents'
material at the same positions, values between the parents'), statistics over many seeds,
determinism for a seed and inputs left unmodified.

Case genomes are built so that every outcome can be read off the result: within a string (and
across the two parents' strings) no two chromosomes are equal, so an interchange, a clone, a
rotation or a copy is never invisible.
"""

from __future__ import annotations

import json

import numpy as np

from coursekit.grading.checks import Check, exercise, register

RNG = {"rng": True}
GENOME = "coursekit.pictures.genome:Genome"
MAX_JSON = 200_000
N_STAT = 60  # calls per statistical case (an outcome of probability 0.3 is missed with p = 0.7**60 < 1e-8)


def _seeds(rng, n):
    return [int(s) for s in rng.integers(0, 2**31, size=n)]


def _lib():
    from coursekit.pictures import genome, primitives

    return genome, primitives


# -- case genomes --------------------------------------------------------------------------------


def _distinct_pair(rng, n_strings, h):
    """Two genomes of one shape; no chromosome symbol repeats inside a string pair (both parents)."""
    G, P = _lib()
    terms, funcs = P.terminals(), P.functions()
    # heads avoid the parameterless terminals (x, y, ...), so a head chromosome never equals a tail one
    names = funcs + [n for n in terms if P.get(n).params]
    if 2 * (h + 1) > len(terms):
        raise ValueError(f"h: {h} too long for distinct tails")
    parents = [[], []]
    for _ in range(n_strings):
        head = rng.choice(names, size=2 * h, replace=False)
        tail = rng.choice(terms, size=2 * (h + 1), replace=False)
        for p in (0, 1):
            syms = list(head[p * h:(p + 1) * h]) + list(tail[p * (h + 1):(p + 1) * (h + 1)])
            parents[p].append(G.ChromosomeString(h, tuple(G.Chromosome.random(rng, str(s)) for s in syms)))
    n_pre = n_strings - 1
    pre = rng.choice(funcs, size=2 * n_pre, replace=False)
    return tuple(G.Genome(tuple(parents[p]), tuple(G.Chromosome.random(rng, str(s)) for s in pre[p * n_pre:(p + 1) * n_pre]))
                 for p in (0, 1))


def _same_symbols_pair(rng, n_strings, h):
    """Two genomes with the same symbols everywhere (all with parameters), different parameters."""
    G, P = _lib()
    with_params = [n for n in P.names() if P.get(n).params]
    terms = [n for n in with_params if P.arity(n) == 0]
    binary = [n for n in with_params if P.arity(n) == 2]
    strings = [list(rng.choice(with_params, size=h)) + list(rng.choice(terms, size=h + 1)) for _ in range(n_strings)]
    pre = list(rng.choice(binary, size=n_strings - 1))

    def genome():
        return G.Genome(tuple(G.ChromosomeString(h, tuple(G.Chromosome.random(rng, str(s)) for s in syms)) for syms in strings),
                        tuple(G.Chromosome.random(rng, str(s)) for s in pre))

    return genome(), genome()


def _obj(g):
    return {"object": GENOME, "json": g.to_json()}


# -- reading results -----------------------------------------------------------------------------


class Bad(Exception):
    """An output that is not a valid genome of the expected shape (message for the student)."""


def _rows(g):
    """``{key: (chromosomes, head_length)}``: strings by index, the PreHeader as 'pre' (all head)."""
    rows = {k: (s.chromosomes, s.head_length) for k, s in enumerate(g.strings)}
    if g.preheader:
        rows["pre"] = (g.preheader, len(g.preheader))
    return rows


def _name(k):
    return "the PreHeader" if k == "pre" else f"string {k}"


def _parse(text, ref, what="the result"):
    G, _ = _lib()
    try:
        g = G.Genome.from_json(text)
    except ValueError as exc:
        raise Bad(f"{what} is not a valid Genome ({str(exc)[:200]})") from None
    want = {k: (len(c), h) for k, (c, h) in _rows(ref).items()}
    got = {k: (len(c), h) for k, (c, h) in _rows(g).items()}
    if got != want:
        raise Bad(f"{what} has strings of (length, head length) {got}, but its parent has {want}; "
                  f"operators keep the number and length of strings and the head/tail split")
    return g


def _diff(g0, g1):
    """``[(key, [changed positions])]`` for the strings that differ."""
    r0, r1 = _rows(g0), _rows(g1)
    out = []
    for k, (c0, _) in r0.items():
        pos = [i for i, (x, y) in enumerate(zip(c0, r1[k][0])) if x != y]
        if pos:
            out.append((k, pos))
    return out


def _results(ctx, cid):
    """``[(seed, parent, child)]`` of a mutation case (all outputs parse: the gate holds)."""
    parent = ctx.arg(cid, 0)
    return [(seed, parent, _parse(text, parent)) for seed, text in zip(ctx.case(cid)["seeds"], ctx.out(cid))]


def _pair_results(ctx, cid):
    """``[(seed, a, b, child1, child2)]`` of a recombination case."""
    a, b = ctx.arg(cid, 0), ctx.arg(cid, 1)
    return [(seed, a, b, _parse(t1, a, "child 1"), _parse(t2, b, "child 2"))
            for seed, (t1, t2) in zip(ctx.case(cid)["seeds"], ctx.out(cid))]


def _renders(genomes):
    from coursekit.pictures import render

    img = render(genomes, 8, workers=1)
    return bool(np.all(np.isfinite(img)))


# -- shared properties ---------------------------------------------------------------------------


def _valid(cids, pair=False):
    def prop(ctx):
        firsts = []
        try:
            for cid in cids:
                rs = _pair_results(ctx, cid) if pair else _results(ctx, cid)
                firsts += list(rs[0][3:]) if pair else [rs[0][2]]
        except Bad as exc:
            return False, str(exc)
        if not _renders(firsts):
            return False, "a result renders to an image that is not finite"
        what = "two valid genomes" if pair else "a valid genome"
        return True, f"returns {what} of the parents' shape (head/tail rule kept) that decode and render"

    return prop


#: Calls with one seed for the determinism property: an operator that ignores its rng (global
#: random state) repeats a result by chance with probability p per pair; with a few dozen
#: possible outcomes p ~ 1/60, so 4 equal results pass it with probability ~ p^3 < 1e-5.
REPEATS = 4


def _deterministic(cid):
    def prop(ctx):
        outs = ctx.out(cid)
        if all(o == outs[0] for o in outs[1:]):
            return True, "same seed, same result"
        return False, ("two calls with the same seed gave different results; draw every random number from "
                       "the rng argument (no np.random.* or random.*)")

    return prop


def _unmodified(cid, names):
    def prop(ctx):
        after = ctx.record(cid).get("inputs_after") or []
        for i, name in enumerate(names):
            if i >= len(after) or not isinstance(after[i], dict) or \
                    json.loads(after[i]["json"]) != json.loads(ctx.case(cid)["args"][i]["json"]):
                return False, f"the genome {name} was modified; build and return a new Genome instead"
        return True, "inputs left unchanged"

    return prop


def _each(cids, judge_one, ok_message):
    """A property that holds when ``judge_one(seed, parent, child)`` returns None for every result."""
    def prop(ctx):
        for cid in cids:
            for seed, parent, child in _results(ctx, cid):
                why = judge_one(parent, child)
                if why:
                    return False, f"with rng seed {seed}: {why}"
        return True, ok_message

    return prop


def _one_string(parent, child):
    d = _diff(parent, child)
    if len(d) > 1:
        return f"changed {len(d)} strings ({', '.join(_name(k) for k, _ in d)}); this mutation works inside one chromosome string"
    return None


def _changes(cids):
    """Job gate of a mutation: at least half of the calls change the genome (a correct one: all)."""
    def prop(ctx):
        n = changed = 0
        for cid in cids:
            for _, parent, child in _results(ctx, cid):
                n += 1
                changed += bool(_diff(parent, child))
        if changed >= n / 2:
            return True, f"{changed} of {n} calls changed the genome"
        return False, (f"only {changed} of {n} calls changed the genome; a mutation's job is to change it (the case "
                       "genomes are built so that every mutation is visible). Nothing else is judged until it does")

    return prop


def _mixes(cids):
    """Job gate of a recombination: in at least half of the calls both children hold material of both parents."""
    def prop(ctx):
        n = mixed = 0
        for cid in cids:
            for _, a, b, c1, c2 in _pair_results(ctx, cid):
                n += 1
                mixed += all(_diff(a, c) and _diff(b, c) for c in (c1, c2))
        if mixed >= n / 2:
            return True, f"in {mixed} of {n} calls both children hold material of both parents"
        return False, (f"in {n - mixed} of {n} calls a child was a copy of a parent; a recombination's children hold "
                       "material of both parents. Nothing else is judged until they do")

    return prop


def _both_occur(ctx, cids, classify, kinds, what):
    seen = {k: 0 for k in kinds}
    n = 0
    for cid in cids:
        for _, parent, child in _results(ctx, cid):
            kind = classify(parent, child)
            n += 1
            if kind in seen:
                seen[kind] += 1
    missing = [k for k, v in seen.items() if v == 0]
    if missing:
        shares = ", ".join(f"{k}: {v}" for k, v in seen.items())
        return False, (f"over {n} calls with different seeds the outcomes were {shares}; {what}")
    return True, f"both outcomes occur over {n} calls ({', '.join(f'{k}: {v}' for k, v in seen.items())})"


# -- decoding (section 3.1) ----------------------------------------------------------------------


def karva(symbols):
    """The grader's own breadth-first (Karva) reading: the tree as a nested list."""
    _, P = _lib()
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
    _, P = _lib()
    funcs, terms = P.functions(), P.terminals()
    head = [str(rng.choice(funcs)) if rng.random() < function_rate else str(rng.choice(terms)) for _ in range(h)]
    return head + [str(rng.choice(terms)) for _ in range(h + 1)]


def _decode_cases(rng):
    _, P = _lib()
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
    # "symbols" is the grader's own copy: a function that consumes its argument list in place must
    # not change what the properties compare with (formative checks may run in threads)
    return [{"id": cid, "args": [syms], "symbols": list(syms), "seeds": [0], "max_len": 50_000}
            for cid, syms in fixed.items()]


def _tree(ctx, cid):
    return json.loads(ctx.out(cid)[0])


def _nodes(tree):
    """``[(symbol, children)]`` in any order; Bad for anything but the nested-list form."""
    _, P = _lib()
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
    _, P = _lib()
    for cid in ctx.cases:
        syms, tree = ctx.case(cid)["symbols"], _tree(ctx, cid)
        if P.arity(syms[0]) > 0 and not (isinstance(tree, list) and len(tree) > 1):
            return False, (f"decode({syms}) returned {json.dumps(tree)[:80]}, with nothing below the root; the root "
                           f"{syms[0]!r} takes {P.arity(syms[0])} argument(s), so the tree goes on. Nothing else is "
                           "judged until it does")
    return True, "builds a tree below every function root"


def _decode_arity(ctx):
    _, P = _lib()
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


def _decode_karva(ctx):
    for cid in ctx.cases:
        syms = ctx.case(cid)["symbols"]
        if _tree(ctx, cid) != karva(syms):
            return False, (f"decode({syms}) gave {json.dumps(_tree(ctx, cid))}, which is not the breadth-first "
                           f"reading: the children of one level are the next chromosomes of the string, "
                           f"left to right, level after level")
    return True, f"reads breadth-first (Karva) on {len(ctx.cases)} strings, non-coding tails ignored"


register(Check(
    name="pictures.decode", function="decode", params=("symbols",), points=2.0,
    title="Karva decoding of a chromosome string", output="json", cases=_decode_cases, gates=2,
    reference=('coursekit.pictures.genome:_karva',),
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
    s = _seeds(rng, 2 + N_STAT + N_STAT // 2)
    g3, g5, g1 = _distinct_pair(rng, 3, 4)[0], _distinct_pair(rng, 5, 3)[0], _distinct_pair(rng, 1, 5)[0]
    return [
        {"id": "basic", "args": [_obj(g3), RNG], "seeds": [s[0]] * REPEATS, "check_inputs": True, "max_len": MAX_JSON},
        {"id": "many", "args": [_obj(g5), RNG], "seeds": s[2:2 + N_STAT], "max_len": MAX_JSON},
        {"id": "single", "args": [_obj(g1), RNG], "seeds": s[2 + N_STAT:], "max_len": MAX_JSON},
    ]


def _region(k, i, h):
    return "head" if k == "pre" or i < h else "tail"


def _transposition_kind(parent, child):
    """'swap', 'clone', 'none' or None (not a transposition) -- for one changed string."""
    d = _diff(parent, child)
    if not d:
        return "none"
    if len(d) > 1:
        return None
    k, pos = d[0]
    old, h = _rows(parent)[k]
    new = _rows(child)[k][0]
    if len(pos) == 2 and new[pos[0]] == old[pos[1]] and new[pos[1]] == old[pos[0]]:
        return "swap"
    if len(pos) == 1 and any(new[pos[0]] == old[j] for j in range(len(old)) if j != pos[0]):
        return "clone"
    return None


def _no_root(parent, child):
    for k, pos in _diff(parent, child):
        if 0 in pos:
            return (f"the root (position 0) of {_name(k)} changed; transposition picks both chromosomes "
                    f"without the root")
    return None


def _same_region(parent, child):
    for k, pos in _diff(parent, child):
        h = _rows(parent)[k][1]
        regions = {_region(k, i, h) for i in pos}
        if len(pos) > 2:
            return f"{len(pos)} chromosomes of {_name(k)} changed; a transposition changes at most two"
        old = _rows(parent)[k][0]
        new = _rows(child)[k][0]
        if len(pos) == 1:  # a clone: where did it come from?
            if old[0] == new[pos[0]]:
                return f"position {pos[0]} of {_name(k)} received a clone of the root; transposition never uses the root"
            regions |= {_region(k, j, h) for j in range(1, len(old)) if old[j] == new[pos[0]] and j != pos[0]}
        if len(regions) > 1:
            return (f"in {_name(k)} (head length {h}) a chromosome moved between head and tail; both chromosomes "
                    f"must lie in the head or both in the tail")
    return None


def _swap_or_clone(parent, child):
    if _transposition_kind(parent, child) is None:
        d = _diff(parent, child)
        return (f"{_name(d[0][0])} changed at positions {d[0][1]}, which is neither an interchange of two of its "
                f"chromosomes nor one replaced by a clone of another")
    return None


def _transposition_both(ctx):
    return _both_occur(ctx, MUT_CASES, _transposition_kind, ("swap", "clone"),
                       "transposition either interchanges the two chromosomes or replaces the first by a clone "
                       "of the second, and both should happen")


register(Check(
    name="pictures.transposition", function="transposition", params=("genome", "rng"), points=2.0,
    title="transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:transposition',),
    props=(
        ("returns a valid genome of the same shape", _valid(MUT_CASES)),
        ("changes the genome", _changes(MUT_CASES)),
        ("changes one string only", _each(MUT_CASES, _one_string, "only one string changes")),
        ("never moves the root", _each(MUT_CASES, _no_root, "the root of every string stays")),
        ("both chromosomes in the same region", _each(MUT_CASES, _same_region, "both chromosomes lie in the head or both in the tail")),
        ("interchange or clone", _each(MUT_CASES, _swap_or_clone, "each result is an interchange or a clone")),
        ("both interchange and clone occur", _transposition_both),
        ("deterministic for a seed", _deterministic("basic")),
        ("input unchanged", _unmodified("basic", ["genome"])),
    ),
))


def _root_kind(parent, child):
    d = _diff(parent, child)
    if not d:
        return "none"
    if len(d) > 1:
        return None
    k, pos = d[0]
    old, h = _rows(parent)[k]
    new = _rows(child)[k][0]
    if len(pos) == 2 and pos[0] == 0 and pos[1] < h and new[0] == old[pos[1]] and new[pos[1]] == old[0]:
        return "swap"
    if pos == [0] and any(new[0] == old[j] for j in range(1, h)):
        return "clone"
    return None


def _root_only(parent, child):
    for k, pos in _diff(parent, child):
        h = _rows(parent)[k][1]
        if 0 not in pos or len(pos) > 2 or any(i >= h for i in pos):
            return (f"{_name(k)} (head length {h}) changed at positions {pos}; root transposition changes the root "
                    f"(position 0) and at most one other head chromosome")
    return None


def _root_swap_or_clone(parent, child):
    if _root_kind(parent, child) is None:
        d = _diff(parent, child)
        return (f"{_name(d[0][0])} changed at positions {d[0][1]}, which is neither the root interchanged with "
                f"another head chromosome nor the root replaced by a clone of one")
    return None


def _root_both(ctx):
    return _both_occur(ctx, MUT_CASES, _root_kind, ("swap", "clone"),
                       "the root is either interchanged with a second head chromosome or replaced by a clone "
                       "of it, and both should happen")


register(Check(
    name="pictures.root_transposition", function="root_transposition", params=("genome", "rng"), points=2.0,
    title="root transposition", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:root_transposition',),
    props=(
        ("returns a valid genome of the same shape", _valid(MUT_CASES)),
        ("changes the genome", _changes(MUT_CASES)),
        ("changes one string only", _each(MUT_CASES, _one_string, "only one string changes")),
        ("changes the root and one head chromosome", _each(MUT_CASES, _root_only, "only the root and one head chromosome change")),
        ("interchange or clone", _each(MUT_CASES, _root_swap_or_clone, "each result is an interchange or a clone")),
        ("both interchange and clone occur", _root_both),
        ("deterministic for a seed", _deterministic("basic")),
        ("input unchanged", _unmodified("basic", ["genome"])),
    ),
))


def _at_most_one(parent, child):
    d = _diff(parent, child)
    n = sum(len(p) for _, p in d)
    if n > 1:
        return f"{n} chromosomes changed ({', '.join(f'{_name(k)} at {p}' for k, p in d)}); substitution replaces one"
    return None


def _substituted(ctx):
    """``[(seed, key, position, head_length, new chromosome)]`` of every call that changed one chromosome."""
    out = []
    for cid in MUT_CASES:
        for seed, parent, child in _results(ctx, cid):
            d = _diff(parent, child)
            if len(d) == 1 and len(d[0][1]) == 1:
                k, [i] = d[0]
                out.append((seed, k, i, _rows(parent)[k][1], _rows(child)[k][0][i]))
    return out


def _substitution_changes(ctx):
    n = sum(len(ctx.out(cid)) for cid in MUT_CASES)
    changed = len(_substituted(ctx))
    if changed < n / 2:
        return False, (f"only {changed} of {n} calls changed a chromosome; substitution replaces one by a new "
                       f"random chromosome, which almost always differs. Nothing else is judged until it does")
    return True, f"{changed} of {n} calls replaced a chromosome"


def _substitution_random(ctx):
    _, P = _lib()
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
    regions = {_region(k, i, h) for _, k, i, h, _ in subs}
    strings = {k for _, k, *_ in subs}
    if regions != {"head", "tail"} or len(strings) < 2:
        return False, (f"over {len(subs)} substitutions the replaced chromosomes were in {' and '.join(sorted(regions)) or 'no region'} "
                       f"of {len(strings)} string(s); any chromosome of a randomly chosen string may be replaced")
    return True, f"replaces chromosomes in head and tail of {len(strings)} different strings"


register(Check(
    name="pictures.substitution", function="substitution", params=("genome", "rng"), points=2.0,
    title="substitution", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:substitution',),
    props=(
        ("returns a valid genome of the same shape", _valid(MUT_CASES)),
        ("changes a chromosome", _substitution_changes),
        ("changes at most one chromosome", _each(MUT_CASES, _at_most_one, "at most one chromosome changes")),
        ("the new chromosome is random", _substitution_random),
        ("any position can be replaced", _substitution_anywhere),
        ("deterministic for a seed", _deterministic("basic")),
        ("input unchanged", _unmodified("basic", ["genome"])),
    ),
))


def _rotation(parent, child):
    """``(region, steps)`` of a head or tail rotation, or a message saying why it is not one."""
    d = _diff(parent, child)
    if not d:
        return None, "nothing changed; one region is rotated by 1 to len-1 steps, which always changes it"
    if len(d) > 1:
        return None, f"changed {len(d)} strings; a rotation works on one string"
    k, _ = d[0]
    old, h = _rows(parent)[k]
    new = _rows(child)[k][0]
    parts = [("head", 0, h)] + ([] if k == "pre" else [("tail", h, len(old))])
    for region, lo, hi in parts:
        o, n = list(old[lo:hi]), list(new[lo:hi])
        rest_equal = list(old[:lo]) + list(old[hi:]) == list(new[:lo]) + list(new[hi:])
        for s in range(1, len(o)):
            if rest_equal and n == o[s:] + o[:s]:
                return (region, s), None
    return None, (f"{_name(k)} (head length {h}) is not its head or its tail cyclically shifted with the other "
                  f"part unchanged")


def _rotation_shift(parent, child):
    return _rotation(parent, child)[1]


def _rotation_varies(ctx):
    seen = [_rotation(p, c)[0] for cid in MUT_CASES for _, p, c in _results(ctx, cid)]
    if None in seen:
        return False, "not checked: not every result is a rotation"
    regions = {r for r, _ in seen}
    steps = {s for _, s in seen}
    if regions != {"head", "tail"} or len(steps) < 2:
        return False, (f"over {len(seen)} calls the rotations were of the {' and '.join(sorted(regions))} only, by "
                       f"{sorted(steps)} steps; the head or the tail (either) is rotated several steps")
    return True, f"rotates heads and tails by {len(steps)} different step counts"


register(Check(
    name="pictures.head_tail_rotation", function="head_tail_rotation", params=("genome", "rng"), points=2.0,
    title="head/tail rotation", output="json", cases=_mutation_cases, gates=2,
    reference=('coursekit.pictures.operators:head_tail_rotation',),
    props=(
        ("returns a valid genome of the same shape", _valid(MUT_CASES)),
        ("changes the genome", _changes(MUT_CASES)),
        ("changes one string only", _each(MUT_CASES, _one_string, "only one string changes")),
        ("a cyclic shift of exactly one region", _each(MUT_CASES, _rotation_shift, "each result rotates the head or the tail of one string")),
        ("head and tail, several steps", _rotation_varies),
        ("deterministic for a seed", _deterministic("basic")),
        ("input unchanged", _unmodified("basic", ["genome"])),
    ),
))

exercise("02_picture_mutations", ["pictures.decode", "pictures.transposition", "pictures.root_transposition",
                                  "pictures.substitution", "pictures.head_tail_rotation"])


# -- recombinations (section 3.3.2) --------------------------------------------------------------

REC_CASES = ("basic", "many", "single")


def _recombination_cases(rng, same_symbols=False):
    s = _seeds(rng, 2 + N_STAT + N_STAT // 2)
    make = _same_symbols_pair if same_symbols else _distinct_pair
    p3, p5, p1 = make(rng, 3, 4), make(rng, 5, 3), make(rng, 1, 5)

    def args(pair):
        return [_obj(pair[0]), _obj(pair[1]), RNG]

    return [
        {"id": "basic", "args": args(p3), "seeds": [s[0]] * REPEATS, "check_inputs": True, "max_len": MAX_JSON},
        {"id": "many", "args": args(p5), "seeds": s[2:2 + N_STAT], "max_len": MAX_JSON},
        {"id": "single", "args": args(p1), "seeds": s[2 + N_STAT:], "max_len": MAX_JSON},
    ]


def _each_pair(cids, judge_one, ok_message):
    def prop(ctx):
        for cid in cids:
            for seed, a, b, c1, c2 in _pair_results(ctx, cid):
                why = judge_one(a, b, c1, c2)
                if why:
                    return False, f"with rng seed {seed}: {why}"
        return True, ok_message

    return prop


def _same_positions(a, b, c1, c2):
    ra, rb = _rows(a), _rows(b)
    for n, c in ((1, c1), (2, c2)):
        for k, (chroms, _) in _rows(c).items():
            for i, x in enumerate(chroms):
                if x != ra[k][0][i] and x != rb[k][0][i]:
                    return (f"child {n} holds {x.label()} at position {i} of {_name(k)}, which is neither parent's "
                            f"chromosome at that position")
    return None


def _complementary(a, b, c1, c2):
    ra, rb, r1, r2 = _rows(a), _rows(b), _rows(c1), _rows(c2)
    for k in ra:
        for i in range(len(ra[k][0])):
            if {r1[k][0][i], r2[k][0][i]} != {ra[k][0][i], rb[k][0][i]}:
                return (f"at position {i} of {_name(k)} the two children do not hold the two parents' chromosomes "
                        f"(one each); what one child gets from a parent, the other gets from the other parent")
    return None


def _split(a, b, c1):
    """``(key, q)`` when child 1 is parent a with one string a[:q] + b[q:] (or b[:q] + a[q:]), else None."""
    d = _diff(a, c1)
    if len(d) != 1:
        return None
    k = d[0][0]
    sa, sb, sc = _rows(a)[k][0], _rows(b)[k][0], _rows(c1)[k][0]
    for q in range(1, len(sa)):
        if sc in (sa[:q] + sb[q:], sb[:q] + sa[q:]):
            return k, q
    return None


def _one_split(a, b, c1, c2):
    if _split(a, b, c1) is None:
        d = _diff(a, c1)
        where = ", ".join(f"{_name(k)} at {p}" for k, p in d) or "nowhere"
        return (f"child 1 differs from parent a in {where}; crossover cuts one pair of strings at one position "
                f"1..len-1 and exchanges the parts after it, leaving the other strings as they are")
    return None


def _split_varies(ctx):
    seen = [(_split(a, b, c1), a) for cid in REC_CASES for _, a, b, c1, _ in _pair_results(ctx, cid)]
    if any(s is None for s, _ in seen):
        return False, "not checked: not every result is a crossover of one string pair"
    keys = {k for (k, _), _ in seen}
    heads = {k == "pre" or q <= _rows(a)[k][1] for (k, q), a in seen}
    qs = {q for (_, q), _ in seen}
    if len(keys) < 2 or len(qs) < 3 or heads != {True, False}:
        return False, (f"over {len(seen)} crossovers the strings crossed were {sorted(map(str, keys))} and the cut "
                       f"positions {sorted(qs)}; the pair of strings and the cut position are chosen at random")
    return True, f"crossed {len(keys)} different strings at {len(qs)} different positions"


register(Check(
    name="pictures.crossover", function="crossover", params=("a", "b", "rng"), points=2.0,
    title="crossover", output="json_pair", cases=_recombination_cases, gates=2,
    reference=('coursekit.pictures.operators:crossover',),
    props=(
        ("returns two valid genomes of the parents' shape", _valid(REC_CASES, pair=True)),
        ("children hold material of both parents", _mixes(REC_CASES)),
        ("only the parents' material at the same positions", _each_pair(REC_CASES, _same_positions, "children hold only the parents' chromosomes at the same positions")),
        ("complementary children", _each_pair(REC_CASES, _complementary, "the children are complementary")),
        ("one string pair cut at one position", _each_pair(REC_CASES, _one_split, "one pair of strings is cut at one position")),
        ("random string pair and cut position", _split_varies),
        ("deterministic for a seed", _deterministic("basic")),
        ("inputs unchanged", _unmodified("basic", ["a", "b"])),
    ),
))


def _copies(parent, donor, child):
    """``[(key, target, sources)]`` of the copies in child (parent plus chromosomes of donor), or a message."""
    rd = _rows(donor)
    out = []
    for k, pos in _diff(parent, child):
        if len(pos) > 1:
            return None, f"{_name(k)} changed at {len(pos)} positions {pos}; random copy copies one chromosome into each string"
        i = pos[0]
        new = _rows(child)[k][0][i]
        sources = [j for j, c in enumerate(rd[k][0]) if c == new]
        if not sources:
            return None, (f"position {i} of {_name(k)} now holds {new.label()}, which is not a chromosome of the "
                          f"other parent's {_name(k)}")
        out.append((k, i, sources))
    return out, None


def _copy_material(a, b, c1, c2):
    for n, parent, donor, child in ((1, a, b, c1), (2, b, a, c2)):
        _, why = _copies(parent, donor, child)
        if why:
            return f"child {n} is its parent with copies from the other parent, but {why}"
    return None


def _copy_every_string(a, b, c1, c2):
    for n, parent, donor, child in ((1, a, b, c1), (2, b, a, c2)):
        copies, _ = _copies(parent, donor, child)
        missing = set(_rows(parent)) - {k for k, *_ in copies}
        if missing:
            return (f"child {n} received no chromosome in {', '.join(_name(k) for k in sorted(missing, key=str))}; "
                    f"random copy copies a chromosome into each chromosome string")
    return None


def _copy_arbitrary(ctx):
    targets, moved, n = set(), 0, 0
    for cid in REC_CASES:
        for _, a, b, c1, c2 in _pair_results(ctx, cid):
            for parent, donor, child in ((a, b, c1), (b, a, c2)):
                copies, why = _copies(parent, donor, child)
                if why:
                    return False, "not checked: not every result is made of copies"
                for k, i, sources in copies:
                    n += 1
                    targets.add(_region(k, i, _rows(parent)[k][1]))
                    moved += i not in sources
    if targets != {"head", "tail"} or moved < n / 10:
        return False, (f"over {n} copies, the target positions were in the {' and '.join(sorted(targets))} and {moved} "
                       f"copies came from a different position than the one they were copied to; random copy "
                       f"selects the source and the target position arbitrarily (each at random)")
    return True, f"{n} copies to head and tail positions, {moved} from a different position"


register(Check(
    name="pictures.random_copy", function="random_copy", params=("a", "b", "rng"), points=2.0,
    title="random copy", output="json_pair", cases=_recombination_cases, gates=2,
    reference=('coursekit.pictures.operators:random_copy',),
    props=(
        ("returns two valid genomes of the parents' shape", _valid(REC_CASES, pair=True)),
        ("children hold material of both parents", _mixes(REC_CASES)),
        ("only the parents' material", _each_pair(REC_CASES, _copy_material, "each child is its parent plus chromosomes of the other parent")),
        ("a copy into every string", _each_pair(REC_CASES, _copy_every_string, "every string of each child receives a copy")),
        ("arbitrary positions", _copy_arbitrary),
        ("deterministic for a seed", _deterministic("basic")),
        ("inputs unchanged", _unmodified("basic", ["a", "b"])),
    ),
))


INTERP_CASES = ("basic", "many", "single", "mixed")


def _interpolation_cases(rng):
    cases = _recombination_cases(rng, same_symbols=True)
    a, b = _distinct_pair(rng, 3, 4)
    cases.append({"id": "mixed", "args": [_obj(a), _obj(b), RNG], "seeds": _seeds(rng, 20), "max_len": MAX_JSON})
    return cases


def _changed_positions(a, b, c1, c2):
    return {(k, i) for g, c in ((a, c1), (b, c2)) for k, pos in _diff(g, c) for i in pos}


def _one_position(a, b, c1, c2):
    pos = _changed_positions(a, b, c1, c2)
    if len(pos) > 1:
        where = ", ".join(f"{_name(k)} position {i}" for k, i in sorted(pos, key=str))
        return f"the children differ from their parents at {where}; random interpolation blends one aligned pair of chromosomes"
    return None


def _interp_changes(ctx):
    n = changed = 0
    for cid in ("basic", "many", "single"):
        for _, a, b, c1, c2 in _pair_results(ctx, cid):
            n += 1
            changed += bool(_changed_positions(a, b, c1, c2))
    if changed < n / 2:
        return False, (f"only {changed} of {n} calls on parents with the same primitives and different parameters "
                       f"changed anything; the children should get interpolated parameters. Nothing else is judged "
                       "until they do")
    return True, f"{changed} of {n} calls blended a pair of chromosomes"


def _between(a, b, c1, c2):
    _, P = _lib()
    ra, rb = _rows(a), _rows(b)
    for n, c in ((1, c1), (2, c2)):
        for k, (chroms, _) in _rows(c).items():
            for i, x in enumerate(chroms):
                xa, xb = ra[k][0][i], rb[k][0][i]
                if x.symbol not in (xa.symbol, xb.symbol):
                    return f"child {n} has {x.symbol!r} at position {i} of {_name(k)}, the primitive of neither parent there"
                pa = {s.name: v for s, v in zip(P.get(xa.symbol).params, xa.params)}
                pb = {s.name: v for s, v in zip(P.get(xb.symbol).params, xb.params)}
                for spec, v in zip(P.get(x.symbol).params, x.params):
                    vals = [p[spec.name] for p in (pa, pb) if spec.name in p]
                    lo, hi = min(vals), max(vals)
                    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
                    if not lo - tol <= v <= hi + tol:
                        return (f"child {n} has {spec.name} = {v:g} at position {i} of {_name(k)}, outside the parents' "
                                f"values {lo:g}..{hi:g}; an interpolation (1 - u) p_a + u p_b with 0 <= u <= 1 stays between them")
    return None


def _u_of(a, b, c1, c2):
    """``(u1, u2, spread)``: the interpolation parameters read off child 1 and child 2 (same-symbol cases)."""
    pos = _changed_positions(a, b, c1, c2)
    if len(pos) != 1:
        return None
    (k, i), = pos
    xa, xb = _rows(a)[k][0][i], _rows(b)[k][0][i]
    x1, x2 = _rows(c1)[k][0][i], _rows(c2)[k][0][i]
    u1 = [(v - p) / (q - p) for p, q, v in zip(xa.params, xb.params, x1.params) if q != p]
    u2 = [(v - q) / (p - q) for p, q, v in zip(xa.params, xb.params, x2.params) if q != p]
    return u1, u2


def _one_u(ctx):
    for cid in ("basic", "many", "single"):
        for seed, a, b, c1, c2 in _pair_results(ctx, cid):
            us = _u_of(a, b, c1, c2)
            if us is None:
                continue
            for n, u in ((1, us[0]), (2, us[1])):
                if u and max(u) - min(u) > 1e-6:
                    return False, (f"with rng seed {seed} the parameters of child {n}'s blended chromosome sit at "
                                   f"different fractions ({', '.join(f'{x:.3f}' for x in u)}) of the way between the "
                                   f"parents; a linear interpolation uses one parameter u for the whole chromosome")
    return True, "one interpolation parameter per chromosome"


def _complementary_u(ctx):
    for cid in ("basic", "many", "single"):
        for seed, a, b, c1, c2 in _pair_results(ctx, cid):
            us = _u_of(a, b, c1, c2)
            if us and us[0] and us[1] and abs(us[0][0] - us[1][0]) > 1e-6:
                return False, (f"with rng seed {seed} child 1 lies {us[0][0]:.3f} of the way from parent a to b, but "
                               f"child 2 lies {us[1][0]:.3f} of the way from b to a; the children are lerp(a, b, u) "
                               f"and lerp(b, a, u) with the same u")
    return True, "children are lerp(a, b, u) and lerp(b, a, u)"


def _u_random(ctx):
    us = []
    for cid in ("many", "single"):
        for _, a, b, c1, c2 in _pair_results(ctx, cid):
            got = _u_of(a, b, c1, c2)
            if got and got[0]:
                us.append(got[0][0])
    halves = {u < 0.5 for u in us}
    distinct = len({round(u, 6) for u in us})
    if halves != {True, False} or distinct < len(us) / 2:
        return False, (f"over {len(us)} interpolations u took {distinct} different values "
                       f"({', '.join(f'{u:.2f}' for u in us[:8])}...); the interpolation parameter is drawn at random in [0, 1]")
    return True, f"u is random ({distinct} different values over {len(us)} calls)"


register(Check(
    name="pictures.random_interpolation", function="random_interpolation", params=("a", "b", "rng"), points=2.0,
    title="random interpolation", output="json_pair", cases=_interpolation_cases, gates=2,
    reference=('coursekit.pictures.operators:random_interpolation',),
    props=(
        ("returns two valid genomes of the parents' shape", _valid(INTERP_CASES, pair=True)),
        ("blends a pair", _interp_changes),
        ("one aligned pair of chromosomes", _each_pair(INTERP_CASES, _one_position, "at most one aligned position changes")),
        ("stays between the parents' values", _each_pair(INTERP_CASES, _between, "every value lies between the parents'")),
        ("one u per chromosome", _one_u),
        ("complementary children", _complementary_u),
        ("u is random", _u_random),
        ("deterministic for a seed", _deterministic("basic")),
        ("inputs unchanged", _unmodified("basic", ["a", "b"])),
    ),
))

exercise("03_picture_recombination", ["pictures.crossover", "pictures.random_copy", "pictures.random_interpolation"])
