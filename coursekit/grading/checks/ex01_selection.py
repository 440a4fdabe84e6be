"""Checks for exercise 01 (selection and variation operators of a genetic algorithm).

The seed paper (section 4, and its Sims-style GA in sections 2-3) has students write the
selection and variation operators that then drive the real evolution loop. These checks never
compare with a reference output -- a student may draw random numbers in any order -- but test
what the operators promise: the shape and type of the result, exact invariants (indices only
from the survivors, children made of their parents' genes), the distribution over many seeded
calls (chi-square / binomial tests from :mod:`coursekit.grading.stats`, each with a false-failure
rate below 1e-8), determinism for a given seed, and that inputs are left unmodified.

Each check's second property is its *job*, a gate: selection prefers fitter individuals (mean
fitness rank of the picks above 0.6, where chance gives 0.5 and the operators give 0.78-0.89),
a crossover's children hold genes of both parents, a mutation changes the genome. Until it holds
nothing else is judged, so copies and random picks score 0. One later property is the operator's
*point*, its definition (:func:`~coursekit.grading.checks.properties.point`): uniform among
exactly the survivors, the fittest of ``size`` contestants, proportional to fitness, a uniform
cut, independent flips at ``rate``. It weighs half the points: a tournament that ignores
``size`` or a roulette that is not proportional kept 71-86 % before, and keeps half now.
"""

from __future__ import annotations

import math
from collections import Counter

import numpy as np

from coursekit.grading import stats
from coursekit.grading.checks import Check, exercise, register
from coursekit.grading.checks.properties import COPY_ARRAY, RNG, all_of, array, deterministic, point, repeated, seeds, unmodified


#: Hint ladders (formative ``hint(...)``): a nudge, where to look, a concrete pointer; never the answer.
HINTS = {
    "ga.truncation": (
        ("prefers fitter individuals", (
            "Truncation keeps only the best: the parents are drawn from the top fraction `survival` of the population.",
            "Sort the indices by fitness (np.argsort sorts ascending: the best are at the end) and keep the top ones.",
            "Then draw k parents uniformly from those survivors with the rng (rng.integers or rng.choice).")),
        ("rounds the survivor count up", ("With 7 individuals and survival 0.2, 1.4 individuals survive: round up (math.ceil).",)),
        ("uniform among survivors", (
            "Every survivor is drawn equally often: the first, the last and those in between.",
            "Print your survivors and the indices you draw for a small example: does the last survivor ever come up?",
            "Check the bounds of the random draw: which values can it return, and are they all the survivors?")),
    ),
    "ga.tournament": (
        ("prefers fitter individuals", (
            "A tournament picks `size` individuals at random and keeps the fittest of them; repeat k times.",
            "rng.integers(0, n, size=(k, size)) draws all tournaments at once; then find each row's fittest.",
            "np.argmax(fitness[contestants], axis=1) tells which contestant of each row won.")),
        ("the fittest of size contestants wins", (
            "Each tournament draws `size` contestants, uniformly and with replacement (an individual may be drawn twice).",
            "Use the size argument, not a fixed number of contestants.")),
    ),
    "ga.roulette": (
        ("prefers fitter individuals", (
            "Roulette-wheel selection picks an individual with probability proportional to its fitness.",
            "Turn the fitness into probabilities that sum to 1, then draw k indices with them.",
            "rng.choice(n, size=k, p=...) draws with given probabilities.")),
    ),
    "ga.one_point_crossover": (
        ("children hold genes of both parents", (
            "A child is the start of one parent followed by the end of the other.",
            "Draw one cut position c at random (1 to len-1), then join a[:c] with b[c:], and b[:c] with a[c:].")),
        ("cut point uniform", ("Every cut from 1 to len(a) - 1 must be possible and equally likely: check rng.integers' bounds.",)),
    ),
    "ga.point_mutation": (
        ("changes the genome", (
            "Each bit flips (0 -> 1, 1 -> 0) with probability `rate`, independently of the others.",
            "rng.random(len(genome)) < rate says, bit by bit, which ones flip.",
            "1 - genome is the flipped genome; np.where picks flipped or kept bit by bit.")),
        ("default rate is 1/len", ("When rate is None, use 1 / len(genome): about one flip per call.",)),
        ("each bit flips independently with probability rate", (
            "Each bit flips on its own coin, with probability rate: sometimes no bit flips, sometimes several.",
            "Use the rate argument when it is given (0 flips nothing, 1 flips every bit).")),
    ),
}


