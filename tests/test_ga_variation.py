"""Reference operators (point mutation, one-point crossover) and Variation's operator mixing."""

import functools
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from coursekit.ga import Variation, infer_arity, one_point_crossover, point_mutation
from coursekit.ga.variation import largest_remainder

bit_arrays = st.integers(2, 64).flatmap(
    lambda n: st.tuples(st.lists(st.integers(0, 1), min_size=n, max_size=n), st.lists(st.integers(0, 1), min_size=n, max_size=n))
).map(lambda ab: (np.array(ab[0], dtype=np.int8), np.array(ab[1], dtype=np.int8)))


@settings(max_examples=60, deadline=None)
@given(ab=bit_arrays, seed=st.integers(0, 2**32 - 1))
def test_one_point_crossover_swaps_tails_at_one_cut(ab, seed):
    a, b = ab
    a0, b0 = a.copy(), b.copy()
    c1, c2 = one_point_crossover(a, b, np.random.default_rng(seed))
    np.testing.assert_array_equal(a, a0)  # inputs untouched
    np.testing.assert_array_equal(b, b0)
    assert c1.dtype == a.dtype and c1.shape == a.shape == c2.shape
    cuts = [c for c in range(1, a.size) if np.array_equal(c1, np.r_[a[:c], b[c:]]) and np.array_equal(c2, np.r_[b[:c], a[c:]])]
    assert cuts, "children are not a[:c]+b[c:] and b[:c]+a[c:] for any cut 1 <= c < len"


def test_crossover_cut_is_uniform():
    # a = 0..L-1 and b = -1: the cut is the number of leading genes from a.
    L = 9
    a, b = np.arange(L, dtype=np.int64), np.full(L, -1, dtype=np.int64)
    rng = np.random.default_rng(0)
    cuts = [int((one_point_crossover(a, b, rng)[0] >= 0).sum()) for _ in range(8000)]
    observed = np.bincount(cuts, minlength=L + 1)
    assert len(observed) == L + 1 and observed[0] == 0 and observed[L] == 0  # cuts lie in 1 .. L-1
    assert stats.chisquare(observed[1:L]).pvalue > 1e-6


@settings(max_examples=40, deadline=None)
@given(ab=bit_arrays, seed=st.integers(0, 2**32 - 1), rate=st.floats(0, 1))
def test_point_mutation_flips_bits_only(ab, seed, rate):
    g = ab[0]
    g0 = g.copy()
    child = point_mutation(g, np.random.default_rng(seed), rate=rate)
    np.testing.assert_array_equal(g, g0)
    assert child.dtype == g.dtype and set(np.unique(child).tolist()) <= {0, 1}


def test_point_mutation_rates():
    g = np.zeros(50, dtype=np.int8)
    rng = np.random.default_rng(1)
    assert (point_mutation(g, rng, rate=0.0) == 0).all()
    assert (point_mutation(g, rng, rate=1.0) == 1).all()
    assert (point_mutation(np.ones(5, dtype=bool), rng, rate=1.0) == False).all()  # noqa: E712
    # default rate 1/L: flips per call ~ Binomial(L, 1/L), so 4000 calls flip 4000 bits on average
    flips = sum(int(point_mutation(g, rng).sum()) for _ in range(4000))
    sd = np.sqrt(4000 * 50 * (1 / 50) * (1 - 1 / 50))
    assert abs(flips - 4000) < 5 * sd


def test_operator_bad_input():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match=r"rate: expected a probability in \[0, 1\], got 2"):
        point_mutation(np.zeros(4, dtype=np.int8), rng, rate=2)
    with pytest.raises(TypeError, match="genome: expected a 1-D numpy array, got list"):
        point_mutation([0, 1], rng)
    with pytest.raises(ValueError, match="b: parents must have the same length"):
        one_point_crossover(np.zeros(4, dtype=np.int8), np.zeros(5, dtype=np.int8), rng)
    with pytest.raises(ValueError, match="genome: expected bits \\(0 or 1\\), got 2 at index 1"):
        point_mutation(np.array([0, 2, 1]), rng)
    with pytest.raises(TypeError, match="rng: expected a numpy.random.Generator"):
        point_mutation(np.zeros(4, dtype=np.int8), None)
    with pytest.raises(TypeError, match="rng: expected a numpy.random.Generator"):
        one_point_crossover(np.zeros(4, dtype=np.int8), np.ones(4, dtype=np.int8), 0)


@settings(max_examples=60, deadline=None)
@given(weights=st.lists(st.floats(0.01, 10), min_size=1, max_size=6), total=st.integers(0, 500))
def test_largest_remainder_sums_and_stays_within_one(weights, total):
    counts = largest_remainder(weights, total)
    quota = total * np.array(weights) / sum(weights)
    assert counts.sum() == total and (np.abs(counts - quota) < 1 + 1e-9).all()


