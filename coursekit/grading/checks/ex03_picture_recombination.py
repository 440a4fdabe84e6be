"""Checks for exercise 03 (genetic pictures: the three recombinations).

The grading rationale both picture exercises share -- the job gates, the false-failure rates of
the statistical properties, how genomes travel and the case genomes -- is in
:mod:`~coursekit.grading.checks.picture_genomes`.
"""

from __future__ import annotations

from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.picture_genomes import (
    MAX_JSON, N_STAT, REPEAT_SEEDS, REPEATS, diff, distinct_pair, lib, mixes, obj, operator_props, pair_results,
    reaching_tail, region, row_name, rows, same_symbols_pair, valid)
from coursekit.grading.checks.properties import (
    NEW_GENOME, RNG, all_of, deterministic, point, repeated, seeds, unmodified)


#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
_MIXES = ("Each child must hold material of both parents; returning the parents (or copies) does not recombine.",
          "Work position by position on aligned strings of the two parents: what does child 1 take from a, and from b?",
          "Child 2 gets what child 1 did not take: build both in the same loop.")
HINTS = {
    "pictures.crossover": (("children hold material of both parents", _MIXES),),
    "pictures.random_copy": (("children hold material of both parents", _MIXES),),
    "pictures.random_interpolation": (
        ("blends a pair", (
            "Interpolation mixes the parameters of one aligned pair of chromosomes: (1 - u) * p_a + u * p_b.",
            "Draw u with the rng for the pair, and give child 2 the complementary blend.")),
    ),
}


# -- recombinations (section 3.3.2) --------------------------------------------------------------

REC_CASES = ("basic", "many", "single")
#: What crossover and random copy judge first: two valid children (gate) holding material of both parents
#: (the job, a gate).
_TWO_CHILDREN = (
    ("returns two valid genomes of the parents' shape", valid(REC_CASES, pair=True)),
    ("children hold material of both parents", mixes(REC_CASES)),
)


