"""Picture genomes for the checks of exercises 02 and 03: case genomes, reading results, shared properties.

Implements the grading side of the seed paper's section 3 operators: decoding a chromosome
string (3.1, Karva reading as in Gene Expression Programming), the mutations of section 3.3.1
(transposition, root transposition, substitution, head/tail rotation) and the recombinations of
section 3.3.2 (crossover, random copy, random interpolation), with the exact signatures of
:mod:`coursekit.pictures.operators`.

Statistical properties and their false-failure rates for a correct operator (every case
genome and seed comes from the grader's generator): "both outcomes occur" (interchange and
clone, head and tail) over 90-100 calls with different seeds misses an outcome of probability
>= 0.3 with probability below 1e-8; "changes a chromosome" / "blends a pair" need half of the
calls to change something where a correct operator changes more than 90 %; "random" properties
ask for variety (8 of the 42 primitives over ~160 substitutions, 3 cut positions, u on both
sides of 1/2) that a uniform random choice misses with probability far below 1e-8; a
substitution must reach the PreHeader, functions at head positions and mostly new chromosomes
(the rates are worked out where they are judged, :mod:`.ex02_picture_mutations`).

Each check's second property is its *job*, a gate (see :class:`~coursekit.grading.checks.Check`):
decoding builds a tree below a function root, a mutation changes the genome in at least half of
the calls, a recombination's children hold material of both parents in at least half of the
calls (correct operators: every call), interpolation blends a pair. Until it holds nothing else
is judged, so identity mutations, ``return a, b`` and deep copies score 0. One later property is
its *point* (:func:`~coursekit.grading.checks.properties.point`): the operator's definition with
the random choices it names (Karva's reading order; an interchange or a clone, both occurring;
complementary children of one random cut; one random u for both children ...). It weighs half
the points, so an answer that gets the definition wrong keeps at most half of them.

Genomes travel as JSON text (``Genome.to_json``) and come back as JSON text; every property
parses them with the grader's own import of the library and judges plain data. Properties are
the paper's definitions, never a comparison with one reference output: what may change and how
(one string, never the root, one region, an interchange or a clone, a cyclic shift, parents'
material at the same positions, values between the parents'), statistics over many seeds,
determinism for a seed and inputs left unmodified.

Case genomes are built so that every outcome can be read off the result: within a string (and
across the two parents' strings) no two chromosomes are equal, so an interchange, a clone, a
rotation or a copy is never invisible. The one-string genomes of the cases code in their tails
(:func:`reaching_tail`), so that an operator aimed at the coding part reaches both regions.
"""

from __future__ import annotations

import numpy as np

from coursekit.grading.checks.properties import NEW_GENOME, all_of, deterministic, unmodified

GENOME = "coursekit.pictures.genome:Genome"
MAX_JSON = 200_000
N_STAT = 60  # calls per statistical case (an outcome of probability 0.3 is missed with p = 0.7**60 < 1e-8)


def lib():
    from coursekit.pictures import genome, primitives

    return genome, primitives


# -- case genomes --------------------------------------------------------------------------------


def distinct_pair(rng, n_strings, h):
    """Two genomes of one shape; no chromosome symbol repeats inside a string pair (both parents)."""
    G, P = lib()
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


def reaching_tail(make, rng, h):
    """``make(rng, 1, h)`` (one-string genomes: a genome or a pair) drawn until each genome codes in
    its tail at least a third of its coding chromosomes (a Karva string codes a prefix: at least
    ``h / 2`` tail chromosomes), so that an operator aimed at the coding part -- as coursekit's own
    are, a change there always shows in the picture -- reaches the tail too. One random string in
    three qualifies."""
    while True:
        made = make(rng, 1, h)
        genomes = made if type(made) is tuple else (made,)
        if all(3 * sum(i >= h for i in g.active[0]) >= len(g.active[0]) for g in genomes):
            return made


