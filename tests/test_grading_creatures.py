"""Checks of exercise 05 (creature expansion, LR recombination, mutation), without kernels.

Two independent correct implementations of each function get full marks (the solution
notebook's, and a second one: an iterative expansion written here, the library's
``operators.crossover`` and ``operators.mutate``); known-wrong implementations fail the property
they violate; the check's own independent part count agrees with the library's expansion and
with the paper's Figure 1.
"""

import copy

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, operators
from coursekit.creatures.genotype import preorder, random_link, random_node, renumber
from coursekit.grading import checks, evaluate
from coursekit.grading.checks import creature_expansion as cc
from coursekit.grading.checks.ex05_creature_operators import CROSSOVER_POINT, EXPAND_POINT, MUTATE_POINT
from creature_answers import crossover_orphans_dropped as crossover_drops_orphans, take_blocks
from solution_cells import solution_functions

NAMES = ["creatures.expand", "creatures.crossover", "creatures.mutate"]


SOL = solution_functions("05_creature_operators.ipynb", imports=True)


def test_the_solution_cells_were_found():
    assert all(callable(SOL.get(f)) for f in ("expand", "crossover", "mutate", "mutate_symmetry"))


# -- a second, independent expansion: explicit stack, records built from a configurable rule set --


def make_expand(*, symmetry=True, terminal_only=True, reset_depth=True, multiply_scale=True, inherit_mirror=True,
                signed_gain=True, cap_offset=0, cap=True, as_tuples=False, reverse=False):
    """An iterative depth-first expansion; each flag switched off breaks one rule on purpose."""

    def expand(creature, max_parts=64):
        nodes = creature.nodes
        parts = []
        stack = [(0, -1, 0, 1.0, False)]
        limit = max_parts + cap_offset if cap else 10**9
        while stack and len(parts) < limit:
            node_id, parent, depth, scale, mirrored = stack.pop()
            node = nodes[node_id]
            me = len(parts)
            gain = node.force if (mirrored and signed_gain) else abs(node.force)
            parts.append({"node": node_id, "parent": parent, "depth": depth, "scale": scale, "mirrored": mirrored,
                          "gain": gain})
            terminal = depth >= node.recursive_limit or not node.recursion
            kids = []
            for link in node.children:
                if terminal_only and link.terminal_only and not terminal:
                    continue
                base = mirrored if inherit_mirror else False
                flip = link.reflect >= 0
                d = 0 if reset_depth else depth
                s = scale * link.scale if multiply_scale else link.scale
                kids.append((link.child, me, d, s, base ^ flip))
                if symmetry:
                    kids += [(link.child, me, d, s, base ^ (not flip)) for t in node.symmetry if t.child == link.child]
            if not terminal:
                kids += [(node_id, me, depth + 1, scale * r.scale, mirrored) for r in node.recursion]
            stack.extend(reversed(kids))
        if reverse:  # children listed before their parents
            n = len(parts)
            parts = [dict(p, parent=(n - 1 - p["parent"]) if p["parent"] >= 0 else -1) for p in reversed(parts)]
        if as_tuples:
            return [tuple(p.values()) for p in parts]
        return parts

    return expand


OTHERS = {"creatures.expand": make_expand(), "creatures.crossover": operators.crossover,
          "creatures.mutate": operators.mutate}


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("seed", [0, 1])
def test_correct_implementations_get_full_marks(name, seed):
    for fn in (SOL[name.split(".")[1]], OTHERS[name]):
        j = evaluate(name, fn, seed=seed, timeout=30)
        assert j.passed and j.score == j.check.points, [v for v in j.verdicts if not v.passed]


# -- the check's independent counting agrees with the library and with the paper ----------------------


