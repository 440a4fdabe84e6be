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


def _resolve_index_error(morph, part, parent, children):
    """No guard for a missing child: children[part][morph - 1] raises IndexError (a student's walk)."""
    if morph >= 1:
        return children[part][morph - 1]
    return SOL["resolve"](morph, part, parent, children)


@pytest.mark.parametrize("kind, prop", [
    ("self_as_none", "0 names the part's own network"),
    ("brain_as_root", "-2 names the brain"),
    ("missing_child_clamped", "a missing child reads nothing"),
    ("root_parent_minus_one", "the root's parent reads nothing"),
    ("zero_based", "m >= 1 names child m"),
])
def test_one_wrong_rule_fails_exactly_its_property(kind, prop):
    """One wrong rule of the table costs its share, not the check (s25: a root answering -1 and an
    off-by-one child scored 0/3 through a gate)."""
    j, v = verdicts("brains.resolve", _resolve_wrong(kind))
    assert [p for p, ok in v.items() if not ok] == [prop] and 0 < j.score < get("brains.resolve").points


def test_a_wrong_rule_of_the_core_costs_more_than_an_edge_case():
    edge = verdicts("brains.resolve", _resolve_wrong("root_parent_minus_one"))[0].score
    core = verdicts("brains.resolve", _resolve_wrong("zero_based"))[0].score
    assert 0.6 * get("brains.resolve").points < core < edge < get("brains.resolve").points


def test_an_index_error_on_a_missing_child_keeps_the_rules_that_ran():
    j, v = verdicts("brains.resolve", _resolve_index_error)
    assert [p for p, ok in v.items() if not ok] == ["runs", "a missing child reads nothing"], v
    assert 0.6 * get("brains.resolve").points < j.score < get("brains.resolve").points


@pytest.mark.parametrize("answer", [lambda m, p, parent, children: None, lambda m, p, parent, children: p])
def test_an_answer_that_names_no_relative_scores_zero(answer):
    """The job gate: neither the parent nor the children named (a constant, the part itself)."""
    j, v = verdicts("brains.resolve", answer)
    assert not v["ids name relatives in the tree"] and j.score == 0
    assert "Nothing else is judged" in next(x.message for x in j.verdicts if x.prop == "ids name relatives in the tree")


def test_an_answer_that_is_not_an_index_fails_validity():
    j, v = verdicts("brains.resolve", lambda m, p, parent, children: float(p))
    assert not v["returns a part index, 'brain' or None"] and j.score == 0


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


def _chain(step, legs="brain"):
    """The exercise's wiring with phase step ``step``; legs on the brain's oscillator or the parent segment's."""
    def wire_snake(snake):
        wired = SOL["wire_snake"](snake)
        wired.nodes[0].neurons[0].inputs[1].weight = step
        if legs == "parent":
            wired.brain = []
            wired.nodes[1].effectors = [Input(-1, N_SENSORS + 1, 1.0)]
        return wired
    return wire_snake


def _drives(wirings):
    """The 4-segment snake of each wiring swum in one batch: its spine's drive (what the grader judges)."""
    from coursekit.grading.checks import ex06_wire_a_brain as ex

    texts = tuple(w(ex.unwired_snake(4)).to_json() for w in wirings)
    return [m["drive"] for m in ex.swim(texts)]


SWEEP = [round(s, 2) for s in np.r_[np.arange(-3.1, -0.29, 0.2), np.arange(0.3, 3.11, 0.2), [-3.0, -0.5]]]


def test_every_phase_step_of_the_sweep_is_a_wave_and_in_step_or_opposition_is_not():
    """s25 false failure: the wave was judged on the joints' motion, which the water shifts (a step
    of -3.0 rad, the fastest swimmer, measured [-3.07, 2.9]; -0.5 measured [-3.12, 1.3], no steady step
    at all; in phase measured [-3.04, 2.84]). Judged on what the wiring sends the muscles, every step
    from -3.1 to -0.3 and from +0.3 to +3.1 is a wave, both ways; in step, exact opposition and
    alternating steps are not."""
    from coursekit.grading.checks.ex06_wire_a_brain import _wave_fault

    alternate = _wire(alternate=True)
    wirings = [_chain(s) for s in SWEEP] + [_chain(-0.5, legs="parent"), _chain(0.0), _chain(0.1), _chain(np.pi),
                                            _chain(-np.pi), alternate]
    faults = [_wave_fault(d)[0] for d in _drives(wirings)]
    assert faults[:len(SWEEP) + 1] == [None] * (len(SWEEP) + 1), list(zip(SWEEP, faults))
    assert faults[len(SWEEP) + 1:] == ["neighbours beat in step"] * 2 + ["neighbours beat in exact opposition, a standing wave"] * 2 \
        + ["the phase differences of neighbours are not one steady step"], faults


def test_random_phases_are_no_wave():
    """Drives of 3 joints at one rhythm with random phases: a steady step only by chance (two lags within
    0.5 rad of each other, about one draw in seven), while a steady step of any size is one."""
    from coursekit.grading.checks.ex06_wire_a_brain import SECONDS, _wave_fault

    rng = np.random.default_rng(0)
    t = np.arange(int(SECONDS * 60)) / 60
    waves = 0
    for _ in range(400):
        phases = rng.uniform(-np.pi, np.pi, 3)
        waves += _wave_fault(np.sin(2 * np.pi * 3.0 * t[:, None] + phases[None, :]))[0] is None
    assert waves < 400 * 0.2, waves
    steady = np.sin(2 * np.pi * 3.0 * t[:, None] - 1.2 * np.arange(3)[None, :])
    assert _wave_fault(steady)[0] is None and _wave_fault(np.zeros((len(t), 3)))[0] == "some spine joints get no oscillating signal"


@pytest.mark.parametrize("wire", [_chain(-3.0), _chain(-0.5, legs="parent"), _chain(1.5)],
                         ids=["step -3.0", "step -0.5, legs on the parent", "step +1.5"])
def test_the_sweeps_swimmers_get_full_marks(wire):
    j, v = verdicts("brains.wire_snake", wire)
    assert j.passed and j.score == get("brains.wire_snake").points, [(x.prop, x.message) for x in j.verdicts if not x.passed]


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