def same_symbols_pair(rng, n_strings, h):
    """Two genomes with the same symbols everywhere (all with parameters), different parameters."""
    G, P = lib()
    with_params = [n for n in P.names() if P.get(n).params]
    terms = [n for n in with_params if P.arity(n) == 0]
    binary = [n for n in with_params if P.arity(n) == 2]
    strings = [list(rng.choice(with_params, size=h)) + list(rng.choice(terms, size=h + 1)) for _ in range(n_strings)]
    pre = list(rng.choice(binary, size=n_strings - 1))

    def genome():
        return G.Genome(tuple(G.ChromosomeString(h, tuple(G.Chromosome.random(rng, str(s)) for s in syms)) for syms in strings),
                        tuple(G.Chromosome.random(rng, str(s)) for s in pre))

    return genome(), genome()


def obj(g):
    return {"object": GENOME, "json": g.to_json()}


# -- reading results -----------------------------------------------------------------------------


class Bad(Exception):
    """An output that is not a valid genome of the expected shape (message for the student)."""


def rows(g):
    """``{key: (chromosomes, head_length)}``: strings by index, the PreHeader as 'pre' (all head)."""
    rows = {k: (s.chromosomes, s.head_length) for k, s in enumerate(g.strings)}
    if g.preheader:
        rows["pre"] = (g.preheader, len(g.preheader))
    return rows


def region(k, i, h):
    """"head" or "tail": where position ``i`` of row ``k`` (head length ``h``) lies."""
    return "head" if k == "pre" or i < h else "tail"


def row_name(k):
    return "the PreHeader" if k == "pre" else f"string {k}"


def parse(text, ref, what="the result"):
    G, _ = lib()
    try:
        g = G.Genome.from_json(text)
    except ValueError as exc:
        raise Bad(f"{what} is not a valid Genome ({str(exc)[:200]})") from None
    want = {k: (len(c), h) for k, (c, h) in rows(ref).items()}
    got = {k: (len(c), h) for k, (c, h) in rows(g).items()}
    if got != want:
        raise Bad(f"{what} has strings of (length, head length) {got}, but its parent has {want}; "
                  f"operators keep the number and length of strings and the head/tail split")
    return g


def diff(g0, g1):
    """``[(key, [changed positions])]`` for the strings that differ."""
    r0, r1 = rows(g0), rows(g1)
    out = []
    for k, (c0, _) in r0.items():
        pos = [i for i, (x, y) in enumerate(zip(c0, r1[k][0])) if x != y]
        if pos:
            out.append((k, pos))
    return out


def results(ctx, cid):
    """``[(seed, parent, child)]`` of a mutation case (all outputs parse: the gate holds)."""
    parent = ctx.arg(cid, 0)
    return [(seed, parent, parse(text, parent)) for seed, text in zip(ctx.case(cid)["seeds"], ctx.out(cid))]


def pair_results(ctx, cid):
    """``[(seed, a, b, child1, child2)]`` of a recombination case."""
    a, b = ctx.arg(cid, 0), ctx.arg(cid, 1)
    return [(seed, a, b, parse(t1, a, "child 1"), parse(t2, b, "child 2"))
            for seed, (t1, t2) in zip(ctx.case(cid)["seeds"], ctx.out(cid))]


def renders(genomes):
    from coursekit.pictures import render

    img = render(genomes, 8, workers=1)
    return bool(np.all(np.isfinite(img)))


# -- shared properties ---------------------------------------------------------------------------


def valid(cids, pair=False):
    def prop(ctx):
        firsts = []
        try:
            for cid in cids:
                rs = pair_results(ctx, cid) if pair else results(ctx, cid)
                firsts += list(rs[0][3:]) if pair else [rs[0][2]]
        except Bad as exc:
            return False, str(exc)
        if not renders(firsts):
            return False, "a result renders to an image that is not finite"
        what = "two valid genomes" if pair else "a valid genome"
        return True, f"returns {what} of the parents' shape (head/tail rule kept) that decode and render"

    return prop