class Recorder:
    """Operators that record how they are called; children are tagged with the operator name."""

    def __init__(self):
        self.calls = Counter()

    def mutate(self, g, rng):
        self.calls["mutate"] += 1
        return ("m", g)

    def cross(self, a, b, rng):
        self.calls["cross"] += 1
        return ("x1", a, b), ("x2", b, a)

    def graft(self, a, b, rng):
        self.calls["graft"] += 1
        return ("g1", a, b), ("g2", b, a)


@pytest.mark.parametrize("n", [240, 11, 1, 0])
def test_variation_mixes_operators_by_ratio(n):
    rec = Recorder()
    vary = Variation([(0.4, rec.mutate), (0.3, rec.cross), (0.3, rec.graft)])
    parents = list(range(n))
    children = vary(parents, np.random.default_rng(2))
    assert len(children) == n
    counts = vary.counts(n)
    assert counts.sum() == n
    if n == 240:
        assert counts.tolist() == [96, 72, 72]  # Sims 1994: 40 % asexual, 30 % crossover, 30 % grafting
    kinds = Counter(c[0] for c in children)
    assert kinds["m"] == counts[0]
    assert kinds["x1"] + kinds["x2"] == counts[1] and kinds["g1"] + kinds["g2"] == counts[2]
    # binary operators make two children per call; an odd slot costs one extra call
    assert rec.calls["mutate"] == counts[0]
    assert rec.calls["cross"] == -(-counts[1] // 2) and rec.calls["graft"] == -(-counts[2] // 2)
    # each slot's child comes from that slot's parent (unary) or has it as first parent (binary)
    for slot, child in enumerate(children):
        assert child[1] == slot


def test_variation_pairs_distinct_slots_and_is_deterministic():
    vary = Variation([(1, lambda a, b, rng: ((a, b), (b, a)))])
    out1 = vary(list(range(101)), np.random.default_rng(5))
    out2 = vary(list(range(101)), np.random.default_rng(5))
    assert out1 == out2
    assert all(a != b for a, b in out1)  # never mates a slot with itself
    assert sorted(a for a, _ in out1) == list(range(101))


def test_arity_inference_and_declaration():
    assert infer_arity(point_mutation) == 1
    assert infer_arity(one_point_crossover) == 2
    assert infer_arity(functools.partial(point_mutation, rate=0.1)) == 1
    assert infer_arity(lambda g, rng: g) == 1
    assert infer_arity(lambda a, b, rng, scale=1.0: (a, b)) == 2
    with pytest.raises(ValueError, match="takes \\*args; declare its arity"):
        infer_arity(lambda *args: args)
    with pytest.raises(ValueError, match="has 1 required positional"):
        Variation([(1.0, lambda g: g)])
    vary = Variation([(1.0, lambda *args: (args[0], args[1]), 2)])  # declared
    assert vary.arities == [2]
    rng = np.random.default_rng(0)
    out = Variation([(1, functools.partial(point_mutation, rate=1.0))])([np.zeros(3, dtype=np.int8)], rng)
    assert out[0].tolist() == [1, 1, 1]


@pytest.mark.parametrize(
    "ops, exc, pattern",
    [
        ([], ValueError, "operators: expected a non-empty list"),
        ([(0.5,)], ValueError, r"operators\[0\]: expected \(ratio, op\)"),
        ([(-1, point_mutation)], ValueError, r"operators\[0\]: ratio must be a finite number >= 0, got -1"),
        ([(1, point_mutation), (1, "mutate")], TypeError, r"operators\[1\]: operator must be callable"),
        ([(1, point_mutation, 3)], ValueError, r"operators\[0\]: arity must be 1 .* or 2 .*, got 3"),
        ([(0, point_mutation)], ValueError, "ratios must not all be zero"),
        ([(1e308, point_mutation), (1e308, point_mutation)], ValueError, "ratios must have a finite sum"),
    ],
)
def test_variation_bad_input(ops, exc, pattern):
    with pytest.raises(exc, match=pattern):
        Variation(ops)


def test_variation_call_and_counts_name_bad_arguments():
    vary = Variation([(1, point_mutation)])
    with pytest.raises(ValueError, match="n: expected an int >= 0, got -1"):
        vary.counts(-1)
    with pytest.raises(TypeError, match="parents: expected a list of genomes, got NoneType"):
        vary(None, np.random.default_rng(0))


def test_binary_operator_must_return_a_pair():
    vary = Variation([(1, lambda a, b, rng: a)])
    with pytest.raises(TypeError, match="must return \\(child1, child2\\), got int"):
        vary([1, 2], np.random.default_rng(0))