def _pct(x):
    return f"{100 * x:.1f}%"


# -- shared properties -------------------------------------------------------------------------


def _indices_valid(case_ids):
    def prop(ctx):
        for cid in case_ids:
            n = len(ctx.arg(cid, 0))
            k = ctx.arg(cid, 1)
            for out in ctx.out(cid):
                if len(out) != k:
                    return False, f"returned {len(out)} individuals, expected k={k}"
                bad = [i for i in out if not 0 <= i < n]
                if bad:
                    return False, f"returned index {bad[0]}, out of range for a population of {n} (valid: 0..{n - 1})"
        return True, "returns k valid indices"

    return prop


def _prefers_fit(cid):
    """Job gate of a selection operator: the picks' mean fitness rank is well above chance."""
    def prop(ctx):
        fitness = ctx.arg(cid, 0)
        rank = _ranks(fitness) / (len(fitness) - 1)  # 0 for the worst, 1 for the best
        picks = np.asarray(ctx.out(cid)[0])
        mean = float(rank[picks].mean())
        if mean > 0.6:
            return True, f"prefers fitter individuals (mean fitness rank of {len(picks)} picks: {mean:.2f}, chance: 0.50)"
        return False, (f"over {len(picks)} picks from {len(fitness)} individuals the mean fitness rank (0 = worst, "
                       f"1 = best) was {mean:.2f}; picking at random gives 0.50. Selection must prefer fitter "
                       "individuals: that is its job. Nothing else is judged until it does")

    return prop


def _ranks(fitness):
    """rank[i] = 0 for the worst, n-1 for the best (fitness values are distinct in our cases)."""
    order = np.argsort(fitness, kind="stable")
    rank = np.empty(len(fitness), dtype=int)
    rank[order] = np.arange(len(fitness))
    return rank


# -- truncation --------------------------------------------------------------------------------


def _truncation_cases(rng):
    def fit(n):
        return array(rng.permutation(n) * 1.5 - n / 2 + rng.uniform(0, 1, n), "float64")

    s = seeds(rng, 5)
    return [
        {"id": "basic", "args": [fit(30), 20, RNG], "seeds": [s[0], s[0]], "max_len": 2000},
        {"id": "survival", "args": [fit(40), 30, RNG], "kwargs": {"survival": 0.5}, "seeds": [s[1]], "max_len": 3000},
        {"id": "ceil", "args": [fit(7), 300, RNG], "kwargs": {"survival": 0.2}, "seeds": [s[2]], "max_len": 30000},
        {"id": "uniform", "args": [fit(20), 20000, RNG], "kwargs": {"survival": 0.25}, "seeds": [s[3]], "max_len": 2000000},
    ]


def _truncation_survivors(ctx):
    for cid in ("basic", "survival", "ceil", "uniform"):
        fitness = ctx.arg(cid, 0)
        survival = ctx.kwarg(cid, "survival", 0.2)
        m = math.ceil(survival * len(fitness))
        rank = _ranks(fitness)
        for out in ctx.out(cid):
            worse = [i for i in out if rank[i] < len(fitness) - m]
            if worse:
                return False, (f"with {len(fitness)} individuals and survival={survival}, picked individual {worse[0]}, "
                               f"which is not among the best ceil(survival*n) = {m}")
    return True, "picks only from the best ceil(survival*n) individuals"


def _never_picked(ctx):
    """``(rank among the survivors, index)`` of the survivors of the "uniform" case (where survival * n is
    a whole number, so rounding plays no part) that were never picked in its 20000 draws, best first."""
    wide = ctx.arg("uniform", 0)
    top = np.argsort(wide)[::-1][:math.ceil(0.25 * len(wide))]
    seen = set(ctx.out("uniform")[0])
    return [(r, int(i)) for r, i in enumerate(top) if int(i) not in seen]