@pytest.mark.parametrize("segments", [1, 2, 3, 4, 5])
def test_figure1_snake_count_from_the_paper(segments):
    # Figure 1: the segment repeats (segments - 1) times; the two legs hang on the last one only.
    snake = Creature.figure1_snake(segments)
    assert cc.full_count(snake) == segments + 2
    assert snake.expand().body.n_bodies == segments + 2


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_recursion_formula_and_mirror_rule_match_the_library_expansion(seed):
    rng = np.random.default_rng(seed)
    c = Creature.random(rng, n_nodes=(1, 7), p_recursion=0.7, p_symmetry=0.7, max_parts=200)
    links = [lk for n in c.nodes for lk in n.children]
    if links:
        links[int(rng.integers(len(links)))].reflect = int(rng.integers(-1, 3))
    for node in c.nodes[1:]:  # negative forces: the library's gain is negative exactly on mirrored parts
        node.force = -abs(node.force)
    ph = c.expand(max_parts=200)
    assert not ph.body.meta["truncated"]
    assert cc.full_count(c) == ph.body.n_bodies
    node_id, parent = ph.body.node_id.tolist(), ph.body.parent.tolist()
    mirrored = (ph.body.gain < 0).tolist()
    depth = [0] * len(node_id)
    for b in range(1, len(node_id)):
        depth[b] = depth[parent[b]] + 1 if node_id[b] == node_id[parent[b]] else 0
    for b, kids in enumerate(ph.children):  # in relative-id order: the check's order of one part's children
        want = cc._expected_children(c.nodes[node_id[b]], node_id[b], depth[b])
        assert [(node_id[k], mirrored[k] != mirrored[b]) for k in kids] == want


def test_cases_are_deterministic_valid_creatures():
    for name in NAMES:
        check = checks.get(name)
        a, b = check.cases(np.random.default_rng(3)), check.cases(np.random.default_rng(3))
        assert a == b
        for case in a:
            for arg in case["args"]:
                if isinstance(arg, dict) and "object" in arg:
                    Creature.from_json(arg["json"])  # validates


# -- known-wrong implementations fail the property they violate -------------------------------------


def _sol(name):
    return SOL[name]


def crossover_always_a(a, b, rng):
    return a.copy()


def crossover_fixed_blocks(a, b, rng):
    class One:  # n = m = 1 every time; the rest of the solution unchanged
        def integers(self, lo, hi=None, size=None):
            return np.ones(size, dtype=int) if size is not None else rng.integers(lo, hi)

        def __getattr__(self, k):
            return getattr(rng, k)

    return _sol("crossover")(a, b, One())


def crossover_shifted(a, b, rng):
    """b's blocks are taken from b's first positions instead of the positions they fill."""
    n = int(rng.integers(1, len(a.nodes) + 1))
    nodes = [copy.deepcopy(x) for x in a.nodes[:n]] + [copy.deepcopy(x) for x in b.nodes[: max(len(b.nodes) - n, 0)]]
    for i, node in enumerate(nodes):
        node.children = [lk for lk in node.children if lk.child < len(nodes) and lk.child > i]
        node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    for i in range(1, len(nodes)):
        if not any(lk.child == i for nd in nodes[:i] for lk in nd.children):
            host = next((h for h in range(i) if len(nodes[h].children) < 4), 0)
            nodes[host].children.append(random_link(rng, i, nodes[host], nodes[i]))
    return Creature(renumber(nodes), copy.deepcopy(a.brain))


def crossover_keeps_loops(a, b, rng):
    """The solution without removing the links that close a cycle (a student's walk: 4/4 before the
    grader's parents could close one); orphans still join where they close none."""
    pa, pb = [a.nodes[i] for i in preorder(a.nodes)], [b.nodes[i] for i in preorder(b.nodes)]
    L = max(len(pa), len(pb))
    n, m = (int(v) for v in rng.integers(1, L + 1, size=2))
    slots = take_blocks(pa, pb, n, m)
    for node in slots:
        if node is not None:
            node.children = [lk for lk in node.children if slots[lk.child] is not None]
            node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
    while True:
        reach = set(preorder(slots))
        orphans = [i for i, node in enumerate(slots) if node is not None and i not in reach]
        if not orphans:
            return Creature(renumber(slots), copy.deepcopy(a.brain))
        i = orphans[0]
        hosts = sorted(h for h in reach if len(slots[h].children) < 4 and not SOL["reaches"](slots, i, h))
        host = hosts[int(rng.integers(len(hosts)))]
        slots[host].children.append(random_link(rng, i, slots[host], slots[i]))


