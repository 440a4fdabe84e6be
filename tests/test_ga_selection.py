"""Selection schemes: invariants (hypothesis) and sampling distributions against their
analytically derived probabilities (chi-square / binomial bounds over many seeded draws)."""

import functools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from coursekit.ga import ranking, roulette, sims_offspring, sims_select, tournament, truncation
from coursekit.ga.selection import n_survivors

# p-value below which a sampled distribution is declared wrong. With fixed seeds the tests are
# deterministic; a correct sampler lands far above this, a wrong one (e.g. an off-by-one in the
# wheel, ties to the wrong index) far below it given the sample sizes used.
P_MIN = 1e-6

fitness_arrays = st.lists(st.floats(0.0, 100.0, allow_nan=False, width=32), min_size=1, max_size=40).map(
    lambda v: np.asarray(v, dtype=np.float64)
)
signed_fitness = st.lists(st.floats(-100.0, 100.0, allow_nan=False, width=32), min_size=1, max_size=40).map(
    lambda v: np.asarray(v, dtype=np.float64)
)
SELECTORS = [truncation, tournament, roulette, sims_select, functools.partial(tournament, size=7),
             functools.partial(truncation, survival=0.5)]


def chisquare_p(observed, expected_prob):
    observed = np.asarray(observed, dtype=float)
    expected = observed.sum() * np.asarray(expected_prob, dtype=float)
    mask = expected > 0
    assert observed[~mask].sum() == 0, "selected an individual that has probability 0"
    return stats.chisquare(observed[mask], expected[mask]).pvalue


@settings(max_examples=60, deadline=None)
@given(fitness=fitness_arrays, k=st.integers(0, 60), seed=st.integers(0, 2**32 - 1), which=st.integers(0, len(SELECTORS) - 1))
def test_selectors_return_k_valid_indices_deterministically(fitness, k, seed, which):
    select = SELECTORS[which]
    a = select(fitness, k, np.random.default_rng(seed))
    b = select(fitness, k, np.random.default_rng(seed))
    assert isinstance(a, np.ndarray) and a.dtype == np.int64 and a.shape == (k,)
    assert ((a >= 0) & (a < fitness.size)).all()
    np.testing.assert_array_equal(a, b)


@settings(max_examples=60, deadline=None)
@given(fitness=signed_fitness, k=st.integers(1, 60), seed=st.integers(0, 2**32 - 1), survival=st.floats(0.01, 1.0))
def test_truncation_returns_only_survivors(fitness, k, seed, survival):
    idx = truncation(fitness, k, np.random.default_rng(seed), survival=survival)
    m = n_survivors(fitness.size, survival)
    assert m == max(1, math.ceil(round(survival * fitness.size, 9)))
    survivors = set(ranking(fitness)[:m].tolist())
    assert set(idx.tolist()) <= survivors
    # every survivor is at least as fit as every non-survivor
    threshold = np.sort(fitness)[::-1][m - 1]
    assert (fitness[idx] >= threshold).all()


@settings(max_examples=60, deadline=None)
@given(fitness=signed_fitness)
def test_ranking_is_a_stable_descending_permutation(fitness):
    order = ranking(fitness)
    assert sorted(order.tolist()) == list(range(fitness.size))
    f = fitness[order]
    assert (np.diff(f) <= 0).all()
    for i in range(len(order) - 1):  # ties keep index order
        if f[i] == f[i + 1]:
            assert order[i] < order[i + 1]


@settings(max_examples=80, deadline=None)
@given(fitness=fitness_arrays, n_offspring=st.integers(0, 400), survival=st.floats(0.01, 1.0))
def test_sims_offspring_counts(fitness, n_offspring, survival):
    counts = sims_offspring(fitness, n_offspring, survival=survival)
    assert counts.dtype == np.int64 and counts.shape == fitness.shape
    assert counts.sum() == n_offspring and (counts >= 0).all()
    survivors = ranking(fitness)[: n_survivors(fitness.size, survival)]
    nonsurvivors = np.setdiff1d(np.arange(fitness.size), survivors)
    assert (counts[nonsurvivors] == 0).all()
    fs = fitness[survivors]
    quota = n_offspring * (fs / fs.sum() if fs.sum() > 0 else np.full(fs.size, 1 / fs.size))
    assert (np.abs(counts[survivors] - quota) < 1 + 1e-9).all()  # largest remainder: within 1 of the quota
    for i in survivors:  # fitter survivors never get fewer offspring
        for j in survivors:
            if fitness[i] > fitness[j]:
                assert counts[i] >= counts[j]