def _truncation_ceil(ctx):
    fitness = ctx.arg("ceil", 0)
    out = ctx.out("ceil")[0]
    m = math.ceil(0.2 * len(fitness))
    picked = len(set(out))
    if picked < m:
        if _never_picked(ctx):
            # e.g. an upper bound one short: the last survivor is never drawn, whatever the count -- the same
            # observation here as rounding down, so this case cannot tell them apart
            return False, ("not checked: it never picks some of the survivors even where survival * n is a whole "
                           "number (see 'uniform among survivors'), so whether it rounds the count up cannot be seen")
        return False, (f"with {len(fitness)} individuals and survival=0.2, only {picked} distinct individual(s) were "
                       f"picked in {len(out)} draws; all of the best ceil(0.2*{len(fitness)}) = {m} should be (round up, not down)")
    return True, "keeps ceil(survival*n) survivors (rounds up)"


def _truncation_uniform(ctx):
    fitness = ctx.arg("uniform", 0)
    out = ctx.out("uniform")[0]
    m = math.ceil(0.25 * len(fitness))
    best = np.argsort(fitness)[::-1][:m]
    counts = Counter(out)
    obs = [counts.get(int(i), 0) for i in best]
    if sum(obs) != len(out):
        return False, "not checked: picks outside the survivors"
    never = _never_picked(ctx)
    if never:
        if [r for r, _ in never] == [m - 1]:
            which = f"the last of them, the {_ordinal(m)} best (index {never[0][1]}), was"
        else:
            which = ", ".join(f"the {_ordinal(r + 1)} best (index {i})" for r, i in never)
            which += " was" if len(never) == 1 else " were"
        return False, (f"with {len(fitness)} individuals and survival=0.25 there are {m} survivors, and over {len(out)} "
                       f"draws {which} never picked; every survivor should be picked about {_pct(1 / m)} of the time")
    ok, _, _ = stats.chi_square(obs, [1 / m] * m)
    if ok:
        return True, f"draws uniformly among the survivors ({len(out)} draws)"
    shares = ", ".join(_pct(o / len(out)) for o in obs)
    return False, (f"over {len(out)} draws the {m} survivors (best first) were picked {shares} of the time; "
                   f"each should be picked about {_pct(1 / m)} (uniformly, with replacement)")


def _ordinal(n):
    return f"{n}{'th' if 10 <= n % 100 < 20 else {1: 'st', 2: 'nd', 3: 'rd'}.get(n % 10, 'th')}"


#: Selection schemes of the library that do a graded scheme's work under another name: Sims' scheme
#: with survival 1 is proportional selection (withheld: nothing in the exercise needs it), and its
#: counts come from largest_remainder, which the notebook's Variation needs (withheld in the run that grades them).
SIBLINGS = ('coursekit.ga.selection:sims_select', 'coursekit.ga.selection:sims_offspring',
            'coursekit.ga.variation:largest_remainder')
NEEDED = ('coursekit.ga.variation:largest_remainder',)


_TRUNCATION = (
    ("returns k valid indices", _indices_valid(["basic", "survival", "ceil", "uniform"])),
    ("prefers fitter individuals", _prefers_fit("uniform")),
    ("only the best survive", _truncation_survivors),
    ("uniform among survivors", _truncation_uniform),  # before the rounding: the summary names the first failure
    ("rounds the survivor count up", _truncation_ceil),
    ("deterministic for a seed", deterministic("basic")),
    ("inputs unchanged", unmodified({0: "fitness"}, COPY_ARRAY)),
)

register(Check(
    hints=HINTS.get("ga.truncation", ()),
    name="ga.truncation", function="truncation", params=("fitness", "k", "rng"), points=2.0,
    title="truncation selection", output="indices", cases=_truncation_cases, gates=2,
    # and the library's steps of it, and the scheme that contains it (red team: ranking + n_survivors, sims_select):
    # withheld in a second run that grades truncation, kept in the first for the library's own selection
    reference=('coursekit.ga.selection:truncation', *SIBLINGS, 'coursekit.ga.selection:ranking',
               'coursekit.ga.selection:n_survivors'),
    library_uses=(*NEEDED, 'coursekit.ga.selection:ranking', 'coursekit.ga.selection:n_survivors'),
    props=_TRUNCATION,
    weights=point("uniform among survivors", _TRUNCATION),  # exactly the survivors, each alike: truncation's point
))


