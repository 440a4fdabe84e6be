"""Rules of exercise 05's checks set after an honest-student study (s26): answers that got an operator's
definition wrong kept 65-100 % of its points, because each rule of the definition counted as one property.

- each check has a *point* (its definition) that weighs half its points: an expansion's parts as the
  genotype implies them; a recombination's alternating LR blocks of random lengths, every taken node kept
  with its links; a mutation's deletions, additions and six modification steps, about one node a call,
  scaled by rate;
- a recombination's blocks alternate (a one-cut crossover kept 4/4);
- a mutation that breaks its input (a parent with a deleted node) costs "input unchanged", not every call;
- an expansion walks depth first, and the cap keeps the first parts of that walk (s27: a breadth-first
  expansion kept 4/4, its parts right but listed level by level);
- one part's children come in the exercise's order: each link's child with its mirrored twins, the recursion
  copies last (s27: an expansion that grew the recursion copies first kept 4/4, and other parts under the cap).
"""

import json

import numpy as np
import pytest

from check_points import assert_a_point_weighs_half
from coursekit.creatures.phenotype import expand as library_expand
from coursekit.grading import checks, evaluate
from coursekit.creatures import Creature
from coursekit.grading.checks import Context, creature_expansion as expansion
from coursekit.grading.checks.creature_cases import obj
from coursekit.grading.checks.ex05_creature_operators import CHILD_ORDER, CROSSOVER_POINT, MUTATE_POINT
from creature_answers import (BUGGY, CORRECT, SOL, as_cell, crossover_one_cut, expand_breadth_first,
                              expand_cap_keeps_shallow_parts, expand_recursion_first, expand_twin_first,
                              mutate_in_place)

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
    weighs 2 of 18 (runs 1, part records 1, grows 1, parents first 1, depth first 2, the children's order 1,
    the cap 2, the point 9): a detail, since the parts are right, which keeps 16/18 of the 4 points = 3.56."""
    check = checks.get("creatures.expand")
    weights = dict(check.weights)
    assert (weights[DEPTH_FIRST], 1 + sum(weights.get(p, 1) for p, _ in check.props)) == (2, 18)
    for seed in (0, 11):
        j = evaluate("creatures.expand", expand_breadth_first, seed=seed, timeout=60)
        failed = [v for v in j.verdicts if not v.passed]
        assert [v.prop for v in failed] == [DEPTH_FIRST], [(v.prop, v.message[:200]) for v in failed]
        assert "breadth first" in failed[0].message
        assert j.score == pytest.approx(4 * 16 / 18, abs=1e-4) and j.score < j.check.points


def test_a_cap_that_keeps_the_parts_nearest_the_root_loses_the_depth_first_order():
    """Listed depth first, but the cap keeps the body's first levels, not the first parts of the walk: judged on
    the student's own list (a part off the path to the last part has not all its children)."""
    j = evaluate("creatures.expand", expand_cap_keeps_shallow_parts, seed=11, timeout=60)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == [DEPTH_FIRST] and "first max_parts of the full walk" in failed[0].message
    assert j.score == pytest.approx(4 * 16 / 18, abs=1e-4)


@pytest.mark.parametrize("fn", [expand_recursion_first, expand_twin_first], ids=lambda fn: fn.__name__)
@pytest.mark.parametrize("seed", [0, 11])
def test_children_in_another_order_lose_only_the_childrens_order(fn, seed):
    """s27: depth first with every part right, but a part's recursion copies grown before its links' children
    (or a link's twins before its own child), kept 4/4. The order of one part's children weighs 1 of 18, the
    smallest share: 17/18 of the 4 points."""
    check = checks.get("creatures.expand")
    assert (dict(check.weights).get(CHILD_ORDER, 1), 1 + sum(dict(check.weights).get(p, 1) for p, _ in check.props)) == (1, 18)
    j = evaluate("creatures.expand", fn, seed=seed, timeout=60)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == [CHILD_ORDER], [(v.prop, v.message[:200]) for v in failed]
    message = failed[0].message
    assert "lists its children as part" in message and "in the exercise's order the same children come as" in message
    assert ("recursion copy" if fn is expand_recursion_first else "mirrored") in message
    assert j.score == pytest.approx(4 * 17 / 18, abs=1e-4)


def snake_with_legs_everywhere():
    """Figure 1's snake of 2 segments whose leg link is not terminal-only: the first segment has a leg, its
    mirrored twin and a recursive copy (that order), the copy a leg and its twin: 6 parts."""
    c = Creature.figure1_snake(2)
    c.nodes[0].children[0].terminal_only = False
    c.validate()
    assert expansion.full_count(c) == 6
    return c