@settings(max_examples=40, deadline=None)
@given(fitness=fitness_arrays, k=st.integers(0, 200), seed=st.integers(0, 2**32 - 1))
def test_sims_select_reproduces_the_counts(fitness, k, seed):
    idx = sims_select(fitness, k, np.random.default_rng(seed))
    np.testing.assert_array_equal(np.bincount(idx, minlength=fitness.size), sims_offspring(fitness, k))


def test_sims_offspring_known_value():
    # Sims 1994: 300 creatures, the top fifth (60) survive, 240 offspring shared in proportion to
    # fitness. 30 survivors of fitness 3 and 30 of fitness 1 (sum 120) get exactly 6 and 2 each.
    fitness = np.zeros(300)
    fitness[100:130] = 3.0
    fitness[200:230] = 1.0
    counts = sims_offspring(fitness, 240)
    expected = np.zeros(300, dtype=int)
    expected[100:130] = 6
    expected[200:230] = 2
    np.testing.assert_array_equal(counts, expected)
    # Hamilton's method by hand: quotas 40/9, 30/9, 20/9 = 4.44, 3.33, 2.22 -> floors 4, 3, 2
    # (sum 9) and the one left over goes to the largest remainder (4.44) -> 5, 3, 2.
    assert sims_offspring([4.0, 0.0, 1.0, 3.0, 2.0], 10, survival=0.6).tolist() == [5, 0, 0, 3, 2]


@pytest.mark.parametrize("n,size", [(10, 3), (5, 1), (8, 5), (20, 2)])
def test_tournament_win_probabilities_match_order_statistics(n, size):
    # With distinct fitness, the individual of rank r (0 = best) wins iff no better one is drawn
    # and it is drawn at least once: P = ((n - r)/n)^size - ((n - r - 1)/n)^size.
    # In particular P(best wins) = 1 - (1 - 1/n)^size.
    rng = np.random.default_rng(1000 + n * size)
    fitness = rng.permutation(n).astype(float)
    draws = 40_000
    idx = tournament(fitness, draws, rng, size=size)
    rank_of = np.empty(n, dtype=int)
    rank_of[ranking(fitness)] = np.arange(n)
    observed = np.bincount(rank_of[idx], minlength=n)
    r = np.arange(n)
    expected = ((n - r) / n) ** size - ((n - r - 1) / n) ** size
    assert chisquare_p(observed, expected) > P_MIN
    p_best = 1 - (1 - 1 / n) ** size
    assert abs(observed[0] / draws - p_best) < 5 * math.sqrt(p_best * (1 - p_best) / draws)


def test_tournament_ties_go_to_the_lowest_index():
    # All equal: the winner is the smallest index drawn, P(i) = ((n - i)/n)^s - ((n - i - 1)/n)^s.
    n, size = 6, 3
    idx = tournament(np.ones(n), 30_000, np.random.default_rng(7), size=size)
    i = np.arange(n)
    assert chisquare_p(np.bincount(idx, minlength=n), ((n - i) / n) ** size - ((n - i - 1) / n) ** size) > P_MIN
    # with size >= the draws needed, a tie between the top two always resolves to the lower index
    fitness = np.array([0.0, 5.0, 1.0, 5.0])
    assert set(tournament(fitness, 2000, np.random.default_rng(8), size=50).tolist()) == {1}


def test_roulette_frequencies_match_fitness_shares():
    fitness = np.array([0.0, 1.0, 2.0, 3.0, 10.0, 0.5, 0.0, 4.0])
    idx = roulette(fitness, 50_000, np.random.default_rng(3))
    assert chisquare_p(np.bincount(idx, minlength=fitness.size), fitness / fitness.sum()) > P_MIN