# -- tournament --------------------------------------------------------------------------------


def _tournament_cases(rng):
    def fit(n):
        return array(rng.permutation(n) - n / 3 + rng.uniform(0, 0.5, n), "float64")

    s = seeds(rng, 3)
    return [
        {"id": "basic", "args": [fit(30), 20, RNG], "seeds": [s[0], s[0]], "max_len": 2000},
        {"id": "size3", "args": [fit(10), 20000, RNG], "seeds": [s[1]], "max_len": 2000000},
        {"id": "size2", "args": [fit(8), 20000, RNG], "kwargs": {"size": 2}, "seeds": [s[2]], "max_len": 2000000},
    ]


def _tournament_rate(ctx, cid):
    fitness = ctx.arg(cid, 0)
    size = ctx.kwarg(cid, "size", 3)
    n = len(fitness)
    out = ctx.out(cid)[0]
    rank = _ranks(fitness)
    counts = np.bincount(rank[np.asarray(out)], minlength=n)
    j = np.arange(n)
    probs = ((j + 1) / n) ** size - (j / n) ** size  # P(winner has rank j): best of `size` uniform draws
    ok, _, _ = stats.chi_square(counts, probs)
    p_best = 1 - (1 - 1 / n) ** size
    if ok:
        return True, f"with size={size}, the best of {n} won {_pct(counts[-1] / len(out))} of {len(out)} tournaments (expected about {_pct(p_best)})"
    return False, (f"with size={size}, the best of {n} individuals won {_pct(counts[-1] / len(out))} of {len(out)} tournaments "
                   f"and the worst {_pct(counts[0] / len(out))}; a tournament of {size} contestants drawn uniformly with "
                   f"replacement is won by the best {_pct(p_best)} of the time (1-(1-1/n)^size) and by the worst {_pct(probs[0])}")


_TOURNAMENT = (
    ("returns k valid indices", _indices_valid(["basic", "size3", "size2"])),
    ("prefers fitter individuals", _prefers_fit("size3")),
    # the winners' ranks follow the best-of-size law, for the default size 3 and for size=2
    ("the fittest of size contestants wins", all_of(lambda ctx: _tournament_rate(ctx, "size3"),
                                                    lambda ctx: _tournament_rate(ctx, "size2"))),
    ("deterministic for a seed", deterministic("basic")),
    ("inputs unchanged", unmodified({0: "fitness"}, COPY_ARRAY)),
)


register(Check(
    hints=HINTS.get("ga.tournament", ()),
    name="ga.tournament", function="tournament", params=("fitness", "k", "rng"), points=2.0,
    title="tournament selection", output="indices", cases=_tournament_cases, gates=2,
    reference=('coursekit.ga.selection:tournament',),
    props=_TOURNAMENT,
    weights=point("the fittest of size contestants wins", _TOURNAMENT),  # a fixed size, no replacement: 71 % before
))


# -- roulette ----------------------------------------------------------------------------------


def _roulette_cases(rng):
    dist = rng.permutation([3.0, 0.0, 1.0, 6.0, 2.0, 0.0, 8.0, 4.5])
    s = seeds(rng, 2)
    return [
        {"id": "basic", "args": [array(rng.uniform(0.5, 5.0, 25), "float64"), 20, RNG], "seeds": [s[0], s[0]], "max_len": 2000},
        {"id": "dist", "args": [array(dist, "float64"), 20000, RNG], "seeds": [s[1]], "max_len": 2000000},
    ]


def _roulette_zero(ctx):
    fitness = ctx.arg("dist", 0)
    out = ctx.out("dist")[0]
    zero = [i for i in out if fitness[i] == 0]
    if zero:
        return False, f"picked individual {zero[0]}, whose fitness is 0, {len(zero)} times in {len(out)} draws; its chance should be 0"
    return True, "never picks an individual of fitness 0"


