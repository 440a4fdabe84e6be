"""The paper's seven operators (section 3.3): validity over operator chains and exact semantics."""

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from coursekit.pictures import operators as O, primitives as P, render
from coursekit.pictures.reference import render_reference
from coursekit.pictures.genome import Chromosome, ChromosomeString, Genome
from tests.test_pictures_genome import assert_valid

ALL = {**O.MUTATIONS, **O.RECOMBINATIONS}


def rows(g):
    """Every string as a list of chromosomes, keyed like the operators ('pre' for the PreHeader)."""
    out = {k: list(s.chromosomes) for k, s in enumerate(g.strings)}
    out["pre"] = list(g.preheader)
    return out


def changed(a, b):
    """{string key: [positions that differ]} between two same-shaped genomes."""
    ra, rb = rows(a), rows(b)
    out = {k: [i for i, (x, y) in enumerate(zip(ra[k], rb[k])) if x != y] for k in ra}
    return {k: v for k, v in out.items() if v}


genome_params = st.tuples(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(2, 7))


@settings(max_examples=150, deadline=None)
@given(params=genome_params, chain=st.lists(st.sampled_from(sorted(ALL)), min_size=1, max_size=25),
       seed=st.integers(0, 2**32 - 1))
def test_operator_chains_always_give_valid_genomes(params, chain, seed):
    gseed, n, h = params
    rng = np.random.default_rng(gseed)
    a = Genome.random(rng, n_strings=n, head_length=h)
    b = Genome.random(rng, n_strings=n, head_length=h)
    before = (a.to_json(), b.to_json())
    rng = np.random.default_rng(seed)
    x, y = a, b
    for name in chain:
        if name in O.MUTATIONS:
            x = O.MUTATIONS[name](x, rng)
        else:
            x, y = O.RECOMBINATIONS[name](x, y, rng)
        for g in (x, y):
            assert_valid(g)
            assert [len(s) for s in g.strings] == [len(s) for s in a.strings]
            assert Genome.from_json(g.to_json()) == g
            g.expression()
    assert (a.to_json(), b.to_json()) == before  # inputs untouched


