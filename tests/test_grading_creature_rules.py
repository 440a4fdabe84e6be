"""Rules of exercise 05's checks set after an honest-student study (s26): answers that got an operator's
definition wrong kept 65-100 % of its points, because each rule of the definition counted as one property.

- each check has a *point* (its definition) that weighs half its points: an expansion's parts as the
  genotype implies them; a recombination's alternating LR blocks of random lengths, every taken node kept
  with its links; a mutation's deletions, additions and six modification steps, about one node a call,
  scaled by rate;
- a recombination's blocks alternate (a one-cut crossover kept 4/4);
- a mutation that breaks its input (a parent with a deleted node) costs "input unchanged", not every call;
- an expansion walks depth first, and the cap keeps the first parts of that walk (s27: a breadth-first
  expansion kept 4/4, its parts right but listed level by level).
"""

import json

import numpy as np
import pytest

from check_points import assert_a_point_weighs_half
from coursekit.creatures.phenotype import expand as library_expand
from coursekit.grading import checks, evaluate
from coursekit.grading.checks import Context, creature_expansion as expansion
from coursekit.grading.checks.ex05_creature_operators import CROSSOVER_POINT, MUTATE_POINT
from creature_answers import (BUGGY, CORRECT, SOL, as_cell, crossover_one_cut, expand_breadth_first,
                              expand_cap_keeps_shallow_parts, mutate_in_place)

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


DEPTH_FIRST = "walks depth first"


def test_a_breadth_first_expansion_loses_the_depth_first_order():
    """s27: a queue instead of the recursion got every part right (children, depths, scales, mirroring, the part
    count) and kept 4/4; only the order of the list, and so which parts the cap keeps, differed. Depth first
    weighs 2 of 16 (runs 1, part records 1, grows 1, parents first 1, depth first 2, the cap 2, the point 8):
    a detail, since the parts are right, which keeps 14/16 of the 4 points = 3.5."""
    check = checks.get("creatures.expand")
    weights = dict(check.weights)
    assert (weights[DEPTH_FIRST], 1 + sum(weights.get(p, 1) for p, _ in check.props)) == (2, 16)
    for seed in (0, 11):
        j = evaluate("creatures.expand", expand_breadth_first, seed=seed, timeout=60)
        failed = [v for v in j.verdicts if not v.passed]
        assert [v.prop for v in failed] == [DEPTH_FIRST], [(v.prop, v.message[:200]) for v in failed]
        assert "breadth first" in failed[0].message
        assert j.score == pytest.approx(4 * 14 / 16) and j.score < j.check.points


def test_a_cap_that_keeps_the_parts_nearest_the_root_loses_the_depth_first_order():
    """Listed depth first, but the cap keeps the body's first levels, not the first parts of the walk: judged on
    the student's own list (a part off the path to the last part has not all its children)."""
    j = evaluate("creatures.expand", expand_cap_keeps_shallow_parts, seed=11, timeout=60)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == [DEPTH_FIRST] and "first max_parts of the full walk" in failed[0].message
    assert j.score == pytest.approx(3.5)


@pytest.mark.parametrize("seed", [0, 11])
def test_the_solution_keeps_full_marks(seed):
    j = evaluate("creatures.expand", SOL["expand"], seed=seed, timeout=60)
    assert j.score == j.check.points == 4, [(v.prop, v.message[:200]) for v in j.verdicts if not v.passed]


def library_parts(creature, max_parts):
    """The library's expansion as ``node``, ``parent`` and ``depth`` of every part: its body tree without the
    massless frames of multi-DOF joints (a part reached through a link has depth 0, a recursive copy of
    its parent's node one more: links never point back to their own node)."""
    body = library_expand(creature, max_parts).body
    massless = body.massless if body.massless is not None else np.zeros(body.n_bodies, bool)
    real = [b for b in range(body.n_bodies) if not massless[b]]
    index = {b: k for k, b in enumerate(real)}
    parts = []
    for b in real:
        q = int(body.parent[b])
        while q >= 0 and massless[q]:
            q = int(body.parent[q])
        parent = index[q] if q >= 0 else -1
        node = int(body.node_id[b])
        same = parent >= 0 and parts[parent]["node"] == node
        parts.append({"node": node, "parent": parent, "depth": parts[parent]["depth"] + 1 if same else 0})
    return parts


@pytest.mark.parametrize("seed", [0, 11])
def test_the_library_expansion_walks_depth_first(seed):
    """The library's own expansion (coursekit.creatures.phenotype:expand, withheld from graded answers) holds
    depth first and every other property its body tree shows, on the grader's test inputs."""
    check = checks.get("creatures.expand")
    cases = check.cases(np.random.default_rng(seed))
    ctx = Context(cases, {})
    for cid in ctx.cases:
        parts = library_parts(ctx.arg(cid, 0), ctx.arg(cid, 1))
        ctx.records[cid] = {"status": "ok", "outputs": [json.dumps(parts)]}
    for prop in (expansion.depth_first, expansion.counts, expansion.depths, expansion.capped):
        ok, message = prop(ctx)
        assert ok, (prop.__name__, message)


def test_every_answer_can_stand_in_for_its_notebook_cell():
    """The study graded these answers in notebooks (the solution's with one cell replaced): each cell
    runs on the notebook's own names alone."""
    for name, fn, *_ in BUGGY + CORRECT:
        function = name.split(".")[1]
        namespace = dict(SOL)
        exec(as_cell(fn, function), namespace)
        assert namespace[function] is not SOL[function] and namespace[function].__name__ == function