def _roulette_proportional(ctx):
    fitness = ctx.arg("dist", 0)
    out = ctx.out("dist")[0]
    pos = np.flatnonzero(fitness > 0)
    counts = Counter(out)
    obs = [counts.get(int(i), 0) for i in pos]
    probs = fitness[pos] / fitness[pos].sum()
    if sum(obs) != len(out):
        return False, "not checked: picks individuals of fitness 0"
    ok, _, _ = stats.chi_square(obs, probs)
    if ok:
        return True, f"picks in proportion to fitness ({len(out)} draws)"
    i = int(np.argmax(np.abs(np.asarray(obs) / len(out) - probs)))
    return False, (f"over {len(out)} draws, individual {int(pos[i])} (fitness {fitness[pos[i]]:g} of a total {fitness.sum():g}) "
                   f"was picked {_pct(obs[i] / len(out))} of the time; roulette selection picks it with probability "
                   f"fitness / total fitness = {_pct(probs[i])}")


_ROULETTE = (
    ("returns k valid indices", _indices_valid(["basic", "dist"])),
    ("prefers fitter individuals", _prefers_fit("dist")),
    ("never picks zero fitness", _roulette_zero),
    ("proportional to fitness", _roulette_proportional),
    ("deterministic for a seed", deterministic("basic")),
    ("inputs unchanged", unmodified({0: "fitness"}, COPY_ARRAY)),
)

register(Check(
    hints=HINTS.get("ga.roulette", ()),
    name="ga.roulette", function="roulette", params=("fitness", "k", "rng"), points=2.0,
    title="roulette-wheel selection", output="indices", cases=_roulette_cases, gates=2,
    reference=('coursekit.ga.selection:roulette', *SIBLINGS),  # sims_select(survival=1) is proportional too
    library_uses=NEEDED,
    props=_ROULETTE,
    weights=point("proportional to fitness", _ROULETTE),  # fitter picked more, not in proportion: 86 % before
))


# -- one-point crossover -----------------------------------------------------------------------


def _crossover_cases(rng):
    s = seeds(rng, 602)

    def bits(n):
        return rng.integers(0, 2, n)

    a10, a5 = bits(10), bits(5)
    return [  # b = 1 - a differs everywhere, so the cut can be read off the children; "mixed" parents share genes
        # 3 seeds 4 times each: a cut from a global generator (9 possible) repeats with probability 9^-9
        {"id": "basic", "args": [array(a10, "int8"), array(1 - a10, "int8"), RNG], "seeds": repeated(s[:3], 4),
         "max_len": 1000},
        {"id": "mixed", "args": [array(bits(16), "int8"), array(bits(16), "int8"), RNG], "seeds": s[3:6], "max_len": 1000},
        {"id": "cuts", "args": [array(a5, "int8"), array(1 - a5, "int8"), RNG], "seeds": s[6:602], "max_len": 500},
    ]


def _cut_of(a, b, c1, c2):
    """A cut c in 1..len-1 with c1 = a[:c]+b[c:] and c2 = b[:c]+a[c:], or None and why not."""
    L = len(a)
    for c in range(1, L):
        if c1 == a[:c] + b[c:] and c2 == b[:c] + a[c:]:
            return c, ""
    if {tuple(c1), tuple(c2)} == {tuple(a), tuple(b)}:
        return None, "the children are copies of the parents; the cut must lie in 1..len-1 so both parents contribute"
    return None, f"children {c1} and {c2} are not a[:c] + b[c:] and b[:c] + a[c:] for any cut 1 <= c <= {L - 1}"


def _crossover_valid(ctx):
    for cid in ("basic", "mixed", "cuts"):
        L = len(ctx.arg(cid, 0))
        for c1, c2 in ctx.out(cid):
            if len(c1) != L or len(c2) != L:
                return False, f"returned children of lengths {len(c1)} and {len(c2)}; expected both of the parents' length {L}"
    return True, "returns two arrays of the parents' length"


def _crossover_mixes(ctx):
    a, b = ctx.arg("cuts", 0).tolist(), ctx.arg("cuts", 1).tolist()
    outs = ctx.out("cuts")
    mixed = sum(c1 not in (a, b) and c2 not in (a, b) for c1, c2 in outs)
    if mixed >= len(outs) / 2:
        return True, f"in {mixed} of {len(outs)} calls both children hold genes of both parents"
    return False, (f"in {len(outs) - mixed} of {len(outs)} calls a child was a copy of a parent; a crossover's children "
                   "hold genes of both parents. Nothing else is judged until they do")