def test_thousands_of_single_operator_applications():
    rng = np.random.default_rng(2024)
    for _ in range(400):
        a = Genome.random(rng, n_strings=int(rng.integers(1, 5)), head_length=int(rng.integers(2, 6)))
        b = Genome.random(rng, n_strings=len(a.strings), head_length=a.strings[0].head_length)
        for op in O.MUTATIONS.values():
            assert_valid(op(a, rng))
        for op in O.RECOMBINATIONS.values():
            for child in op(a, b, rng):
                assert_valid(child)


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1))
def test_transposition_semantics(params, seed):
    g = Genome.random(np.random.default_rng(params[0]), n_strings=params[1], head_length=params[2])
    out = O.transposition(g, np.random.default_rng(seed))
    diff = changed(g, out)
    assert len(diff) <= 1
    for k, pos in diff.items():
        h = len(g.preheader) if k == "pre" else g.strings[k].head_length
        assert 0 not in pos  # never the root
        old, new = rows(g)[k], rows(out)[k]
        assert len(pos) <= 2
        # both positions in the head or both in the tail: the touched ones come from one region
        region_of = lambda i: i < h  # noqa: E731
        if len(pos) == 2:
            i, j = pos
            assert region_of(i) == region_of(j)
            assert new[i] == old[j] and new[j] == old[i]  # interchange
        else:
            (i,) = pos
            # clone: the new chromosome equals another chromosome of the same region
            assert any(new[i] == old[j] for j in range(len(old)) if j != i and region_of(j) == region_of(i))


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1))
def test_root_transposition_semantics(params, seed):
    g = Genome.random(np.random.default_rng(params[0]), n_strings=params[1], head_length=params[2])
    out = O.root_transposition(g, np.random.default_rng(seed))
    diff = changed(g, out)
    assert len(diff) <= 1
    for k, pos in diff.items():
        h = len(g.preheader) if k == "pre" else g.strings[k].head_length
        old, new = rows(g)[k], rows(out)[k]
        assert pos[0] == 0 and all(i < h for i in pos) and len(pos) <= 2
        assert new[0] in old[1:h]
        if len(pos) == 2:
            assert new[pos[1]] == old[0]


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1))
def test_substitution_and_rotation_semantics(params, seed):
    g = Genome.random(np.random.default_rng(params[0]), n_strings=params[1], head_length=params[2])
    sub = O.substitution(g, np.random.default_rng(seed))
    assert sum(len(v) for v in changed(g, sub).values()) <= 1
    rot = O.head_tail_rotation(g, np.random.default_rng(seed))
    diff = changed(g, rot)
    assert len(diff) <= 1
    for k in diff:
        h = len(g.preheader) if k == "pre" else g.strings[k].head_length
        old, new = rows(g)[k], rows(rot)[k]
        head_same, tail_same = old[:h] == new[:h], old[h:] == new[h:]
        assert head_same != tail_same or (head_same and tail_same)
        part_old, part_new = (old[h:], new[h:]) if head_same else (old[:h], new[:h])
        assert any(part_old[r:] + part_old[:r] == part_new for r in range(1, len(part_old)))


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1), splits=st.integers(1, 3))
def test_crossover_exchanges_parts_position_wise(params, seed, splits):
    rng = np.random.default_rng(params[0])
    a = Genome.random(rng, n_strings=params[1], head_length=params[2])
    b = Genome.random(rng, n_strings=params[1], head_length=params[2])
    ca, cb = O.crossover(a, b, np.random.default_rng(seed), splits=splits)
    ra, rb, rca, rcb = rows(a), rows(b), rows(ca), rows(cb)
    touched = [k for k in ra if rca[k] != ra[k] or rcb[k] != rb[k]]
    assert len(touched) <= 1
    for k in ra:
        for i in range(len(ra[k])):
            assert Counter([id(rca[k][i]), id(rcb[k][i])]) == Counter([id(ra[k][i]), id(rb[k][i])])
    if touched and splits == 1:
        k = touched[0]
        # one split: child a is a prefix of a followed by a suffix of b
        q = next(i for i in range(len(ra[k])) if rca[k][i] is not ra[k][i])
        assert all(rca[k][i] is rb[k][i] for i in range(q, len(ra[k])))


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1))
def test_random_copy_copies_from_the_other_parent(params, seed):
    rng = np.random.default_rng(params[0])
    a = Genome.random(rng, n_strings=params[1], head_length=params[2])
    b = Genome.random(rng, n_strings=params[1], head_length=params[2])
    ca, cb = O.random_copy(a, b, np.random.default_rng(seed))
    for child, parent, donor in ((ca, a, b), (cb, b, a)):
        for k, pos in changed(parent, child).items():
            assert len(pos) == 1
            assert rows(child)[k][pos[0]] in rows(donor)[k]


@settings(max_examples=80, deadline=None)
@given(params=genome_params, seed=st.integers(0, 2**32 - 1))
def test_random_interpolation_changes_one_aligned_position(params, seed):
    rng = np.random.default_rng(params[0])
    a = Genome.random(rng, n_strings=params[1], head_length=params[2])
    b = Genome.random(rng, n_strings=params[1], head_length=params[2])
    ca, cb = O.random_interpolation(a, b, np.random.default_rng(seed))
    da, db = changed(a, ca), changed(b, cb)
    assert sum(len(v) for v in da.values()) <= 1 and sum(len(v) for v in db.values()) <= 1
    for k, (i,) in da.items():
        x, y, z = rows(a)[k][i], rows(b)[k][i], rows(ca)[k][i]
        assert z.symbol in (x.symbol, y.symbol)
        if x.symbol == y.symbol:
            for p, q, r in zip(x.params, y.params, z.params):
                assert min(p, q) - 1e-12 <= r <= max(p, q) + 1e-12