def order_verdict(expand, max_parts):
    c = snake_with_legs_everywhere()
    cases = [{"id": cid, "args": [obj(c), max_parts], "seeds": [0]} for cid in expansion.CASES]
    ctx = Context(cases, {cid: {"status": "ok", "outputs": [json.dumps(expand(c, max_parts))]} for cid in expansion.CASES})
    return expansion.children_in_order(ctx)


def test_under_the_cap_the_children_listed_are_judged_by_their_order_alone():
    """With max_parts 3 the exercise keeps the first segment and its two legs; recursion first keeps the segment,
    its copy and one leg of the copy. The first segment then lists the copy alone, which looks the same as a
    segment whose node makes no legs (a count, not an order): not judged here. All 6 parts show the order."""
    assert [p["node"] for p in SOL["expand"](snake_with_legs_everywhere(), 3)] == [0, 1, 1]
    assert [p["node"] for p in expand_recursion_first(snake_with_legs_everywhere(), 3)] == [0, 0, 1]
    assert order_verdict(SOL["expand"], 3)[0] and order_verdict(SOL["expand"], 6)[0]
    assert order_verdict(expand_recursion_first, 3)[0]
    ok, message = order_verdict(expand_recursion_first, 6)
    assert not ok and "part 0 (node 0, recursion depth 0) lists its children as part 1: recursion copy" in message
    assert "in the exercise's order the same children come as node 1, node 1 mirrored, recursion copy" in message
    ok, message = order_verdict(expand_twin_first, 5)  # cut short in the copy's twin legs: the root is complete
    assert not ok and "lists its children as part 1: node 1 mirrored, part 2: node 1, part 3: recursion copy" in message


def test_children_that_are_not_the_ones_the_node_implies_are_left_to_the_point():
    """A twin on the wrong side or a terminal-only link followed everywhere fails the point, not the order too."""
    for fn in (a for name, a, kind in BUGGY if kind == "point" and name == "creatures.expand"):
        j = evaluate("creatures.expand", fn, seed=11, timeout=60)
        assert CHILD_ORDER in {v.prop for v in j.verdicts if v.passed}, fn.__name__


@pytest.mark.parametrize("seed", [0, 11])
def test_the_solution_keeps_full_marks(seed):
    j = evaluate("creatures.expand", SOL["expand"], seed=seed, timeout=60)
    assert j.score == j.check.points == 4, [(v.prop, v.message[:200]) for v in j.verdicts if not v.passed]


def library_parts(creature, max_parts):
    """The library's expansion as ``node``, ``parent``, ``depth``, ``mirrored`` and ``gain`` of every part: its
    body tree without the massless frames of multi-DOF joints (a part reached through a link has depth 0, a
    recursive copy of its parent's node one more: links never point back to their own node). ``mirrored`` is
    read off the gain's sign, so it is right only where every non-root node's force is negative
    (:func:`negative_forces`)."""
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
        parts.append({"node": node, "parent": parent, "depth": parts[parent]["depth"] + 1 if same else 0,
                      "mirrored": bool(parent >= 0 and body.gain[b] < 0), "gain": float(body.gain[b])})
    return parts


def negative_forces(creature):
    """``creature`` with every force negative: the library's gain is then negative exactly on mirrored parts."""
    for node in creature.nodes:
        node.force = -abs(node.force)
    return creature


@pytest.mark.parametrize("seed", [0, 11])
def test_the_library_expansion_walks_depth_first(seed):
    """The library's own expansion (coursekit.creatures.phenotype:expand, withheld from graded answers) holds
    depth first, its children's order and every other property its body tree shows, on the grader's test inputs
    (with negative forces: the gain's sign shows mirroring)."""
    check = checks.get("creatures.expand")
    cases = check.cases(np.random.default_rng(seed))
    for case in cases:
        case["args"][0] = obj(negative_forces(Creature.from_json(case["args"][0]["json"])))
    ctx = Context(cases, {})
    for cid in ctx.cases:
        parts = library_parts(ctx.arg(cid, 0), ctx.arg(cid, 1))
        ctx.records[cid] = {"status": "ok", "outputs": [json.dumps(parts)]}
    for prop in (expansion.depth_first, expansion.children_in_order, expansion.counts, expansion.depths,
                 expansion.mirrors, expansion.capped):
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