def _crossover_one_point(ctx):
    for cid in ("basic", "mixed", "cuts"):
        a, b = ctx.arg(cid, 0).tolist(), ctx.arg(cid, 1).tolist()
        for (c1, c2), seed in zip(ctx.out(cid), ctx.case(cid)["seeds"]):
            c, why = _cut_of(a, b, c1, c2)
            if c is None:
                return False, f"for parents a={a} and b={b} (rng seed {seed}): {why}"
    return True, "children are a[:c]+b[c:] and b[:c]+a[c:] with 1 <= c <= len-1"


def _crossover_uniform(ctx):
    a, b = ctx.arg("cuts", 0).tolist(), ctx.arg("cuts", 1).tolist()
    cuts = []
    for c1, c2 in ctx.out("cuts"):
        c, _ = _cut_of(a, b, c1, c2)
        if c is None:
            return False, "not checked: not every result is a one-point crossover"
        cuts.append(c)
    L = len(a)
    counts = [cuts.count(c) for c in range(1, L)]
    ok, _, _ = stats.chi_square(counts, [1 / (L - 1)] * (L - 1))
    shares = ", ".join(f"c={c}: {_pct(n / len(cuts))}" for c, n in zip(range(1, L), counts))
    if ok:
        return True, f"cut point uniform on 1..{L - 1} over {len(cuts)} calls"
    return False, f"over {len(cuts)} crossovers of length-{L} parents the cut fell at {shares}; each of 1..{L - 1} should have about {_pct(1 / (L - 1))}"


_CROSSOVER = (
    ("returns two children of the right length", _crossover_valid),
    ("children hold genes of both parents", _crossover_mixes),
    ("children are one-point crossovers", _crossover_one_point),
    ("cut point uniform", _crossover_uniform),
    ("deterministic for a seed", deterministic("basic")),
    ("inputs unchanged", unmodified({0: "a", 1: "b"}, COPY_ARRAY)),
)

register(Check(
    hints=HINTS.get("ga.one_point_crossover", ()),
    name="ga.one_point_crossover", function="one_point_crossover", params=("a", "b", "rng"), points=2.0,
    title="one-point crossover", output="array_pair", cases=_crossover_cases, gates=2,
    reference=('coursekit.ga.operators:one_point_crossover',),
    props=_CROSSOVER,
    # one-point crossovers at a uniform cut (it judges nothing else): a fixed cut is no GA operator, as in exercise 03
    weights=point("cut point uniform", _CROSSOVER),
))


# -- point mutation ----------------------------------------------------------------------------


def _mutation_cases(rng):
    s = seeds(rng, 1508)

    def genome(n):
        return array(rng.integers(0, 2, n), "int8")

    return [
        # 3 seeds 4 times each, at rate 0.5: flips from a global generator repeat with probability 2^-270 (at the
        # default rate one call in three flips nothing, and so would two calls of a function that ignores its rng)
        {"id": "basic", "args": [genome(30), RNG], "kwargs": {"rate": 0.5}, "seeds": repeated(s[:3], 4), "max_len": 1000},
        {"id": "default", "args": [genome(40), RNG], "seeds": s[3:1003], "max_len": 1000},
        {"id": "rate", "args": [genome(20), RNG], "kwargs": {"rate": 0.25}, "seeds": s[1003:1503], "max_len": 1000},
        {"id": "rate0", "args": [genome(16), RNG], "kwargs": {"rate": 0.0}, "seeds": s[1503:1505], "max_len": 1000},
        {"id": "rate1", "args": [genome(16), RNG], "kwargs": {"rate": 1.0}, "seeds": s[1505:1508],
         "max_len": 1000},
    ]


_MUTATION_CASES = ("basic", "default", "rate", "rate0", "rate1")


def _flips(ctx, cid):
    g = ctx.arg(cid, 0)
    return np.array([np.asarray(out) != g for out in ctx.out(cid)])


def _mutation_valid(ctx):
    for cid in _MUTATION_CASES:
        L = len(ctx.arg(cid, 0))
        for out in ctx.out(cid):
            if len(out) != L:
                return False, f"returned a genome of length {len(out)} for an input of length {L}"
            bad = [v for v in out if v not in (0, 1)]
            if bad:
                return False, f"returned a genome containing {bad[0]!r}; a mutated 0/1 genome holds only 0 and 1"
    return True, "returns a 0/1 genome of the same length"