def test_lerp_chromosome_known_values():
    a, b = Chromosome("const", (0.2,)), Chromosome("const", (1.0,))
    assert O.lerp_chromosome(a, b, 0.25).params == pytest.approx((0.4,))
    c1, c2 = Chromosome("color", (0, 0, 1)), Chromosome("color", (1, 0.5, 0))
    assert O.lerp_chromosome(c1, c2, 0.5).params == pytest.approx((0.5, 0.25, 0.5))
    # different symbols: the nearer one's symbol, shared parameters still blend
    n1, n2 = Chromosome("bw-noise", (2.0, 10.0, 20.0)), Chromosome("color-noise", (4.0, 30.0, 40.0))
    m = O.lerp_chromosome(n1, n2, 0.75)
    assert m.symbol == "color-noise" and m.params == pytest.approx((3.5, 25.0, 35.0))
    assert O.lerp_chromosome(Chromosome("x"), Chromosome("sin"), 0.3) == Chromosome("x")


def test_operators_are_deterministic_per_seed():
    rng = np.random.default_rng(3)
    a, b = Genome.random(rng), Genome.random(rng)
    for op in O.MUTATIONS.values():
        assert op(a, np.random.default_rng(9)) == op(a, np.random.default_rng(9))
    for op in O.RECOMBINATIONS.values():
        assert op(a, b, np.random.default_rng(9)) == op(a, b, np.random.default_rng(9))


def test_recombination_refuses_incompatible_parents():
    rng = np.random.default_rng(0)
    a = Genome.random(rng, n_strings=1, head_length=2)
    b = Genome.random(rng, n_strings=1, head_length=3)
    with pytest.raises(ValueError, match="equal length"):
        O.crossover(a, b, rng)
    with pytest.raises(ValueError, match="splits"):
        O.crossover(a, a, rng, splits=0)
    with pytest.raises(TypeError, match="Genome"):
        O.transposition("genome", rng)
    for op in (O.transposition, O.root_transposition, O.substitution, O.head_tail_rotation):
        with pytest.raises(TypeError, match="rng: expected numpy.random.Generator, got NoneType"):
            op(a, None)
    for op in (O.crossover, O.random_copy, O.random_interpolation):
        with pytest.raises(TypeError, match="rng: expected numpy.random.Generator, got int"):
            op(a, a, 0)
    one = Genome((ChromosomeString(1, (Chromosome("sin"), Chromosome("x"), Chromosome("y"))),))
    with pytest.raises(ValueError, match="head length >= 2"):
        O.root_transposition(one, rng)


def test_crossing_the_same_parents_again_gives_new_genomes_that_share_the_crossed_strings():
    rng = np.random.default_rng(8)
    a, b = (Genome.random(rng, n_strings=3, head_length=4) for _ in range(2))
    first = O.crossover(a, b, np.random.default_rng(1))
    again = O.crossover(a, b, np.random.default_rng(1))
    assert first == again
    assert all(x is not y for x, y in zip(first, again))  # a session tells its children apart by identity
    for x, y in zip(first, again):
        assert all(s is t for s, t in zip(x.strings, y.strings)) and x.preheader == y.preheader
    # the same children as the crossover written out, at the split it drew
    rows_a, rows_b, rows_ca, rows_cb = rows(a), rows(b), rows(first[0]), rows(first[1])
    (k,) = [k for k in rows_a if rows_ca[k] != rows_a[k]]
    q = next(i for i, (c, p) in enumerate(zip(rows_ca[k], rows_a[k])) if c is not p)
    sa, sb = rows_a[k], rows_b[k]
    assert rows_ca[k] == sa[:q] + sb[q:] and rows_cb[k] == sb[:q] + sa[q:]