def test_roulette_all_zero_is_uniform_and_rejects_negative():
    idx = roulette(np.zeros(5), 20_000, np.random.default_rng(4))
    assert chisquare_p(np.bincount(idx, minlength=5), np.full(5, 0.2)) > P_MIN
    with pytest.raises(ValueError, match="fitness.*non-negative.*-1.0.*index 2"):
        roulette(np.array([1.0, 2.0, -1.0]), 3, np.random.default_rng(0))


def test_truncation_is_uniform_over_survivors():
    fitness = np.array([5.0, 1.0, 9.0, 3.0, 7.0, 2.0, 8.0, 0.0, 6.0, 4.0])
    idx = truncation(fitness, 20_000, np.random.default_rng(5), survival=0.3)  # ceil(3) survivors: 2, 6, 4
    expected = np.zeros(10)
    expected[[2, 6, 4]] = 1 / 3
    assert chisquare_p(np.bincount(idx, minlength=10), expected) > P_MIN


def test_selection_pressure_orders_the_schemes():
    # Mean selected rank (0 = best) for 50 individuals: uniform ~24.5, tournament(3) ~ n/4,
    # truncation(0.2) ~ 4.5. Exact expectations, sampled with many draws.
    n = 50
    fitness = np.linspace(1, 2, n)[::-1].copy()
    rng = np.random.default_rng(11)
    mean_rank = {name: ranking(fitness).argsort()[sel(fitness, 20_000, rng)].mean()
                 for name, sel in [("uniform", functools.partial(tournament, size=1)), ("tournament3", tournament),
                                   ("truncation", truncation)]}
    r = np.arange(n)
    expect_t3 = np.sum(r * (((n - r) / n) ** 3 - ((n - r - 1) / n) ** 3))
    assert abs(mean_rank["uniform"] - (n - 1) / 2) < 0.5
    assert abs(mean_rank["tournament3"] - expect_t3) < 0.5
    assert abs(mean_rank["truncation"] - 4.5) < 0.2


@pytest.mark.parametrize(
    "call, exc, pattern",
    [
        (lambda r: tournament([1.0, float("nan")], 2, r), ValueError, r"fitness: value nan at index 1"),
        (lambda r: tournament(np.ones((2, 2)), 2, r), ValueError, r"fitness: expected a 1-D"),
        (lambda r: tournament([], 2, r), ValueError, r"fitness: the population is empty"),
        (lambda r: tournament(["a", "b"], 2, r), TypeError, r"fitness: expected real numbers"),
        (lambda r: tournament([1.0, 2.0], -1, r), ValueError, r"k: expected a non-negative int, got -1"),
        (lambda r: tournament([1.0, 2.0], 2.5, r), TypeError, r"k: expected a non-negative int"),
        (lambda r: tournament([1.0, 2.0], 2, r, size=0), ValueError, r"size: tournament size must be an int >= 1, got 0"),
        (lambda r: truncation([1.0, 2.0], 2, r, survival=0), ValueError, r"survival: expected a fraction in \(0, 1\], got 0"),
        (lambda r: truncation([1.0, 2.0], 2, r, survival=1.5), ValueError, r"survival"),
        (lambda r: truncation([1.0, 2.0], 2, 42), TypeError, r"rng: expected a numpy.random.Generator"),
        (lambda r: sims_offspring([-1.0, -2.0], 4), ValueError, r"fitness: .*non-negative survivor fitness"),
        (lambda r: sims_offspring([1.0, 2.0], -4), ValueError, r"n_offspring"),
        (lambda r: sims_select([1.0, 2.0], -4, r), ValueError, r"^k: expected a non-negative int, got -4"),
        (lambda r: sims_select([1.0, 2.0], 2.5, r), TypeError, r"^k: expected a non-negative int"),
    ],
)
def test_bad_input_errors_name_the_field(call, exc, pattern):
    with pytest.raises(exc, match=pattern):
        call(np.random.default_rng(0))