def _mutation_changes(ctx):
    f = _flips(ctx, "default")
    changed = int(f.any(axis=1).sum())
    if changed >= len(f) / 3:  # a correct mutation changes 1 - (1 - 1/40)^40 = 64 % of them
        return True, f"changed {changed} of {len(f)} genomes at the default rate"
    return False, (f"changed {changed} of {len(f)} genomes of length {f.shape[1]} at the default rate; a mutation "
                   "flips each bit with probability 1/len, so most genomes change. Nothing else is judged until it does")


def _mutation_default_rate(ctx):
    f = _flips(ctx, "default")
    calls, L = f.shape
    ok, lo, hi = stats.binomial_ok(int(f.sum()), f.size, 1 / L)
    if ok:
        return True, f"flipped {int(f.sum())} of {f.size} bits with the default rate (about 1/len expected)"
    return False, (f"with the default rate on {calls} genomes of length {L}, {int(f.sum())} of {f.size} bits were flipped "
                   f"({_pct(f.mean())}); each bit should flip with probability 1/len = {_pct(1 / L)}")


def _mutation_independent(ctx):
    f = _flips(ctx, "default")
    calls, L = f.shape
    p = 1 / L
    per_genome = f.sum(axis=1)
    top = 4  # bins 0, 1, 2, 3 and ">= 4" (expected counts >= 5 for L=40, 1000 calls)
    obs = [int(np.sum(per_genome == j)) for j in range(top)] + [int(np.sum(per_genome >= top))]
    pk = [math.comb(L, j) * p**j * (1 - p) ** (L - j) for j in range(top)]
    ok_hist, _, _ = stats.chi_square(obs, pk + [1 - sum(pk)])
    ok_pos, _, _ = stats.chi_square(f.sum(axis=0), [1 / L] * L) if f.sum() else (False, 0, 0)
    if not ok_hist:
        hist = ", ".join(f"{j}: {_pct(o / calls)}" for j, o in enumerate(obs[:top]))
        exp = ", ".join(f"{j}: {_pct(q)}" for j, q in enumerate(pk))
        return False, (f"number of bits flipped per genome (of {calls} genomes of length {L}): {hist}; "
                       f"flipping each bit independently gives about {exp}")
    if not ok_pos:
        return False, f"some positions of the genome are flipped much more often than others (over {calls} genomes of length {L}); every position should be equally likely"
    return True, "each bit flips independently, at every position alike"


def _mutation_rate(ctx):
    f = _flips(ctx, "rate")
    ok, _, _ = stats.binomial_ok(int(f.sum()), f.size, 0.25)
    if not ok:
        return False, f"with rate=0.25, {_pct(f.mean())} of {f.size} bits were flipped; expected about 25%"
    if _flips(ctx, "rate0").any():
        return False, "with rate=0.0 some bits were flipped; no bit should change"
    if not _flips(ctx, "rate1").all():
        return False, "with rate=1.0 some bits were not flipped; every bit should change"
    return True, "honours the rate argument (0, 0.25 and 1)"


_MUTATION = (
    ("returns a 0/1 genome of the same length", _mutation_valid),
    ("changes the genome", _mutation_changes),
    ("default rate is 1/len", _mutation_default_rate),
    # each bit flips on its own, with probability rate: the default rate's spread, then rates 0.25, 0 and 1
    ("each bit flips independently with probability rate", all_of(_mutation_independent, _mutation_rate)),
    ("deterministic for a seed", deterministic("basic")),
    ("input unchanged", unmodified({0: "genome"}, COPY_ARRAY)),
)


register(Check(
    hints=HINTS.get("ga.point_mutation", ()),
    name="ga.point_mutation", function="point_mutation", params=("genome", "rng"), points=2.0,
    title="point mutation", output="array", cases=_mutation_cases, gates=2,
    reference=('coursekit.ga.operators:point_mutation',),
    props=_MUTATION,
    weights=point("each bit flips independently with probability rate", _MUTATION),  # one flip always, rate ignored
))


exercise("01_selection", ["ga.truncation", "ga.tournament", "ga.roulette", "ga.one_point_crossover", "ga.point_mutation"])
