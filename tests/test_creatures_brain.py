"""Neural control (paper 2.1.2) and the batched expanded brain (2.3)."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import BrainBatch, ChildLink, Creature, Input, Neuron, Node, Recursion, Symmetry
from coursekit.creatures.neural import FUNCTION_CODE, FUNCTION_NAMES, N_SENSORS, OUTPUT_LIMIT, evaluate

# An independent scalar reference for every stateless function (Sims' 23 names).
REF = {
    "sum": lambda x, p: sum(x),
    "product": lambda x, p: math.prod(x),
    "divide": lambda x, p: (x[0] / (x[1] if len(x) > 1 else 1.0)) if len(x) < 2 or abs(x[1]) >= 1e-6 else 0.0,
    "sum_threshold": lambda x, p: 1.0 if sum(x) > p else -1.0,
    "greater_than": lambda x, p: 1.0 if x[0] > (x[1] if len(x) > 1 else 0.0) else -1.0,
    "sign_of": lambda x, p: float((sum(x) > 0) - (sum(x) < 0)),
    "min": lambda x, p: min(x),
    "max": lambda x, p: max(x),
    "abs": lambda x, p: abs(sum(x)),
    "if": lambda x, p: (x[1] if len(x) > 1 else 0.0) if x[0] > 0 else (x[2] if len(x) > 2 else 0.0),
    "interpolate": lambda x, p: (lambda b, c: b + (c - b) * min(max(x[0], 0.0), 1.0))(
        x[1] if len(x) > 1 else 0.0, x[2] if len(x) > 2 else 1.0),
    "sin": lambda x, p: math.sin(sum(x)),
    "cos": lambda x, p: math.cos(sum(x)),
    "atan": lambda x, p: math.atan(sum(x)),
    "log": lambda x, p: math.log(max(abs(sum(x)), 1e-6)),
    "expt": lambda x, p: math.exp(min(sum(x), 20.0)),
    "sigmoid": lambda x, p: 1.0 / (1.0 + math.exp(-sum(x))),
}
STATEFUL = {"integrate", "differentiate", "smooth", "memory", "oscillate_wave", "oscillate_saw"}


def test_all_23_sims_functions_present():
    assert len(FUNCTION_NAMES) == 23
    assert set(FUNCTION_NAMES) == set(REF) | STATEFUL


vals = st.floats(-5, 5, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(name=st.sampled_from(sorted(REF)), x=st.lists(vals, min_size=1, max_size=3), p=st.floats(-1, 1))
def test_stateless_functions_match_definitions(name, x, p):
    xs = np.zeros((1, 3))
    xs[0, : len(x)] = x
    out, _ = evaluate(np.array([FUNCTION_CODE[name]]), xs, np.array([len(x)]), np.array([p]), np.zeros(1), np.zeros(1),
                      False, 0.0, 0.01)
    want = min(max(REF[name](x, p), -OUTPUT_LIMIT), OUTPUT_LIMIT)
    assert out[0] == pytest.approx(want, rel=1e-12, abs=1e-12)


def _single(func, param=0.0, n_inputs=1):
    """A creature whose brain neuron 0 has ``func`` and reads root neurons through brain id (1, k);
    the root neurons copy the child's joint angle and velocity; the child's effector shows the
    brain neuron."""
    inputs = [Input(1, N_SENSORS + k, 1.0) for k in range(n_inputs)]
    root = Node(children=[ChildLink(1)], neurons=[Neuron("sum", [Input(1, 0, 1.0)]), Neuron("sum", [Input(1, 1, 1.0)])],
                effectors=[None])
    child = Node(effectors=[Input(-2, 0, 1.0)])
    return Creature([root, child], [Neuron(func, inputs, param)])


def _run(c, angles, velocities=None, dt=0.1):
    bb = BrainBatch([c.expand()])
    out = []
    for k, a in enumerate(angles):
        v = 0.0 if velocities is None else velocities[k]
        out.append(bb.step(np.array([a]), np.array([v]), -np.ones((2, 6)), dt)[0])
    return np.array(out)


def test_stateful_functions():
    dt = 0.1
    s = np.array([1.0, 2.0, -1.0, 0.5, 3.0, 0.0, 0.0, 0.0])
    # Root neuron 0 copies the child's angle sensor this tick; the brain neuron reads it from the
    # previous tick (synchronous update), so its input at tick k is s[k-1].
    lag = np.concatenate([[0.0], s[:-1]])
    np.testing.assert_allclose(_run(_single("integrate"), s), np.cumsum(lag) * dt)
    diff = _run(_single("differentiate"), s)
    np.testing.assert_allclose(diff[1:], np.diff(lag) / dt)
    assert diff[0] == 0.0
    rate = 5.0
    sm = _run(_single("smooth", rate), s)
    y, want = 0.0, []
    for v in lag:
        y = y + (1 - math.exp(-rate * dt)) * (v - y)
        want.append(y)
    np.testing.assert_allclose(sm, want)
    gate = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0, -1.0, -1.0])
    mem = _run(_single("memory", n_inputs=2), s, gate)
    glag = np.concatenate([[0.0], gate[:-1]])
    y, want = 0.0, []
    for a, b in zip(lag, glag):
        y = a if b > 0 else y
        want.append(y)
    np.testing.assert_allclose(mem, want)
    f = 1.5
    t = np.arange(len(s)) * dt
    np.testing.assert_allclose(_run(_single("oscillate_wave", f), s), np.sin(2 * np.pi * f * t + lag), atol=1e-12)
    saw = _run(_single("oscillate_saw", f), s)
    np.testing.assert_allclose(saw, 2 * np.mod(f * t + lag / (2 * np.pi), 1.0) - 1, atol=1e-12)
    assert np.all((saw >= -1) & (saw < 1))


def test_outputs_finite_and_clipped():
    xs = np.array([[1e300, 1e300, 1e300], [1.0, 0.0, 0.0], [-1e308, 0, 0]])
    code = np.array([FUNCTION_CODE["product"], FUNCTION_CODE["divide"], FUNCTION_CODE["expt"]])
    out, _ = evaluate(code, xs, np.array([3, 2, 1]), np.zeros(3), np.zeros(3), np.zeros(3), False, 0.0, 0.01)
    assert np.all(np.isfinite(out)) and np.all(np.abs(out) <= OUTPUT_LIMIT)


# ------------------------------------------------------------------- relative ids after expansion


def test_relative_ids_resolve_to_the_right_instances():
    """Each segment's neuron reads its parent's neuron (-1), its child m's joint angle (m, 0) and
    the brain (-2); recursion and symmetry copies wire to their own instances."""
    seg = Node(
        size=(0.2, 0.1, 0.1), recursive_limit=2, recursion=[Recursion((1.0, 0, 0))],
        children=[ChildLink(1, (0, 1.0, 0), terminal_only=True)], symmetry=[Symmetry(1, 1)],
        neurons=[Neuron("sum", [Input(0, 0, 1.0)]),  # own joint angle
                 Neuron("sum", [Input(-1, N_SENSORS, 1.0)]),  # parent's neuron 0
                 Neuron("sum", [Input(1, 0, 1.0), Input(2, 0, 10.0)])],  # child 1 and child 2 angles
        effectors=[Input(-2, 0, 1.0)],
    )
    leg = Node(size=(0.05, 0.1, 0.05), joint_pos=(0, -1.0, 0), neurons=[Neuron("sum", [Input(-1, N_SENSORS, 1.0)])],
               effectors=[Input(0, N_SENSORS, 2.0)])
    c = Creature([seg, leg], [Neuron("sum", [Input(1, 0, 0.0), Input(None, 0, 0.25)])])
    ph = c.expand()
    body = ph.body
    assert body.node_id.tolist() == [0, 0, 0, 1, 1] and body.parent.tolist() == [-1, 0, 1, 2, 2]
    assert ph.children == [[1], [2], [3, 4], [], []]
    bb = BrainBatch([ph])
    angles = np.array([0.1, 0.2, 0.3, 0.4])  # joints = parts 1..4
    eff = None
    for _ in range(3):
        eff = bb.step(angles, np.zeros(4), -np.ones((5, 6)), 0.01)
    out = bb.neuron_outputs()
    brain = ph.brain
    get = {(int(b), int(k)): out[j] for j, (b, k) in enumerate(zip(brain.neuron_body, brain.neuron_index))}
    part_angle = np.concatenate([[0.0], angles])
    for b in range(3):
        assert get[(b, 0)] == pytest.approx(part_angle[b])
        assert get[(b, 1)] == pytest.approx(part_angle[b - 1] if b > 0 else 0.0)  # root has no parent: 0
    assert get[(0, 2)] == pytest.approx(part_angle[1])  # one child: child 2 missing reads 0
    assert get[(2, 2)] == pytest.approx(part_angle[3] + 10 * part_angle[4])  # both legs
    assert get[(3, 0)] == pytest.approx(part_angle[2]) and get[(4, 0)] == pytest.approx(part_angle[2])
    assert get[(-1, 0)] == pytest.approx(0.25)
    np.testing.assert_allclose(eff, [0.25, 0.25, 2 * part_angle[2], 2 * part_angle[2]])


def test_synchronous_update_delays_one_tick_per_neuron():
    root = Node(children=[ChildLink(1)], neurons=[Neuron("sum", [Input(1, 0, 1.0)]), Neuron("sum", [Input(0, N_SENSORS, 1.0)])],
                effectors=[None])
    child = Node(effectors=[Input(-1, N_SENSORS + 1, 1.0)])
    bb = BrainBatch([Creature([root, child]).expand()])
    out = [bb.step(np.array([a]), np.zeros(1), -np.ones((2, 6)), 0.01)[0] for a in [1.0, 2.0, 3.0, 4.0]]
    assert out == [0.0, 1.0, 2.0, 3.0]  # sensor -> n0 (tick 1) -> n1 (tick 2) read by the effector


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_batch_equals_creatures_run_alone(seed):
    rng = np.random.default_rng(seed)
    creatures = [Creature.random(rng, neurons=(1, 4), brain_neurons=(1, 3)) for _ in range(4)]
    creatures.insert(int(rng.integers(5)), Creature([Node(effectors=[None])]))  # no joints, no neurons
    phs = [c.expand() for c in creatures]
    batch = BrainBatch(phs)
    alone = [BrainBatch([p]) for p in phs]
    for _ in range(6):
        ja = rng.normal(size=batch.total_joints)
        jv = rng.normal(size=batch.total_joints)
        ct = rng.choice([-1.0, 1.0], size=(batch.total_bodies, 6))
        got = batch.step(ja, jv, ct, 0.02)
        want, j0, b0 = [], 0, 0
        for a in alone:
            want.append(a.step(ja[j0:j0 + a.total_joints], jv[j0:j0 + a.total_joints], ct[b0:b0 + a.total_bodies], 0.02))
            j0 += a.total_joints
            b0 += a.total_bodies
        np.testing.assert_array_equal(got, np.concatenate(want))
        assert np.all(np.isfinite(got))
    batch.reset()
    assert np.all(batch.neuron_outputs() == 0) and batch.time == 0.0


def test_step_rejects_bad_shapes():
    bb = BrainBatch([Creature.figure1_snake().expand()])
    with pytest.raises(ValueError, match="contact"):
        bb.step(np.zeros(5), np.zeros(5), np.zeros((5, 6)), 0.01)
    with pytest.raises(ValueError, match=r"\(5,\)"):
        bb.step(np.zeros(4), np.zeros(5), np.zeros((6, 6)), 0.01)
    with pytest.raises(TypeError, match="Brain"):
        BrainBatch([])
    with pytest.raises(TypeError, match=r"BrainBatch.brains: expected a non-empty list of Brain \(or Phenotype\) objects, got NoneType"):
        BrainBatch(None)


def test_snake_legs_move_in_opposition():
    """Both legs read the brain's wave; the negative force coefficient flips the mirrored one."""
    ph = Creature.figure1_snake().expand()
    bb = BrainBatch([ph])
    for _ in range(10):
        eff = bb.step(np.zeros(5), np.zeros(5), -np.ones((6, 6)), 0.05)
    torque = eff * ph.body.gain[1:]
    assert eff[3] == eff[4] != 0 and torque[3] == -torque[4]


