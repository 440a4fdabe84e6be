"""The compiled step (``World(compiled=True)``, :mod:`coursekit.creatures.physics.compiled`) is the
numpy step's physics: the same states to rounding, on random creatures and on evolved swimmers
with their contacts and locked joints, through every integrator; a creature's motion does not
depend on its batch; and what it cannot do is refused by name."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, simulate
from coursekit.creatures.physics import compiled, kernels, random_body_tree, random_state
from coursekit.creatures.physics.world import World
from tests.test_graph_ready import _largest_relative_difference, _steps

EVOLVED = Path(__file__).resolve().parents[1] / "benchmarks" / "data" / "evolved_swimmers.json"


def _pair(trees, states=None, **options):
    worlds = [World(trees, compiled=c, **options) for c in (False, True)]
    if states is not None:
        for w in worlds:
            w.set_state([s[0] for s in states], [s[1] for s in states])
    return worlds


@pytest.mark.parametrize("integrator", ["rkn", "rk4"])
@pytest.mark.parametrize("contacts", [False, True])
def test_the_compiled_step_follows_the_numpy_step_for_100_steps(integrator, contacts):
    # rkn runs the compiled integrator, rk4 numpy's integrator around the compiled stages
    rng = np.random.default_rng(3)
    trees = [random_body_tree(rng, (4, 12)) for _ in range(6)]
    states = [random_state(rng, t, speed=1.0, inside=0.9) for t in trees]
    plain, fast = _pair(trees, states, contacts=contacts, integrator=integrator)
    touched, locked = _steps(plain, fast, rng)
    assert _largest_relative_difference(plain.state, fast.state) < 1e-10
    np.testing.assert_allclose(fast.overshoot, plain.overshoot, rtol=1e-9, atol=1e-12)
    assert locked > 0 and (touched > 0) == contacts  # the limits and the contacts were exercised


def test_every_step_of_an_evolved_swim_agrees_with_the_numpy_step():
    # from states of a real swim, brains on: the step's contacts and locks as evolution meets them
    from coursekit.creatures.brain import BrainBatch

    doc = json.loads(EVOLVED.read_text(encoding="utf-8"))
    phenotypes = [Creature.from_dict(c).expand() for c in doc["creatures"][:12]]
    brain, w = BrainBatch(phenotypes), World([p.body for p in phenotypes])
    worst, contacts, locks = 0.0, 0, 0
    keep = {id(w.model): w.model, id(w.xp): w.xp}
    for k in range(150):
        if k > 30:  # settled: the brains drive the joints, ticking twice a step as simulate's do
            for _ in range(2):
                e = brain.step(*w.sensors(), w.dt / 2)
            w.set_effectors(e)
        w.step()
        if k % 10 == 5:
            plain, fast = copy.deepcopy(w, dict(keep)), copy.deepcopy(w, dict(keep))
            fast._compiled = compiled.Dynamics(fast.model, fast.damping)
            for x in (plain, fast):
                x._inertia_q = None  # each computes its own inertias
                x.step()
            worst = max(worst, _largest_relative_difference(plain.state, fast.state))
            contacts += 0 if w.active_contacts is None else len(w.active_contacts["a"])  # touching
            contacts += 0 if w._held is None else int(np.sum(w._held[9] >= 0))  # held (the compiled hold's slots)
            locks += int(np.sum(w._lock))
    assert worst < 1e-12
    assert contacts > 100 and locks > 100


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**31 - 1), n=st.integers(1, 4), speed=st.floats(0.0, 3.0))
def test_one_step_of_random_creatures_agrees_with_the_numpy_step(seed, n, speed):
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (2, 10)) for _ in range(n)]
    states = [random_state(rng, t, speed=speed, inside=0.9) for t in trees]
    plain, fast = _pair(trees, states)
    e = rng.uniform(-1.0, 1.0, plain.model.n_joints)
    for w in (plain, fast):
        w.set_effectors(e)
        w.step()
    assert _largest_relative_difference(plain.state, fast.state) < 1e-10


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 4), speed=st.floats(0.0, 3.0))
def test_a_stage_gives_the_textbook_accelerations_and_locked_forces(seed, n, speed):
    # against reference.aba (the book's ABA, one body at a time): water damping, locked joints
    from coursekit.creatures.physics import reference
    from coursekit.creatures.physics.model import Model
    from coursekit.creatures.physics.water import DRAG_COEFFICIENT, drag_diagonal, drag_matrix

    rng = np.random.default_rng(seed)
    trees = [Creature.random(rng, joint_types=["revolute", "prismatic", "universal"]).expand().body for _ in range(n)]
    m = Model(trees)
    M = m.n_joints
    q, qd, tau = rng.uniform(-1.0, 1.0, M), rng.normal(0.0, speed, M), rng.normal(0.0, 0.5, M)  # user order
    lock = rng.random(M) < 0.3
    v0 = rng.normal(0.0, speed, (n, 6))
    internal = lambda x: x[np.argsort(m.joint_order)]  # noqa: E731  (user joint k is internal row joint_order[k])
    dyn = compiled.Dynamics(m, drag_matrix(m))
    held = dyn.inertias(internal(q), internal(lock))
    R = np.repeat(np.eye(3)[None], n, axis=0)
    lin_acc, ang_acc, qdd, need = dyn.accel(held, R, internal(qd), v0[:, 3:].copy(), v0[:, :3].copy(), internal(tau), internal(lock), None)
    a_lin = lin_acc - np.cross(v0[:, :3], v0[:, 3:])  # the stage returns the root's acceleration in the world frame
    qdd, need = qdd[m.joint_order], need[m.joint_order]
    at = 0
    for k, t in enumerate(trees):
        js = slice(at, at + t.n_bodies - 1)
        a0, qddr, taur = reference.aba(t, q[js], qd[js], v0[k], tau[js], damping=drag_diagonal(t.half_extents, DRAG_COEFFICIENT), lock=lock[js])
        scale = 1.0 + max(np.abs(a0).max(), np.abs(qddr).max(initial=0.0), np.abs(taur).max(initial=0.0))
        assert np.abs(ang_acc[k] - a0[:3]).max() <= 1e-10 * scale and np.abs(a_lin[k] - a0[3:]).max() <= 1e-10 * scale
        assert np.abs(qdd[js] - qddr).max(initial=0.0) <= 1e-10 * scale
        assert np.abs(need[js] - taur).max(initial=0.0) <= 1e-10 * scale
        at += t.n_bodies - 1


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), first=st.booleans(), scale=st.sampled_from([1e-8, 1.0, 30.0, 1e4]))
def test_the_compiled_neurons_compute_every_function_as_evaluate_does(seed, first, scale):
    from coursekit.creatures.neural import FUNCTION_NAMES, OUTPUT_LIMIT, evaluate

    rng = np.random.default_rng(seed)
    N = 4 * len(FUNCTION_NAMES)
    code = np.arange(N) % len(FUNCTION_NAMES)  # every function, four times
    x = rng.normal(0.0, scale, (N, 3))
    x[rng.random((N, 3)) < 0.05] = 0.0  # a divide by zero, a sign of zero
    x[rng.random((N, 3)) < 0.03] = np.nan  # a NaN input
    n_inputs = rng.integers(1, 4, N)
    param, y_prev, s_prev = rng.uniform(0.2, 3.0, N), rng.normal(0.0, scale, N), rng.normal(0.0, scale, N)
    t, dt = float(rng.uniform(0, 10)), 1 / 120
    want, want_sums = evaluate(code, x, n_inputs, param, y_prev, s_prev, first, t, dt)
    out, sums = np.empty(N), np.empty(N)
    kernels.neurons(code, x, n_inputs, param, y_prev, s_prev, first, t, dt, OUTPUT_LIMIT, out, sums)
    np.testing.assert_allclose(sums, want_sums, rtol=1e-12, atol=0, equal_nan=True)
    np.testing.assert_allclose(out, want, rtol=1e-12, atol=1e-300)


def test_a_creature_swims_the_same_alone_and_in_a_batch_bit_for_bit():
    # what lets evolution split a generation over worker processes with the same results
    doc = json.loads(EVOLVED.read_text(encoding="utf-8"))
    creatures = [Creature.from_dict(c) for c in doc["creatures"][:5]]
    together = simulate(creatures, 1.0, settle=0.2, compiled=True)
    for i in (0, 3):
        alone = simulate([creatures[i]], 1.0, settle=0.2, compiled=True)
        assert alone.fitness[0] == together.fitness[i]
        assert np.array_equal(alone.com[0], together.com[i])


def test_the_compiled_swim_scores_what_the_numpy_swim_scores():
    doc = json.loads(EVOLVED.read_text(encoding="utf-8"))
    creatures = [Creature.from_dict(c) for c in doc["creatures"][:8]]
    plain = simulate(creatures, 2.0, settle=0.5)
    fast = simulate(creatures, 2.0, settle=0.5, compiled=True)
    np.testing.assert_allclose(fast.fitness, plain.fitness, rtol=1e-6)
    assert np.max(plain.fitness) > 0.01  # they swim


def test_the_step_is_compiled_by_default_and_what_it_cannot_do_is_refused_by_name(monkeypatch):
    tree = random_body_tree(np.random.default_rng(0), (3, 5))
    with pytest.raises(ValueError, match="compiled: the compiled step runs on the numpy backend"):
        World([tree], compiled=True, graph=True)
    with pytest.raises(ValueError, match="compiled: .*backend='torch'"):
        World([tree], compiled=True, backend="torch")
    with pytest.raises(TypeError, match="compiled: must be True or False"):
        World([tree], compiled="yes")
    # by default, compiled wherever it can run
    assert World([tree])._compiled is not None
    assert World([tree], backend="torch")._compiled is None and World([tree], graph=True)._compiled is None
    monkeypatch.setattr(kernels, "numba", None)
    with pytest.raises(ImportError, match="compiled: .*pip install numba"):
        World([tree], compiled=True)
    assert World([tree])._compiled is None  # by default the numpy step, where numba is missing


def _glue_inputs(data, n):
    """Random joints for the limits' and the guards' glue: within, at and beyond their limits,
    moving and locked, with a NaN or an infinity now and then."""
    floats = st.floats(-3.0, 3.0, allow_nan=False)
    lo = np.array(data.draw(st.lists(st.floats(-2.0, 0.0), min_size=n, max_size=n)))
    hi = lo + np.array(data.draw(st.lists(st.floats(0.1, 2.0), min_size=n, max_size=n)))
    q = np.array(data.draw(st.lists(st.one_of(floats, st.sampled_from([0.0, np.nan, np.inf])), min_size=n, max_size=n)))
    pick = np.array(data.draw(st.lists(st.integers(0, 3), min_size=n, max_size=n)))
    q = np.where(pick == 1, lo, np.where(pick == 2, hi, q))  # exactly at a limit
    rates = st.one_of(floats, st.sampled_from([0.0, -0.0]))  # a force or a rate of exactly zero
    draw = lambda: np.array(data.draw(st.lists(rates, min_size=n, max_size=n)))  # noqa: E731
    return lo, hi, q, draw


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_the_compiled_limits_decide_and_stop_exactly_as_numpys(data):
    from coursekit.creatures.physics.limits import Limits

    n = data.draw(st.integers(1, 12))
    lo, hi, q, draw = _glue_inputs(data, n)
    qd, tau, push = draw() * 10, draw(), draw()
    model = type("M", (), {"xp": np, "device": None, "limits_np": np.stack([lo, hi], axis=1)})()
    mine, theirs = Limits(model, 1 / 480), Limits(model, 1 / 480)
    dynamics = compiled.Dynamics.__new__(compiled.Dynamics)
    locked = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)))
    target = np.where(np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n))), hi, lo)
    for lim in (mine, theirs):
        lim.push, lim.lock, lim.target = push, locked, target
    lock, at = theirs.begin(q, qd, tau)
    rate = theirs.rate(at, qd)
    got = dynamics.limits(mine, q, qd, tau)
    for a, b in [(got[0], lock), (got[1], at), (got[2], rate), (mine.up, theirs.up), (mine.target, theirs.target),
                 (mine.beyond, theirs.beyond), (mine.lock, theirs.lock)]:
        np.testing.assert_array_equal(a, b)  # bit for bit, NaNs in the same places


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data(), creatures=st.integers(1, 4))
def test_the_compiled_guard_and_rotations_are_numpys_bit_for_bit(data, creatures):
    from coursekit.creatures.physics import spatial as sp
    from coursekit.creatures.physics.integrate import State

    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    trees = [random_body_tree(rng, (2, 5)) for _ in range(creatures)]
    plain, fast = _pair(trees)
    C, M = creatures, plain.model.n_joints
    scale = lambda shape: rng.normal(size=shape) * 10.0 ** rng.uniform(-1, 3, size=shape[:1] + (1,) * (len(shape) - 1))  # noqa: E731
    quat = rng.normal(size=(C, 4))
    quat /= np.linalg.norm(quat, axis=1, keepdims=True)
    new = State(scale((C, 3)), quat, scale((M,)), scale((C, 3)), scale((C, 3)), scale((M,)))
    for field in data.draw(st.lists(st.sampled_from(["pos", "quat", "q", "lin", "qd"]), max_size=2)):
        getattr(new, field).flat[rng.integers(getattr(new, field).size)] = rng.choice([np.nan, np.inf])
    np.testing.assert_array_equal(fast._rotations(new.quat), sp.quat_to_mat(np, new.quat))
    fields = ("pos", "quat", "q", "lin", "omega", "qd")
    prev = State(*(np.zeros_like(getattr(new, f)) for f in fields))
    mine, theirs = fast._guard(prev, new), plain._guard(prev, new)
    for f in fields:
        np.testing.assert_array_equal(getattr(mine, f), getattr(theirs, f))
    np.testing.assert_array_equal(fast._diverged, plain._diverged)