#: The determinism case (``"basic"``): :data:`REPEAT_SEEDS` seeds, each :data:`REPEATS` times in
#: a row, on a genome from :func:`repeat_genomes`. An operator that draws a choice from a global
#: generator (``np.random``) repeats its result for one seed by chance only where that choice has
#: few outcomes: a cut of a 2-long PreHeader or a rotation of 2 chromosomes has one, so an
#: operator that picked the string with ``rng`` and the cut with ``np.random`` passed whenever
#: ``rng`` chose that string (honest-student study, seeds 11 and 13). On the repeat genome every
#: head, tail and PreHeader has 5 or more positions, so every such choice has at least 4 outcomes
#: (a shift, a cut, a second head chromosome ...), and 3 seeds x 4 calls pass with probability at
#: most 4^-9 < 4e-6 (a global coin alone, 2 outcomes: 2^-9).
REPEATS = 4
REPEAT_SEEDS = 3


def repeat_genomes(rng):
    """Two genomes of 6 strings of head 5 (tail 6) and a PreHeader of 5 (:func:`distinct_pair`)."""
    return distinct_pair(rng, 6, 5)


def each(cids, judge_one, ok_message):
    """A property that holds when ``judge_one(seed, parent, child)`` returns None for every result."""
    def prop(ctx):
        for cid in cids:
            for seed, parent, child in results(ctx, cid):
                why = judge_one(parent, child)
                if why:
                    return False, f"with rng seed {seed}: {why}"
        return True, ok_message

    return prop


def one_string(parent, child):
    d = diff(parent, child)
    if len(d) > 1:
        return f"changed {len(d)} strings ({', '.join(row_name(k) for k, _ in d)}); this mutation works inside one chromosome string"
    return None


def changes(cids):
    """Job gate of a mutation: at least half of the calls change the genome (a correct one: all)."""
    def prop(ctx):
        n = changed = 0
        for cid in cids:
            for _, parent, child in results(ctx, cid):
                n += 1
                changed += bool(diff(parent, child))
        if changed >= n / 2:
            return True, f"{changed} of {n} calls changed the genome"
        return False, (f"only {changed} of {n} calls changed the genome; a mutation's job is to change it (the case "
                       "genomes are built so that every mutation is visible). Nothing else is judged until it does")

    return prop


def mixes(cids):
    """Job gate of a recombination: in at least half of the calls both children hold material of both parents."""
    def prop(ctx):
        n = mixed = 0
        for cid in cids:
            for _, a, b, c1, c2 in pair_results(ctx, cid):
                n += 1
                mixed += all(diff(a, c) and diff(b, c) for c in (c1, c2))
        if mixed >= n / 2:
            return True, f"in {mixed} of {n} calls both children hold material of both parents"
        return False, (f"in {n - mixed} of {n} calls a child was a copy of a parent; a recombination's children hold "
                       "material of both parents. Nothing else is judged until they do")

    return prop


def both_occur(ctx, cids, classify, kinds, what):
    seen = {k: 0 for k in kinds}
    n = 0
    for cid in cids:
        for _, parent, child in results(ctx, cid):
            kind = classify(parent, child)
            n += 1
            if kind in seen:
                seen[kind] += 1
    missing = [k for k, v in seen.items() if v == 0]
    if missing:
        shares = ", ".join(f"{k}: {v}" for k, v in seen.items())
        return False, (f"over {n} calls with different seeds the outcomes were {shares}; {what}")
    return True, f"both outcomes occur over {n} calls ({', '.join(f'{k}: {v}' for k, v in seen.items())})"




def operator_props(head: tuple, point_name: str, *parts, args=("genome",)) -> tuple:
    """A picture operator's properties, in the order its check lists them: ``head`` (the result's validity,
    the job gate, what may change), then the point ``point_name`` (``parts`` judged as one, :func:`all_of`),
    determinism on the case ``"basic"``, and the arguments ``args`` left unchanged."""
    return tuple(head) + (
        (point_name, all_of(*parts)),
        ("deterministic for a seed", deterministic("basic")),
        ("input unchanged" if len(args) == 1 else "inputs unchanged",
         unmodified(dict(enumerate(args)), NEW_GENOME, what="the genome {name}")),
    )
