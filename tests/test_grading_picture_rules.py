"""Rules of the picture exercises (02, 03) set after an honest-student study: answers that got an operator's
definition wrong kept 80-100 % of its points, and the determinism check could land on a choice with one outcome.

- each check has a *point* (its definition, with the random choices it names) that weighs half its points;
- a substitution draws a new random chromosome (not a copy of one of the string's), functions at head
  positions too, and reaches the PreHeader (a string, in the exercise's text);
- the determinism case repeats several seeds on a genome where every random choice has several outcomes.
"""

import numpy as np
import pytest

from coursekit.grading import checks, evaluate
from coursekit.grading.checks import picture_genomes as PG
from coursekit.pictures import Genome
from check_points import assert_a_point_weighs_half
from test_grading_pictures import (
    MUTATIONS, RECOMBINATIONS, copy_same_position, crossover_fixed, crossover_identical_children,
    decode_depth_first, interp_children_independent, interp_half, interp_u_per_parameter, root_swap_only,
    rotation_tail_by_one, strings_of, substitution_copies_the_string, substitution_never_the_preheader,
    substitution_terminals_only, transposition_swap_only, transposition_with_root, with_string)

NAMES = [f"pictures.{n}" for n in ["decode"] + MUTATIONS + RECOMBINATIONS]


@pytest.mark.parametrize("name", NAMES)
def test_every_check_has_a_point_weighing_half(name):
    assert_a_point_weighs_half(name)


# What the study's buggy answers did (scores before: 83 %, 80-90 %, 100 %, 91 %, 94 % ...).
CORE_BUGS = [
    ("decode", decode_depth_first), ("transposition", transposition_with_root),
    ("transposition", transposition_swap_only), ("root_transposition", root_swap_only),
    ("substitution", substitution_copies_the_string), ("substitution", substitution_terminals_only),
    ("substitution", substitution_never_the_preheader), ("head_tail_rotation", rotation_tail_by_one),
    ("crossover", crossover_identical_children), ("crossover", crossover_fixed), ("random_copy", copy_same_position),
    ("random_interpolation", interp_children_independent), ("random_interpolation", interp_u_per_parameter),
    ("random_interpolation", interp_half),
]


@pytest.mark.parametrize("name,fn", CORE_BUGS, ids=[f.__name__ for _, f in CORE_BUGS])
def test_getting_the_definition_wrong_keeps_at_most_half(name, fn):
    j = evaluate(f"pictures.{name}", fn, seed=11)
    assert 0 < j.score <= j.check.points / 2, [(v.prop, v.passed, v.message[:120]) for v in j.verdicts]


@pytest.mark.parametrize("fn, says", [
    (substitution_copies_the_string, "equals another chromosome of the same string"),
    (substitution_terminals_only, "a terminal every time"),
    (substitution_never_the_preheader, "none replaced a chromosome of the PreHeader"),
])
def test_substitution_says_what_is_not_random_about_it(fn, says):
    point = checks.get("pictures.substitution").props[3][0]
    for seed in (11, 12, 13):
        verdicts = {v.prop: v for v in evaluate("pictures.substitution", fn, seed=seed).verdicts}
        assert not verdicts[point].passed and says in verdicts[point].message, verdicts[point].message


# -- determinism ---------------------------------------------------------------------------------------


def rotation_global_shift(genome, rng):  # the study's: the region from rng, the shift from np.random
    choices = [(key, chroms, lo, hi) for key, chroms, h in strings_of(genome)
               for lo, hi in ((0, h), (h, len(chroms))) if hi - lo >= 2]
    key, chroms, lo, hi = choices[rng.integers(len(choices))]
    s = int(np.random.randint(1, hi - lo))
    return with_string(genome, key, chroms[:lo] + chroms[lo + s:hi] + chroms[lo:lo + s] + chroms[hi:])


def crossover_global_cut(a, b, rng):  # the study's: the string pair from rng, the cut from np.random
    rows_a, rows_b = strings_of(a), strings_of(b)
    n = int(rng.integers(len(rows_a)))
    (key, sa, _), (_, sb, _) = rows_a[n], rows_b[n]
    q = int(np.random.randint(1, len(sa)))
    return with_string(a, key, sa[:q] + sb[q:]), with_string(b, key, sb[:q] + sa[q:])


@pytest.mark.parametrize("name,fn", [("head_tail_rotation", rotation_global_shift), ("crossover", crossover_global_cut)])
@pytest.mark.parametrize("seed", [11, 12, 13, 0, 1])
def test_a_global_generator_for_one_choice_is_caught(name, fn, seed):
    """Seeds 11 and 13 passed before (the repeated call crossed a 2-long PreHeader, whose cut is always 1); a
    pass now needs 9 repeats of a choice with at least 4 outcomes: probability below 4e-6."""
    j = evaluate(f"pictures.{name}", fn, seed=seed)
    assert {v.prop: v.passed for v in j.verdicts}["deterministic for a seed"] is False
    assert j.score < j.check.points


@pytest.mark.parametrize("name", NAMES[1:])
@pytest.mark.parametrize("seed", range(4))
def test_the_determinism_case_repeats_several_seeds_where_every_choice_has_several_outcomes(name, seed):
    case = next(c for c in checks.get(name).cases(np.random.default_rng(seed)) if c["id"] == "basic")
    distinct = list(dict.fromkeys(case["seeds"]))
    assert len(distinct) >= 3 and case["seeds"] == [s for s in distinct for _ in range(PG.REPEATS)] and PG.REPEATS >= 4
    for arg in case["args"][:-1]:
        for key, (chroms, h) in PG.rows(Genome.from_json(arg["json"])).items():
            assert h >= 5 and (key == "pre" or len(chroms) - h >= 5), (key, len(chroms), h)


# -- substitution reaches the PreHeader ----------------------------------------------------------------


@pytest.mark.parametrize("seed", range(6))
def test_a_correct_substitution_misses_the_preheader_with_probability_below_1e_6(seed):
    """A correct substitution picking the string uniformly (coursekit's own, the solution) or a chromosome
    uniformly over the genome must reach the PreHeader in some call: with the cases' genomes and seeds the
    chance that it never does is below 1e-6 for both (60 calls on the old cases: 1.5e-3 for the second)."""
    miss = {"string": 1.0, "chromosome": 1.0}
    for case in checks.get("pictures.substitution").cases(np.random.default_rng(seed)):
        rows = PG.rows(Genome.from_json(case["args"][0]["json"]))
        if "pre" not in rows:
            continue
        calls = len(set(case["seeds"]))  # a repeated seed makes the same choice
        miss["string"] *= (1 - 1 / len(rows)) ** calls
        miss["chromosome"] *= (1 - len(rows["pre"][0]) / sum(len(c) for c, _ in rows.values())) ** calls
    assert max(miss.values()) < 1e-6, miss

