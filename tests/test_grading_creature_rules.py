"""Rules of exercise 05's checks set after an honest-student study (s26): answers that got an operator's
definition wrong kept 65-100 % of its points, because each rule of the definition counted as one property.

- each check has a *point* (its definition) that weighs half its points: an expansion's parts as the
  genotype implies them; a recombination's alternating LR blocks of random lengths, every taken node kept
  with its links; a mutation's deletions, additions and six modification steps, about one node a call,
  scaled by rate;
- a recombination's blocks alternate (a one-cut crossover kept 4/4);
- a mutation that breaks its input (a parent with a deleted node) costs "input unchanged", not every call.
"""

import pytest

from check_points import assert_a_point_weighs_half
from coursekit.grading import evaluate
from coursekit.grading.checks.ex05_creature_operators import CROSSOVER_POINT, MUTATE_POINT
from creature_answers import BUGGY, CORRECT, SOL, as_cell, crossover_one_cut, mutate_in_place

NAMES = ["creatures.expand", "creatures.crossover", "creatures.mutate"]


@pytest.mark.parametrize("name", NAMES)
def test_every_check_has_a_point_weighing_half(name):
    assert_a_point_weighs_half(name)


POINT_BUGS = [(name, fn) for name, fn, kind in BUGGY if kind == "point"]
DETAIL_BUGS = [(name, fn) for name, fn, kind in BUGGY if kind == "detail"]


@pytest.mark.parametrize("name,fn", POINT_BUGS, ids=[fn.__name__ for _, fn in POINT_BUGS])
def test_getting_the_definition_wrong_keeps_at_most_half(name, fn):
    j = evaluate(name, fn, seed=11, timeout=60)
    assert j.score <= j.check.points / 2, [(v.prop, v.passed, v.message[:120]) for v in j.verdicts]


@pytest.mark.parametrize("name,fn", DETAIL_BUGS, ids=[fn.__name__ for _, fn in DETAIL_BUGS])
def test_a_detail_wrong_keeps_more_than_half(name, fn):
    j = evaluate(name, fn, seed=11, timeout=60)
    assert j.check.points / 2 < j.score < j.check.points, [(v.prop, v.passed) for v in j.verdicts]


@pytest.mark.parametrize("seed", [0, 11])
@pytest.mark.parametrize("name,fn", CORRECT, ids=[fn.__name__ for _, fn in CORRECT])
def test_correct_answers_that_differ_from_the_solution_keep_full_marks(name, fn, seed):
    j = evaluate(name, fn, seed=seed, timeout=60)
    assert j.score == j.check.points, [(v.prop, v.message[:200]) for v in j.verdicts if not v.passed]


def test_a_crossover_with_one_cut_is_told_that_the_blocks_alternate():
    j = evaluate("creatures.crossover", crossover_one_cut, seed=11, timeout=60)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == [CROSSOVER_POINT]
    assert "alternate" in failed[0].message and "n from a again" in failed[0].message


def test_a_mutation_that_breaks_its_parent_loses_only_input_unchanged():
    """Deleting a node of the parent itself leaves None among its nodes, which no longer serialises: that
    stopped the graded process on every call (0/4, "exited with status 0 (os._exit?)") before."""
    j = evaluate("creatures.mutate", mutate_in_place, seed=11, timeout=60)
    assert [v.prop for v in j.verdicts if not v.passed] == ["input unchanged"], j.verdicts
    assert MUTATE_POINT in {v.prop for v in j.verdicts if v.passed}


def test_every_answer_can_stand_in_for_its_notebook_cell():
    """The study graded these answers in notebooks (the solution's with one cell replaced): each cell
    runs on the notebook's own names alone."""
    for name, fn, *_ in BUGGY + CORRECT:
        function = name.split(".")[1]
        namespace = dict(SOL)
        exec(as_cell(fn, function), namespace)
        assert namespace[function] is not SOL[function] and namespace[function].__name__ == function
