"""Exercise 06 checks (resolve relative ids, wire the snake), without kernels.

The solution passes every property; one known-wrong implementation per property fails exactly
that property (or, for a gate, scores 0 with nothing after it judged). The grader's reference
rule for relative ids is cross-checked against the library's expansion on random creatures.
"""


import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, Input, Neuron
from coursekit.creatures.brain import N_CONST
from coursekit.creatures.neural import N_SENSORS
from coursekit.grading import evaluate
from coursekit.grading.checks import for_notebook, get
from coursekit.grading.checks.ex06_wire_a_brain import expected_target
from solution_cells import solution_functions



SOL = {}
exec("from coursekit.creatures import Creature, Input, Neuron\nfrom coursekit.creatures.neural import N_SENSORS", SOL)
solution_functions("06_wire_a_brain.ipynb", SOL)


def verdicts(name, fn):
    j = evaluate(name, fn, timeout=60)
    return j, {v.prop: v.passed for v in j.verdicts}


def test_the_exercise_is_registered_with_both_checks():
    assert [c.name for c in for_notebook("06_wire_a_brain")] == ["brains.resolve", "brains.wire_snake"]


@pytest.mark.parametrize("name, fn", [("brains.resolve", "resolve"), ("brains.wire_snake", "wire_snake")])
def test_the_solution_gets_full_marks(name, fn):
    j, _ = verdicts(name, SOL[fn])
    assert j.score == get(name).points and j.passed, [(v.prop, v.message) for v in j.verdicts]


def _resolve_wrong(kind):
    def resolve(morph, part, parent, children):
        right = SOL["resolve"](morph, part, parent, children)
        if kind == "zero_based" and morph >= 1:
            return children[part][morph] if morph < len(children[part]) else None
        if kind == "self_as_none" and morph == 0:
            return None
        if kind == "brain_as_root" and morph == -2:
            return 0
        if kind == "root_parent_minus_one" and morph == -1 and parent[part] < 0:
            return -1
        if kind == "missing_child_clamped" and morph >= 1 and morph > len(children[part]):
            return children[part][-1] if children[part] else None
        return right
    return resolve


@pytest.mark.parametrize("kind, prop", [
    ("self_as_none", "0 names the part's own network"),
    ("brain_as_root", "-2 names the brain"),
    ("missing_child_clamped", "a missing child reads nothing"),
])
def test_one_wrong_rule_fails_exactly_its_property(kind, prop):
    j, v = verdicts("brains.resolve", _resolve_wrong(kind))
    assert [p for p, ok in v.items() if not ok] == [prop] and 0 < j.score < get("brains.resolve").points


def test_an_index_outside_the_tree_fails_validity_and_a_zero_based_child_fails_the_job():
    j, v = verdicts("brains.resolve", _resolve_wrong("root_parent_minus_one"))
    assert not v["returns a part index, 'brain' or None"] and j.score == 0
    j, v = verdicts("brains.resolve", _resolve_wrong("zero_based"))
    assert v["returns a part index, 'brain' or None"] and not v["parent and child ids follow the tree"] and j.score == 0


def _wire(phase=-1.5, legs=True, only_segments=None, in_place=False, alternate=False):
    def wire_snake(snake):
        if only_segments is not None and snake.nodes[0].recursive_limit != only_segments - 1:
            return snake.copy()
        wired = SOL["wire_snake"](snake)
        wired.nodes[0].neurons[0].inputs[1].weight = phase
        if alternate:  # phase = 1.5 - parent's phase: 0, 1.5, 0, 1.5 ... (it swims a little, with no wave)
            wired.nodes[0].neurons[0] = Neuron("sum", [Input(-1, N_SENSORS, -1.0), Input(None, 0, 1.5)])
        if not legs:
            wired.nodes[1].effectors = [None]
        if in_place:
            snake.nodes[0].neurons = wired.nodes[0].neurons
        return wired
    return wire_snake


@pytest.mark.parametrize("wire, prop", [
    (_wire(legs=False), "the legs swing"),
    (_wire(only_segments=4), "swims at every length"),
    (_wire(in_place=True), "input unchanged"),
    (_wire(alternate=True), "a wave travels along the spine"),
])
def test_one_flaw_of_the_wiring_fails_exactly_its_property(wire, prop):
    j, v = verdicts("brains.wire_snake", wire)
    assert [p for p, ok in v.items() if not ok] == [prop], v


@pytest.mark.parametrize("wire, says", [(_wire(phase=0.0), "no wave travels along the body"),
                                        (lambda snake: snake.copy(), "a signal that oscillates")])
def test_segments_in_step_or_no_wiring_score_zero(wire, says):
    """Both fail the swimming gate; its message tells moving joints with no travelling wave (a phase
    step of 0, a student's walk) from joints that get no signal."""
    j, v = verdicts("brains.wire_snake", wire)
    assert j.score == 0.0
    assert says in next(x.message for x in j.verdicts if x.prop == "the snake swims")


def test_a_changed_body_scores_zero():
    def bigger(snake):
        w = SOL["wire_snake"](snake)
        w.nodes[0].size = (0.3, 0.04, 0.06)
        return w
    j, v = verdicts("brains.wire_snake", bigger)
    assert v["returns a valid creature"] and not v["keeps the body"] and j.score == 0.0


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_the_graders_rule_is_the_librarys_expansion(seed):
    """Every local neuron input of a random creature lands where expected_target says it does."""
    c = Creature.random(np.random.default_rng(seed), n_nodes=(2, 5), neurons=(1, 3))
    pheno = c.expand()
    brain, body = pheno.brain, pheno.body
    parent, children = body.parent.tolist(), pheno.children
    B = body.n_bodies
    first = np.cumsum([0] + [len(c.nodes[n].neurons) for n in body.node_id.tolist()])
    for j in range(brain.n_neurons):
        b = int(brain.neuron_body[j])
        if b < 0:
            continue
        neuron = c.nodes[int(body.node_id[b])].neurons[int(brain.neuron_index[j])]
        for k, inp in enumerate(neuron.inputs):
            if inp.morph is None:
                continue
            target = expected_target(inp.morph, b, parent, children)
            slot = int(brain.src[j, k])
            if target is None:
                assert slot == 0
            elif target == "brain":
                assert slot == 0 or slot >= N_CONST + N_SENSORS * B + first[-1]
            elif inp.ctrl < N_SENSORS:
                assert slot == N_CONST + N_SENSORS * target + inp.ctrl
            else:
                n_target = len(c.nodes[int(body.node_id[target])].neurons)
                k_neuron = inp.ctrl - N_SENSORS
                want = N_CONST + N_SENSORS * B + first[target] + k_neuron if k_neuron < n_target else 0
                assert slot == want