def test_a_crossover_that_keeps_links_closing_a_loop_fails_only_for_parents_that_can_close_one():
    j = evaluate("creatures.crossover", crossover_keeps_loops, seed=1, timeout=30)
    failed = [v for v in j.verdicts if not v.passed]
    assert {v.prop for v in failed} == {"runs", "the repair leaves no loop"}, [(v.prop, v.message[:200]) for v in failed]
    assert "cycle" in failed[-1].message and j.score <= 0.8 * j.check.points


def crossover_changes_links(a, b, rng):
    child = _sol("crossover")(a, b, rng)
    for node in child.nodes:
        for lk in node.children:
            lk.terminal_only = not lk.terminal_only
    return child


def crossover_global_rng(a, b, rng):
    return _sol("crossover")(a, b, np.random.default_rng())


def crossover_modifies_a(a, b, rng):
    child = _sol("crossover")(a, b, rng)
    a.nodes[0].force = -a.nodes[0].force
    return child


def crossover_invalid(a, b, rng):
    return {"nodes": [], "brain": []}


def make_mutate(*, scale_by_size=True, use_rate=True, steps=None, deepcopy=True, global_rng=False, off_list=False,
                change=True):
    """The solution's mutate with one rule broken on purpose."""

    def mutate(c, rng, rate=1.0):
        if global_rng:
            rng = np.random.default_rng()
        if not change:
            return c.copy()
        nodes = copy.deepcopy(c.nodes) if deepcopy else c.nodes
        r_ = rate if use_rate else 1.0
        p = r_ / len(nodes) if scale_by_size else r_
        for i in range(len(nodes)):
            node = nodes[i]
            r = rng.random()
            if i > 0 and r < 0.2 * p:
                nodes[i] = None
            elif r < 0.5 * p and len(node.children) < 4 and len(nodes) < 24:
                new = random_node(rng)
                nodes.append(new)
                node.children.append(random_link(rng, len(nodes) - 1, node, new))
            elif r < 1.5 * p:
                SOL["pick"](rng, steps or SOL["STEPS"])(node, rng)
                if off_list:
                    node.size = tuple(min(s * 1.01, 1.0) for s in node.size)
        for node in nodes:
            if node is not None:
                node.children = [lk for lk in node.children if nodes[lk.child] is not None]
                node.symmetry = [s for s in node.symmetry if any(lk.child == s.child for lk in node.children)]
        return Creature(renumber(nodes), copy.deepcopy(c.brain))

    return mutate


def mutate_size_anywhere(node, rng):
    """Step 2 with a random size from SIZES, not a neighbouring one (a student's walk, s25: not checked)."""
    size = list(node.size)
    size[int(rng.integers(3))] = SOL["pick"](rng, SOL["SIZES"])
    node.size = tuple(size)


def link_scale_off_list(c, rng, rate=1.0):
    child = _sol("mutate")(c, rng, rate)
    for node in child.nodes:
        for lk in node.children:
            lk.scale = 1.05  # inside the valid range, not in SCALES
    return child


