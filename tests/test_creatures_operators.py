"""Recombination, grafting and mutation (paper 2.2) and validity everywhere (issue item 6)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import ChildLink, Creature, Node, operators
from coursekit.creatures.body import MIN_HALF_EXTENT
from coursekit.creatures.brain import N_CONST
from coursekit.creatures.genotype import MAX_NODES, has_cycle, preorder
from coursekit.creatures.neural import N_SENSORS
from coursekit.creatures.phenotype import MAX_PARTS
from coursekit.profile import sized

seeds = st.integers(0, 2**32 - 1)


def assert_valid(c: Creature) -> None:
    """Every invariant the rest of the system relies on."""
    c.validate()  # field ranges, references in range, acyclic, all reachable
    n = len(c.nodes)
    assert 1 <= n <= MAX_NODES
    assert not has_cycle(c.nodes) and sorted(preorder(c.nodes)) == list(range(n))
    for node in c.nodes:
        assert all(0 <= k.child < n for k in node.children)
        assert {s.child for s in node.symmetry} <= {k.child for k in node.children}
    ph = c.expand()
    body = ph.body
    body.validate()
    assert 1 <= body.n_bodies <= MAX_PARTS
    assert body.half_extents.min() >= MIN_HALF_EXTENT
    assert np.all(body.limits[1:, 0] < 0) and np.all(body.limits[1:, 1] > 0)
    assert set(body.node_id.tolist()) <= set(range(n))
    brain = ph.brain
    assert np.all((brain.src >= 0) & (brain.src < brain.n_slots))
    assert np.all((brain.effector_src >= 0) & (brain.effector_src < brain.n_slots))
    assert np.all((brain.n_inputs >= 1) & (brain.n_inputs <= 3))
    # a neuron never reads a neuron slot past the end, and sensors land in the sensor block
    assert brain.n_slots == N_CONST + N_SENSORS * body.n_bodies + brain.n_neurons


@pytest.mark.slow
@settings(max_examples=sized(classroom=10_000, ci=2_500), deadline=None)  # CI: 2,500, the same ones each run
@given(seeds, st.integers(1, 10))
def test_thousands_of_random_genomes_are_valid(seed, size):
    c = Creature.random(np.random.default_rng(seed), n_nodes=(1, size), neurons=(0, 4))
    assert_valid(c)
    assert not c.expand().body.meta["truncated"]  # random creatures fit the cap whole


@settings(max_examples=100, deadline=None)
@given(seeds, st.integers(8, 30))
def test_random_respects_a_small_part_budget(seed, cap):
    c = Creature.random(np.random.default_rng(seed), n_nodes=(1, 8), max_parts=cap, p_recursion=0.8, p_symmetry=0.8)
    body = c.expand(max_parts=1000).body
    assert body.n_bodies <= cap and not body.meta["truncated"]


@settings(max_examples=60, deadline=None)
@given(seeds)
def test_long_operator_chains_stay_valid_and_never_modify_inputs(seed):
    rng = np.random.default_rng(seed)
    pop = [Creature.random(rng, n_nodes=(1, 6)) for _ in range(6)]
    for _ in range(40):
        i, j = rng.integers(len(pop), size=2)
        a, b = pop[i], pop[j]
        before = (a.to_json(), b.to_json())
        r = rng.random()
        if r < 0.4:
            child = operators.mutate(a, rng)
        elif r < 0.7:
            child = operators.crossover(a, b, rng)
        else:
            child = operators.graft(a, b, rng)
        assert (a.to_json(), b.to_json()) == before
        assert_valid(child)
        pop[int(rng.integers(len(pop)))] = child


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(seeds)
def test_heavy_mutation_chains_stay_valid(seed):
    """Rates far above normal: deletions, additions and re-pointing on every step."""
    rng = np.random.default_rng(seed)
    c = Creature.random(rng, n_nodes=(1, 8), neurons=(0, 4), brain_neurons=(0, 4))
    for _ in range(60):
        c = operators.mutate(c, rng, rate=6.0)
        assert_valid(c)


@pytest.mark.parametrize("op", ["mutate", "crossover", "graft"])
def test_operators_are_deterministic(op):
    a = Creature.random(np.random.default_rng(1), n_nodes=5)
    b = Creature.random(np.random.default_rng(2), n_nodes=5)
    f = getattr(operators, op)
    args = (a,) if op == "mutate" else (a, b)
    outs = [f(*args, np.random.default_rng(7)).to_json() for _ in range(2)]
    assert outs[0] == outs[1]


def test_mutate_with_rate_zero_is_identity_and_rejects_bad_rates():
    a = Creature.random(np.random.default_rng(3), n_nodes=5, neurons=(1, 3))
    assert operators.mutate(a, np.random.default_rng(0), rate=0.0) == a
    with pytest.raises(ValueError, match="mutate.rate"):
        operators.mutate(a, np.random.default_rng(0), rate=-1)
    with pytest.raises(TypeError, match="rng"):
        operators.mutate(a, 0)


def test_mutation_changes_something_on_average_whatever_the_size():
    """Rates scale with 1 / size (Sims), so a small and a large genome change at similar rates."""
    rng = np.random.default_rng(11)
    for n in (2, 10):
        c = Creature.random(np.random.default_rng(n), n_nodes=n)
        changed = [operators.mutate(c, rng) != c for _ in range(100)]
        assert 0.5 <= np.mean(changed) <= 1.0


# -------------------------------------------------------------------------- the paper's crossover


def _chain(n, tag):
    """A chain of ``n`` nodes (LR order = list order) whose x size encodes (parent, index)."""
    nodes = []
    for i in range(n):
        kids = [ChildLink(i + 1, (1.0, 0.0, 0.0))] if i + 1 < n else []
        nodes.append(Node(size=(tag + 0.01 * i, 0.1, 0.1), children=kids, effectors=[None]))
    return Creature(nodes)


def _source(c):
    """(parent 'a'/'b', original index) of every node."""
    out = []
    for node in c.nodes:
        x = node.size[0]
        out.append(("a", round((x - 0.1) / 0.01)) if x < 0.5 else ("b", round((x - 0.5) / 0.01)))
    return out


def _alternates(pattern, L):
    """True when ``pattern`` (source per position) is A^n B^m A^n ... for some n, m."""
    for n in range(1, L + 1):
        for m in range(1, L + 1):
            want, pos, first = [], 0, True
            while pos < L:
                span = n if first else m
                want += ["a" if first else "b"] * min(span, L - pos)
                pos += span
                first = not first
            if want == pattern:
                return True
    return False


@settings(max_examples=80, deadline=None)
@given(seeds)
def test_crossover_takes_alternating_blocks_at_the_same_positions(seed):
    rng = np.random.default_rng(seed)
    L = 7
    child = operators.crossover(_chain(L, 0.1), _chain(L, 0.5), rng)
    src = _source(child)
    assert len(child.nodes) == L
    assert [k for _, k in src] == list(range(L))  # every taken node kept its position
    assert _alternates([p for p, _ in src], L)
    # a child of position i stays the child of position i (a leg stays a leg)
    for i, node in enumerate(child.nodes[:-1]):
        assert [k.child for k in node.children] == [i + 1]


@settings(max_examples=80, deadline=None)
@given(seeds, st.integers(1, 8), st.integers(1, 8))
def test_crossover_unequal_parents_keeps_every_taken_node(seed, la, lb):
    rng = np.random.default_rng(seed)
    child = operators.crossover(_chain(la, 0.1), _chain(lb, 0.5), rng)
    assert_valid(child)
    src = _source(child)
    assert src[0] == ("a", 0)  # the root comes from the first parent
    positions = [k for _, k in src]
    assert len(set(positions)) == len(positions)  # no position taken twice
    # both parents' nodes are taken only at positions they had, never both at one position
    for p, k in src:
        assert k < (la if p == "a" else lb)


def test_crossover_repair_redraws_dangling_brain_references():
    a = Creature.random(np.random.default_rng(4), n_nodes=4, neurons=(2, 3), brain_neurons=(0, 0))
    b = Creature.random(np.random.default_rng(5), n_nodes=4, neurons=(2, 3), brain_neurons=(3, 3))
    for s in range(20):
        child = operators.crossover(a, b, np.random.default_rng(s))
        assert_valid(child)
        assert child.brain == a.brain


# ------------------------------------------------------------------------------------- grafting


@settings(max_examples=60, deadline=None)
@given(seeds, st.integers(1, 6), st.integers(1, 6))
def test_graft_appends_a_subgraph_of_the_second_parent(seed, la, lb):
    rng = np.random.default_rng(seed)
    child = operators.graft(_chain(la, 0.1), _chain(lb, 0.5), rng)
    assert_valid(child)
    src = _source(child)
    a_part = [k for p, k in src if p == "a"]
    b_part = [k for p, k in src if p == "b"]
    assert a_part == list(range(len(a_part))) and a_part[0] == 0  # a prefix of a's chain
    assert b_part and b_part == list(range(b_part[0], lb))  # a whole subgraph (a suffix) of b


def test_deleting_every_node_removes_every_reference():
    c = Creature.random(np.random.default_rng(8), n_nodes=6)
    out = operators.mutate(c, np.random.default_rng(0), p_delete=10.0, p_add=0.0, p_modify=0.0, p_link=0.0, p_neural=0.0)
    assert len(out.nodes) == 1  # only the root survives (it cannot be deleted)
    assert out.nodes[0].children == [] and out.nodes[0].symmetry == []
    assert_valid(out)


@pytest.mark.parametrize("k, fields", [
    (0, {"joint_axis", "joint_pos", "joint_type", "limits"}),  # 1. joint axis and position
    (1, {"size"}),  # 2. body size
    (2, {"limits"}),  # 3. mobility
    (3, {"force"}),  # 4. force coefficient
    (4, {"recursion", "recursive_limit"}),  # 5. recursion
    (5, {"symmetry"}),  # 6. symmetry
])
def test_each_modification_step_touches_only_its_attributes(k, fields):
    """The paper's six modification steps (2.2.2), each drawing from the predefined lists."""
    from coursekit.creatures.genotype import AXES, SIZES

    step = operators.MODIFY_STEPS[k]
    rng = np.random.default_rng(k)
    changed = set()
    for seed in range(40):
        c = Creature.random(np.random.default_rng(seed), n_nodes=(2, 4), p_symmetry=0.5)
        node = c.copy().nodes[0]
        step(node, rng)
        before, after = c.nodes[0].to_dict(), node.to_dict()
        diff = {f for f in before if before[f] != after[f]}
        assert diff <= fields, (diff, fields)
        changed |= diff
        assert set(node.size) <= set(SIZES) or k != 1
        assert tuple(node.joint_axis) in AXES or k != 0
        nodes = c.copy().nodes
        nodes[0] = node
        assert_valid(Creature(nodes, c.brain))
    assert changed  # the step does change things