def test_snake_travelling_wave_from_recursive_relative_ids():
    """Each snake segment adds -1.5 rad to its parent's phase: a known travelling wave."""
    ph = Creature.figure1_snake(segments=4).expand()
    bb = BrainBatch([ph])
    dt = 0.01
    for n in range(12):
        t = bb.time
        eff = bb.step(np.zeros(5), np.zeros(5), -np.ones((6, 6)), dt)
    # joints 0..2 are segments 1..3; segment k has phase -1.5 (k + 1)
    want = [math.sin(2 * math.pi * 3.0 * t - 1.5 * (k + 1)) for k in (1, 2, 3)]  # 3 Hz oscillators
    np.testing.assert_allclose(eff[:3], want, atol=1e-12)


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_the_brain_on_torch_equals_the_brain_on_numpy(seed):
    """The brain runs on the simulator's backend: every function of Sims' 23, state included, gives
    the numpy brain's outputs tick by tick, and its arrays stay torch tensors."""
    torch = pytest.importorskip("torch")
    rng = np.random.default_rng(seed)
    creatures = [Creature.random(rng, neurons=(2, 6), brain_neurons=(1, 4)) for _ in range(5)]
    phs = [c.expand() for c in creatures]
    cpu, dev = BrainBatch(phs), BrainBatch(phs, backend="torch", device="cpu")
    for _ in range(8):
        ja, jv = rng.normal(size=(2, cpu.total_joints)) * 3
        ct = rng.choice([-1.0, 1.0], size=(cpu.total_bodies, 6))
        want = cpu.step(ja, jv, ct, 0.02)
        got = dev.step(*(torch.as_tensor(a) for a in (ja, jv, ct)), 0.02)
        assert isinstance(got, torch.Tensor) and isinstance(dev.neuron_outputs(), torch.Tensor)
        np.testing.assert_allclose(got.numpy(), want, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(dev.neuron_outputs().numpy(), cpu.neuron_outputs(), rtol=1e-12, atol=1e-12)


def test_every_function_evaluates_alike_on_torch():
    """Each of the 23 functions with 1, 2 and 3 inputs, at awkward values (zeros, huge, negative)."""
    torch = pytest.importorskip("torch")
    from coursekit.creatures.physics.backend import namespace

    xt = namespace("torch")
    rng = np.random.default_rng(0)
    values = np.array([0.0, -0.0, 1e-7, -3.0, 2.5, 50.0, -1e4, np.pi])
    for name in FUNCTION_NAMES:
        n = 24
        code = np.full(n, FUNCTION_CODE[name])
        x = rng.choice(values, size=(n, 3))
        k = np.tile([1, 2, 3], n // 3)
        p, y0, s0 = rng.choice(values, size=(3, n))
        for first in (True, False):
            want = evaluate(code, x, k, p, y0, s0, first, 0.7, 0.01)
            got = evaluate(code, *(torch.as_tensor(a) for a in (x, k, p, y0, s0)), first, 0.7, 0.01,
                           groups=[(FUNCTION_CODE[name], torch.arange(n))], xp=xt)
            for g, w in zip(got, want):
                np.testing.assert_allclose(g.numpy(), w, rtol=1e-12, atol=1e-12, err_msg=name)


@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_a_copied_brain_goes_on_as_the_original(backend):
    # the realistic-workload benchmark starts every engine from one mid-swim brain (a deep copy);
    # a pickled one reaches worker processes
    import copy
    import pickle

    rng = np.random.default_rng(3)
    creatures = [Creature.random(rng) for _ in range(4)]
    brain = BrainBatch([c.expand() for c in creatures], backend=backend)
    J, B = brain.total_joints, brain.total_bodies
    sensed = lambda t: (np.sin(t + np.arange(J)), np.cos(t * np.arange(J)), np.where(np.arange(B * 6).reshape(B, 6) % 3, 1.0, -1.0))  # noqa: E731
    for t in range(5):
        brain.step(*sensed(t), 1 / 120)
    copies = [copy.deepcopy(brain), pickle.loads(pickle.dumps(brain))]
    for t in range(5, 15):
        out = np.asarray(brain.step(*sensed(t), 1 / 120))
        for c in copies:
            assert np.array_equal(np.asarray(c.step(*sensed(t), 1 / 120)), out)