WRONG = [
    ("creatures.expand", make_expand(as_tuples=True), "returns a list of part records"),
    ("creatures.expand", make_expand(reverse=True), "parents precede children"),
    ("creatures.expand", make_expand(symmetry=False), EXPAND_POINT),
    ("creatures.expand", make_expand(terminal_only=False), EXPAND_POINT),
    ("creatures.expand", make_expand(reset_depth=False), EXPAND_POINT),
    ("creatures.expand", make_expand(multiply_scale=False), EXPAND_POINT),
    ("creatures.expand", make_expand(inherit_mirror=False), EXPAND_POINT),
    ("creatures.expand", make_expand(signed_gain=False), EXPAND_POINT),
    ("creatures.expand", make_expand(cap=False), "part cap respected"),
    ("creatures.expand", make_expand(cap_offset=-1), "part cap respected"),
    ("creatures.crossover", crossover_invalid, "returns a valid creature"),
    ("creatures.crossover", crossover_shifted, CROSSOVER_POINT),
    ("creatures.crossover", crossover_drops_orphans, CROSSOVER_POINT),
    ("creatures.crossover", crossover_changes_links, CROSSOVER_POINT),
    ("creatures.crossover", crossover_always_a, CROSSOVER_POINT),
    ("creatures.crossover", crossover_fixed_blocks, CROSSOVER_POINT),
    ("creatures.crossover", crossover_keeps_loops, "the repair leaves no loop"),
    ("creatures.crossover", crossover_global_rng, "deterministic for a seed"),
    ("creatures.crossover", crossover_modifies_a, "inputs unchanged"),
    ("creatures.mutate", make_mutate(off_list=True), "values from the predefined lists"),
    ("creatures.mutate", link_scale_off_list, "values from the predefined lists"),
    ("creatures.mutate", make_mutate(change=False), MUTATE_POINT),
    ("creatures.mutate", make_mutate(scale_by_size=False), MUTATE_POINT),
    ("creatures.mutate", make_mutate(use_rate=False), MUTATE_POINT),
    ("creatures.mutate", make_mutate(steps=(lambda n, r: None,) * 5 + (SOL["mutate_symmetry"],)),
     MUTATE_POINT),
    ("creatures.mutate", make_mutate(steps=tuple(s if s.__name__ != "mutate_size" else mutate_size_anywhere
                                                  for s in SOL["STEPS"])), "a size moves to a neighbouring value"),
    ("creatures.mutate", make_mutate(global_rng=True), "deterministic for a seed"),
    ("creatures.mutate", make_mutate(deepcopy=False), "input unchanged"),
]
WRONG_IDS = [f"{name.split('.')[1]}-{getattr(fn, '__name__', 'fn')}-{k}" for k, (name, fn, _) in enumerate(WRONG)]


@pytest.mark.parametrize("name,fn,prop", WRONG, ids=WRONG_IDS)
def test_wrong_implementations_fail_the_violated_property(name, fn, prop):
    j = evaluate(name, fn, timeout=30)
    failed = {v.prop for v in j.verdicts if not v.passed}
    assert prop in failed, j.verdicts
    assert j.score < j.check.points


@pytest.mark.parametrize("name, fn, at_most", [
    ("creatures.expand", make_expand(multiply_scale=False), 0.86),
    ("creatures.expand", make_expand(inherit_mirror=False), 0.86),
    ("creatures.expand", make_expand(terminal_only=False), 0.75),
    ("creatures.crossover", crossover_drops_orphans, 0.88),
    ("creatures.crossover", crossover_fixed_blocks, 0.77),
    ("creatures.mutate", make_mutate(use_rate=False), 0.88),
    ("creatures.mutate", make_mutate(scale_by_size=False), 0.88),
])
def test_a_broken_rule_of_the_definition_costs_more_than_a_detail(name, fn, at_most):
    """s25, an honest-student study: these kept 91-92 % when every rule but the operator's point counted 1
    (and the operator's point, weighed against more rules, must not lose its share)."""
    j = evaluate(name, fn, timeout=30)
    assert j.score <= at_most * j.check.points, (j.score, [v.prop for v in j.verdicts if not v.passed])


def test_a_random_size_fails_only_the_neighbouring_size_rule():
    j = evaluate("creatures.mutate", make_mutate(steps=tuple(s if s.__name__ != "mutate_size" else mutate_size_anywhere
                                                              for s in SOL["STEPS"])), timeout=30)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == ["a size moves to a neighbouring value"] and "jumped" in failed[0].message


def test_a_single_broken_rule_costs_only_its_properties():
    j = evaluate("creatures.expand", make_expand(multiply_scale=False))
    assert {v.prop for v in j.verdicts if not v.passed} == {EXPAND_POINT}
    j = evaluate("creatures.crossover", crossover_changes_links, timeout=30)
    assert {v.prop for v in j.verdicts if not v.passed} == {CROSSOVER_POINT}


def test_messages_name_the_rule_not_the_answer():
    j = evaluate("creatures.expand", make_expand(symmetry=False))
    msg = next(v.message for v in j.verdicts if not v.passed)
    assert "children made from node" in msg and "symmetry copies" in msg and "def " not in msg
    j = evaluate("creatures.mutate", make_mutate(off_list=True), timeout=30)
    msg = next(v.message for v in j.verdicts if not v.passed)
    assert "sizes come from [0.025, 0.04" in msg and "def " not in msg