@pytest.mark.parametrize("name", sorted(ALL))
def test_an_operator_drawn_again_gives_equal_children_as_new_genomes(name):
    rng = np.random.default_rng(8)
    a, b = (Genome.random(rng, n_strings=3, head_length=4) for _ in range(2))
    op = ALL[name]
    args = (a,) if name in O.MUTATIONS else (a, b)
    first, again = (op(*args, np.random.default_rng(3)) for _ in range(2))
    first, again = ((first,), (again,)) if name in O.MUTATIONS else (first, again)
    assert first == again
    assert all(x is not y for x, y in zip(first, again))  # a session tells its children apart by identity
    if name not in ("substitution", "random_interpolation"):  # these make new chromosomes
        for x, y in zip(first, again):  # the same edit of the same string: one string
            assert all(s is t for s, t in zip(x.strings, y.strings))


# ---- swapped arguments of a commutative primitive are no change -----------------------------

def _string(tree):
    """A string coding ``tree`` (nested ``(symbol, params, children...)``), read breadth-first."""
    order, level = [], [tree]
    while level:
        order += level
        level = [c for t in level for c in t[2:]]
    h = 1 + max(i for i, t in enumerate(order) if t[2:])
    chroms = [Chromosome(t[0], t[1]) for t in order]
    return ChromosomeString(h, tuple(chroms + [Chromosome("x")] * (2 * h + 1 - len(chroms))))


def _swapped_pairs(op, rng, n):
    """``n`` pairs ``atan(op(a, b))``, ``atan(op(b, a))`` of random subtrees a, b (string roots
    linked by a PreHeader: the strings swap places), an infinite and a NaN one among them."""
    zero = ("const", (0.0,))
    big = ("expt", (), zero, ("log", (), zero))                    # exp(30) in float32
    inf = ("times", (), ("times", (), big, big), big)               # beyond float32: inf
    special = [_string(inf), _string(("minus", (), inf, inf))]     # and inf - inf: NaN
    strings = special + [Genome.random(rng, n_strings=1, head_length=int(rng.integers(1, 6))).strings[0]
                         for _ in range(n)]
    out = []
    for k in range(n):
        a, b = strings[k], strings[k + 1]
        node = Chromosome(op, tuple(float(rng.uniform(p.low, p.high)) for p in P.get(op).params))
        pre = (Chromosome("atan"), node)  # atan(op(a, b)): below a function that is not even
        out.append((Genome((a, b, strings[-1]), pre), Genome((b, a, strings[-1]), pre)))
    return out


@pytest.mark.parametrize("op", [n for n in P.names() if P.arity(n) == 2])
def test_swapped_arguments_are_one_expression_exactly_when_they_are_one_picture(op):
    pairs = _swapped_pairs(op, np.random.default_rng(3), 24)
    pics = render([g for pair in pairs for g in pair], 16, workers=1).reshape(len(pairs), 2, 16, 16, 3)
    same_picture = [np.array_equal(p[0], p[1]) for p in pics]
    same_coding = [O.coding(a) == O.coding(b) for a, b in pairs]
    if P.get(op).commutative:
        assert all(same_picture) and all(same_coding), op
    else:
        assert not all(same_picture), f"{op}: swapped arguments look the same: declare it commutative"
        assert not any(same_coding), op


def test_commutative_primitives_agree_with_the_reference_when_swapped():
    for op in [n for n in P.names() if P.get(n).commutative]:
        for a, b in _swapped_pairs(op, np.random.default_rng(4), 3):
            assert np.array_equal(render_reference(a, 5), render_reference(b, 5)), op


def test_a_transposition_that_only_swaps_the_arguments_of_plus_is_drawn_again():
    # plus x y: the only region is the tail (x, y); interchanging it swaps plus's arguments,
    # which the picture cannot show, so every transposition must clone instead
    g = Genome((ChromosomeString(1, (Chromosome("plus"), Chromosome("x"), Chromosome("y"))),))
    for seed in range(40):
        child = O.transposition(g, np.random.default_rng(seed))
        assert child.expression() in ("(plus x x)", "(plus y y)"), (seed, child.expression())