def _recombination_cases(rng, same_symbols=False):
    s = seeds(rng, REPEAT_SEEDS + N_STAT + N_STAT // 2)
    make = same_symbols_pair if same_symbols else distinct_pair
    # the determinism case: every string and the PreHeader 5 long or more (picture_genomes.REPEATS)
    p6, p5, p1 = make(rng, 6, 5), make(rng, 5, 3), reaching_tail(make, rng, 5)
    r = REPEAT_SEEDS

    def args(pair):
        return [obj(pair[0]), obj(pair[1]), RNG]

    return [
        {"id": "basic", "args": args(p6), "seeds": repeated(s[:r], REPEATS), "max_len": MAX_JSON},
        {"id": "many", "args": args(p5), "seeds": s[r:r + N_STAT], "max_len": MAX_JSON},
        {"id": "single", "args": args(p1), "seeds": s[r + N_STAT:], "max_len": MAX_JSON},
    ]


def _each_pair(cids, judge_one, ok_message):
    def prop(ctx):
        for cid in cids:
            for seed, a, b, c1, c2 in pair_results(ctx, cid):
                why = judge_one(a, b, c1, c2)
                if why:
                    return False, f"with rng seed {seed}: {why}"
        return True, ok_message

    return prop


def _same_positions(a, b, c1, c2):
    ra, rb = rows(a), rows(b)
    for n, c in ((1, c1), (2, c2)):
        for k, (chroms, _) in rows(c).items():
            for i, x in enumerate(chroms):
                if x != ra[k][0][i] and x != rb[k][0][i]:
                    return (f"child {n} holds {x.label()} at position {i} of {row_name(k)}, which is neither parent's "
                            f"chromosome at that position")
    return None


def _complementary(a, b, c1, c2):
    ra, rb, r1, r2 = rows(a), rows(b), rows(c1), rows(c2)
    for k in ra:
        for i in range(len(ra[k][0])):
            if {r1[k][0][i], r2[k][0][i]} != {ra[k][0][i], rb[k][0][i]}:
                return (f"at position {i} of {row_name(k)} the two children do not hold the two parents' chromosomes "
                        f"(one each); what one child gets from a parent, the other gets from the other parent")
    return None


def _split(a, b, c1):
    """``(key, q)`` when child 1 is parent a with one string a[:q] + b[q:] (or b[:q] + a[q:]), else None."""
    d = diff(a, c1)
    if len(d) != 1:
        return None
    k = d[0][0]
    sa, sb, sc = rows(a)[k][0], rows(b)[k][0], rows(c1)[k][0]
    for q in range(1, len(sa)):
        if sc in (sa[:q] + sb[q:], sb[:q] + sa[q:]):
            return k, q
    return None


def _one_split(a, b, c1, c2):
    if _split(a, b, c1) is None:
        d = diff(a, c1)
        what = f"differs from parent a in {', '.join(f'{row_name(k)} at {p}' for k, p in d)}" if d else "is parent a unchanged"
        return (f"child 1 {what}; crossover cuts one pair of strings at one position 1..len-1 and exchanges the parts "
                f"after it, leaving the other strings as they are")
    return None


def _split_varies(ctx):
    seen = [(_split(a, b, c1), a) for cid in REC_CASES for _, a, b, c1, _ in pair_results(ctx, cid)]
    if any(s is None for s, _ in seen):
        return False, "not checked: not every result is a crossover of one string pair"
    keys = {k for (k, _), _ in seen}
    heads = {k == "pre" or q <= rows(a)[k][1] for (k, q), a in seen}
    qs = {q for (_, q), _ in seen}
    if len(keys) < 2 or len(qs) < 3 or heads != {True, False}:
        return False, (f"over {len(seen)} crossovers the strings crossed were {sorted(map(str, keys))} and the cut "
                       f"positions {sorted(qs)}; the pair of strings and the cut position are chosen at random")
    return True, f"crossed {len(keys)} different strings at {len(qs)} different positions"


_CROSSOVER = operator_props(
    _TWO_CHILDREN + (
        ("only the parents' material at the same positions", _each_pair(REC_CASES, _same_positions, "children hold only the parents' chromosomes at the same positions")),
    ),
    # the point: complementary children, one string pair cut at one position, both chosen at random
    "complementary children of one random cut",
    _each_pair(REC_CASES, _complementary, "the children are complementary"),
    _each_pair(REC_CASES, _one_split, "one pair of strings is cut at one position"),
    _split_varies, args=("a", "b"))

register(Check(
    hints=HINTS.get("pictures.crossover", ()),
    name="pictures.crossover", function="crossover", params=("a", "b", "rng"), points=2.0,
    title="crossover", output="json_pair", cases=_recombination_cases, gates=2,
    reference=('coursekit.pictures.operators:crossover',),
    props=_CROSSOVER,
    # identical children: 91 % before; a fixed cut is no GA operator (red team: 89 %)
    weights=point(_CROSSOVER[3][0], _CROSSOVER),
))


def _copies(parent, donor, child):
    """``[(key, target, sources)]`` of the copies in child (parent plus chromosomes of donor), or a message."""
    rd = rows(donor)
    out = []
    for k, pos in diff(parent, child):
        if len(pos) > 1:
            return None, f"{row_name(k)} changed at {len(pos)} positions {pos}; random copy copies one chromosome into each string"
        i = pos[0]
        new = rows(child)[k][0][i]
        sources = [j for j, c in enumerate(rd[k][0]) if c == new]
        if not sources:
            return None, (f"position {i} of {row_name(k)} now holds {new.label()}, which is not a chromosome of the "
                          f"other parent's {row_name(k)}")
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
        missing = set(rows(parent)) - {k for k, *_ in copies}
        if missing:
            return (f"child {n} received no chromosome in {', '.join(row_name(k) for k in sorted(missing, key=str))}; "
                    f"random copy copies a chromosome into each chromosome string")
    return None


def _copy_arbitrary(ctx):
    targets, moved, n = set(), 0, 0
    for cid in REC_CASES:
        for _, a, b, c1, c2 in pair_results(ctx, cid):
            for parent, donor, child in ((a, b, c1), (b, a, c2)):
                copies, why = _copies(parent, donor, child)
                if why:
                    return False, "not checked: not every result is made of copies"
                for k, i, sources in copies:
                    n += 1
                    targets.add(region(k, i, rows(parent)[k][1]))
                    moved += i not in sources
    if targets != {"head", "tail"} or moved < n / 10:
        return False, (f"over {n} copies, the target positions were in the {' and '.join(sorted(targets))} and {moved} "
                       f"copies came from a different position than the one they were copied to; random copy "
                       f"selects the source and the target position arbitrarily (each at random)")
    return True, f"{n} copies to head and tail positions, {moved} from a different position"


_RANDOM_COPY = operator_props(
    _TWO_CHILDREN + (
        ("only the parents' material", _each_pair(REC_CASES, _copy_material, "each child is its parent plus chromosomes of the other parent")),
    ),
    # the point: one copy into every string, from and to positions chosen at random
    "a copy into every string, between arbitrary positions",
    _each_pair(REC_CASES, _copy_every_string, "every string of each child receives a copy"),
    _copy_arbitrary, args=("a", "b"))

register(Check(
    hints=HINTS.get("pictures.random_copy", ()),
    name="pictures.random_copy", function="random_copy", params=("a", "b", "rng"), points=2.0,
    title="random copy", output="json_pair", cases=_recombination_cases, gates=2,
    reference=('coursekit.pictures.operators:random_copy',),
    props=_RANDOM_COPY,
    weights=point(_RANDOM_COPY[3][0], _RANDOM_COPY),  # always the same positions: 70-88 % before
))


INTERP_CASES = ("basic", "many", "single", "mixed")


def _interpolation_cases(rng):
    cases = _recombination_cases(rng, same_symbols=True)
    a, b = distinct_pair(rng, 3, 4)
    cases.append({"id": "mixed", "args": [obj(a), obj(b), RNG], "seeds": seeds(rng, 40), "max_len": MAX_JSON})
    return cases


def _changed_positions(a, b, c1, c2):
    return {(k, i) for g, c in ((a, c1), (b, c2)) for k, pos in diff(g, c) for i in pos}


def _one_position(a, b, c1, c2):
    pos = _changed_positions(a, b, c1, c2)
    if len(pos) > 1:
        where = ", ".join(f"{row_name(k)} position {i}" for k, i in sorted(pos, key=str))
        return f"the children differ from their parents at {where}; random interpolation blends one aligned pair of chromosomes"
    return None


def _interp_changes(ctx):
    n = changed = 0
    for cid in ("basic", "many", "single"):
        for _, a, b, c1, c2 in pair_results(ctx, cid):
            n += 1
            changed += bool(_changed_positions(a, b, c1, c2))
    if changed < n / 2:
        return False, (f"only {changed} of {n} calls on parents with the same primitives and different parameters "
                       f"changed anything; the children should get interpolated parameters. Nothing else is judged "
                       "until they do")
    return True, f"{changed} of {n} calls blended a pair of chromosomes"


def _named(x) -> dict:
    """A chromosome's parameters by name."""
    _, P = lib()
    return {s.name: v for s, v in zip(P.get(x.symbol).params, x.params)}


def _between(a, b, c1, c2):
    _, P = lib()
    ra, rb = rows(a), rows(b)
    for n, c in ((1, c1), (2, c2)):
        for k, (chroms, _) in rows(c).items():
            for i, x in enumerate(chroms):
                xa, xb = ra[k][0][i], rb[k][0][i]
                if x.symbol not in (xa.symbol, xb.symbol):
                    return f"child {n} has {x.symbol!r} at position {i} of {row_name(k)}, the primitive of neither parent there"
                pa, pb = _named(xa), _named(xb)
                for spec, v in zip(P.get(x.symbol).params, x.params):
                    vals = [p[spec.name] for p in (pa, pb) if spec.name in p]
                    lo, hi = min(vals), max(vals)
                    tol = 1e-9 * max(1.0, abs(lo), abs(hi))
                    if not lo - tol <= v <= hi + tol:
                        return (f"child {n} has {spec.name} = {v:g} at position {i} of {row_name(k)}, outside the parents' "
                                f"values {lo:g}..{hi:g}; an interpolation (1 - u) p_a + u p_b with 0 <= u <= 1 stays between them")
    return None


def _u_of(a, b, c1, c2):
    """``(u1, u2, spread)``: the interpolation parameters read off child 1 and child 2 (same-symbol cases)."""
    pos = _changed_positions(a, b, c1, c2)
    if len(pos) != 1:
        return None
    (k, i), = pos
    xa, xb = rows(a)[k][0][i], rows(b)[k][0][i]
    x1, x2 = rows(c1)[k][0][i], rows(c2)[k][0][i]
    u1 = [(v - p) / (q - p) for p, q, v in zip(xa.params, xb.params, x1.params) if q != p]
    u2 = [(v - q) / (p - q) for p, q, v in zip(xa.params, xb.params, x2.params) if q != p]
    return u1, u2


def _mixed_blends(ctx):
    """On parents whose primitives differ at every position, some call changes a chromosome. Not
    every call need: where the two share no parameter and u < 0.5 a child is its own parent (the
    reference solution changes 5 to 20 of 20 calls, over 40 seeds)."""
    n = changed = 0
    for _, a, b, c1, c2 in pair_results(ctx, "mixed"):
        n += 1
        changed += bool(_changed_positions(a, b, c1, c2))
    if not changed:
        return False, (f"on parents whose primitives differ at every position none of {n} calls changed anything; "
                       "interpolation blends the parameters two different primitives share by name too (prefer a "
                       "position where they share one)")
    return True, f"{changed} of {n} calls on parents with different primitives changed a chromosome"


def _nearer_parent(a, b, c1, c2):
    pos = _changed_positions(a, b, c1, c2)
    if len(pos) != 1:
        return None
    (k, i), = pos
    xa, xb = rows(a)[k][0][i], rows(b)[k][0][i]
    pa, pb = _named(xa), _named(xb)
    for n, x, (near, far), (pn, pf) in ((1, rows(c1)[k][0][i], (xa, xb), (pa, pb)), (2, rows(c2)[k][0][i], (xb, xa), (pb, pa))):
        px = _named(x)
        us = [(px[m] - pn[m]) / (pf[m] - pn[m]) for m in px if m in pn and m in pf and pf[m] != pn[m]]
        if not us or abs(us[0] - 0.5) < 1e-6:
            continue
        want = near if us[0] < 0.5 else far
        if x.symbol != want.symbol:
            return (f"child {n} lies {us[0]:.2f} of the way from its parent to the other but has {x.symbol!r} at "
                    f"position {i} of {row_name(k)}, not the nearer parent's {want.symbol!r}; the symbol and any "
                    "parameter only one primitive has come from the nearer parent")
    return None


def _one_u(ctx):
    for cid in ("basic", "many", "single"):
        for seed, a, b, c1, c2 in pair_results(ctx, cid):
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
        for seed, a, b, c1, c2 in pair_results(ctx, cid):
            us = _u_of(a, b, c1, c2)
            if us and us[0] and us[1] and abs(us[0][0] - us[1][0]) > 1e-6:
                return False, (f"with rng seed {seed} child 1 lies {us[0][0]:.3f} of the way from parent a to b, but "
                               f"child 2 lies {us[1][0]:.3f} of the way from b to a; the children are lerp(a, b, u) "
                               f"and lerp(b, a, u) with the same u")
    return True, "children are lerp(a, b, u) and lerp(b, a, u)"


def _u_random(ctx):
    us = []
    for cid in ("many", "single"):
        for _, a, b, c1, c2 in pair_results(ctx, cid):
            got = _u_of(a, b, c1, c2)
            if got and got[0]:
                us.append(got[0][0])
    halves = {u < 0.5 for u in us}
    distinct = len({round(u, 6) for u in us})
    if halves != {True, False} or distinct < len(us) / 2:
        return False, (f"over {len(us)} interpolations u took {distinct} different values "
                       f"({', '.join(f'{u:.2f}' for u in us[:8])}...); the interpolation parameter is drawn at random in [0, 1]")
    return True, f"u is random ({distinct} different values over {len(us)} calls)"


_INTERPOLATION = (
    ("returns two valid genomes of the parents' shape", valid(INTERP_CASES, pair=True)),
    ("blends a pair", _interp_changes),
    # the point: one aligned pair, blended linearly with one u drawn at random in [0, 1] for every parameter and
    # both children
    ("one pair blended with one random u", all_of(
        _each_pair(INTERP_CASES, _one_position, "at most one aligned position changes"),
        _each_pair(INTERP_CASES, _between, "every value lies between the parents'"),
        _one_u, _complementary_u, _u_random)),
    ("blends different primitives too", _mixed_blends),
    ("the symbol of the nearer parent", _each_pair(("mixed",), _nearer_parent, "the symbol comes from the nearer parent")),
    ("deterministic for a seed", deterministic("basic")),
    ("inputs unchanged", unmodified({0: "a", 1: "b"}, NEW_GENOME, what="the genome {name}")),
)

register(Check(
    hints=HINTS.get("pictures.random_interpolation", ()),
    name="pictures.random_interpolation", function="random_interpolation", params=("a", "b", "rng"), points=2.0,
    title="random interpolation", output="json_pair", cases=_interpolation_cases, gates=2,
    reference=('coursekit.pictures.operators:random_interpolation',),
    props=_INTERPOLATION,
    # the point: two u, one per child, kept 94 % before, always u = 0.5 90 %; a no-op wherever the primitives
    # differ, as they mostly do in a gallery (a student's walk): 93 %
    weights=point(_INTERPOLATION[2][0], _INTERPOLATION, (("blends different primitives too", 3),)),
))

exercise("03_picture_recombination", ["pictures.crossover", "pictures.random_copy", "pictures.random_interpolation"])
