"""The graph-ready swimmer step and host-synchronisation counts, proved on the CPU (issue #16).

On a GPU the host waits for the device at every value Python reads and at every output whose size
depends on the data, and a CUDA graph can capture none of them. ``World(graph=True)`` steps with
static shapes and reads nothing on the host; here it must equal the ordinary step, and a counter of
the synchronising calls must find none in it (nor in a picture render), while it does find those
of the ordinary step.
"""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import Creature, simulate
from coursekit.creatures.physics import backend as bk
from coursekit.creatures.physics import random_body_tree, random_state
from coursekit.creatures.physics.world import World
from coursekit.operations import CountHostSyncs
from coursekit.pictures import Genome, render
from coursekit.pictures.context import host

FIELDS = ("pos", "quat", "q", "lin", "omega", "qd")


def _worlds(seed, n=6, contacts=True, backend="torch", speed=1.0, **options):
    """An ordinary and a graph-ready world of the same random creatures in the same state."""
    rng = np.random.default_rng(seed)
    trees = [random_body_tree(rng, (4, 12)) for _ in range(n)]
    states = [random_state(rng, t, speed=speed, inside=0.9) for t in trees]
    worlds = [World(trees, backend=backend, contacts=contacts, graph=g, **options) for g in (False, True)]
    for w in worlds:
        w.set_state([s[0] for s in states], [s[1] for s in states])
    return worlds, rng


def _largest_relative_difference(a, b) -> float:
    n = bk.to_numpy
    return max(float(np.max(np.abs(n(getattr(a, f)) - n(getattr(b, f)))) / max(float(np.max(np.abs(n(getattr(a, f))))), 1e-300))
               for f in FIELDS)


def _steps(plain, ready, rng, n=100) -> tuple[int, int]:
    """``n`` steps of both worlds with the same random effectors every step and the state set
    anew half way (the limits and the contacts forget their history); the contact sensors and the
    frozen creatures must agree at every step. Returns the touching faces and the locked joints,
    counted over the steps (the contacts and the limits were exercised)."""
    touched = locked = 0
    for i in range(n):
        if i == n // 2:
            qpos, qvel = plain.get_state()
            for w in (plain, ready):
                w.set_state(qpos, qvel)
        e = rng.uniform(-1.0, 1.0, plain.model.n_joints)
        for w in (plain, ready):
            w.set_effectors(e)
            w.step()
        sensed = plain.sensors()[2]
        assert np.array_equal(sensed, ready.sensors()[2]), f"contact sensors differ at step {i}"
        assert np.array_equal(plain.diverged, ready.diverged)
        touched += int(np.sum(sensed > 0))
        locked += 0 if plain._lock is None else int(np.sum(bk.to_numpy(plain._lock)))
    return touched, locked


@pytest.mark.parametrize("backend", ["numpy", "torch"])
@pytest.mark.parametrize("contacts", [False, True])
def test_the_graph_ready_step_equals_the_ordinary_one(backend, contacts):
    # as the CUDA graph must reproduce the CPU: to 1e-10 over 100 steps
    (plain, ready), rng = _worlds(3, contacts=contacts, backend=backend)
    touched, _ = _steps(plain, ready, rng)
    assert _largest_relative_difference(plain.state, ready.state) < 1e-10
    np.testing.assert_allclose(bk.to_numpy(ready.overshoot), bk.to_numpy(plain.overshoot), rtol=1e-9, atol=1e-12)
    if contacts:  # the creatures did touch themselves: the contact path was exercised
        assert touched > 0


class EmulatedGraph:
    """CUDA graph semantics on the CPU: the step's Python runs once, at the capture; every replay
    runs the same computation with every attribute of the world, its limits and its contacts as
    they were after the capture, so only the buffers carry anything from one step to the next (a
    step's hand-over that :meth:`World._carried` forgot would be lost, as on a GPU)."""

    captures = 0

    def __init__(self, world):
        self.world, self.record, self.frozen = world, None, None

    @staticmethod
    def applies(world):
        return True

    @staticmethod
    def warm(world, step):
        step()

    def capture(self, record):
        self.record = record
        EmulatedGraph.captures += 1

    def _owners(self):
        w = self.world
        return [o for o in (w, w.limits, w.contacts) if o is not None]

    def _restore(self):
        for owner, attributes in self.frozen:
            kept = {k: v for k, v in vars(owner).items() if owner is self.world and k in ("time", "_graph")}
            vars(owner).clear()
            vars(owner).update(attributes, **kept)

    def replay(self):
        if self.frozen is None:
            self.frozen = [(o, dict(vars(o))) for o in self._owners()]
        self._restore()
        self.record()
        self._restore()  # a replay runs no Python: the attributes stay the buffers


@pytest.mark.parametrize("contacts", [False, True])
def test_a_recorded_graph_replays_the_ordinary_steps(monkeypatch, contacts):
    # what the CUDA graph does, emulated: captured after the warm-up, captured again after the
    # state is set anew, replayed in between, with effectors set from outside before every replay
    monkeypatch.setattr(World, "GRAPH", EmulatedGraph)
    EmulatedGraph.captures = 0
    (plain, ready), rng = _worlds(7, contacts=contacts)
    _steps(plain, ready, rng)
    assert EmulatedGraph.captures == 2 and ready._graph is not None
    assert _largest_relative_difference(plain.state, ready.state) < 1e-10
    assert np.array_equal(plain.diverged, ready.diverged)
    np.testing.assert_allclose(bk.to_numpy(ready.overshoot), bk.to_numpy(plain.overshoot), rtol=1e-9, atol=1e-12)


def test_a_step_the_device_will_not_record_runs_eagerly_with_the_same_results(monkeypatch):
    # a capture that fails half way through the step (an operation CUDA refuses to record) leaves
    # no trace of the Python it ran: the world warns once and steps eagerly, as the ordinary step
    class Refusing(EmulatedGraph):
        def capture(self, record):
            record()
            raise RuntimeError("operation not permitted when stream is capturing")

    monkeypatch.setattr(World, "GRAPH", Refusing)
    (plain, ready), rng = _worlds(7, contacts=True)
    with pytest.warns(RuntimeWarning, match="could not be captured as a CUDA graph"):
        _steps(plain, ready, rng, n=40)
    assert ready._graph is None and "not permitted" in ready._graph_failed
    assert _largest_relative_difference(plain.state, ready.state) < 1e-10


def test_the_graph_emulation_loses_what_the_step_does_not_hand_over(monkeypatch):
    # the emulation is strict: a world that forgot to hand over its joint forces swims without
    # the effectors set after the capture
    monkeypatch.setattr(World, "GRAPH", EmulatedGraph)
    carried = World._carried
    monkeypatch.setattr(World, "_carried", lambda self: [(g, p) for g, p in carried(self) if g() is not self.tau])
    (plain, ready), rng = _worlds(7, contacts=False)
    with pytest.raises(AssertionError):
        _steps(plain, ready, rng, n=40)
        assert _largest_relative_difference(plain.state, ready.state) < 1e-10


@pytest.mark.parametrize("contacts", [False, True])
def test_a_diverging_creature_is_frozen_the_same_way_in_the_graph_ready_step(contacts):
    # a speed cap that some creatures break and others keep: the graph-ready guard freezes the same
    # creatures at the same states without reading the flags on the host, and the others swim on
    # as in the ordinary step (with collisions, every pair of the frozen ones still tested)
    (plain, ready), rng = _worlds(5, n=8, contacts=contacts, max_speed=0.6)
    for _ in range(30):
        e = rng.uniform(-1.0, 1.0, plain.model.n_joints)
        for w in (plain, ready):
            w.set_effectors(e)
            w.step()
    assert 0 < plain.diverged.sum() < len(plain.diverged)
    assert np.array_equal(plain.diverged, ready.diverged)
    assert _largest_relative_difference(plain.state, ready.state) < 1e-10


@pytest.mark.parametrize("contacts", [False, True])
def test_the_graph_ready_step_synchronises_with_the_host_never(contacts):
    (plain, ready), _ = _worlds(11, contacts=contacts)
    for w in (plain, ready):
        for _ in range(3):
            w.step()
    with CountHostSyncs() as ordinary:
        plain.step()
    with CountHostSyncs() as graph_ready:
        ready.step()
    assert ordinary.count > 0, "the counter must see the ordinary step's reads (the guard's flags, the locked leaves)"
    assert graph_ready.count == 0, graph_ready.calls


def test_a_swim_step_with_brains_synchronises_with_the_host_never():
    # what simulate does per step: two brain ticks on the sensors, the effectors, the step
    from coursekit.creatures import BrainBatch

    rng = np.random.default_rng(4)
    phenotypes = [Creature.random(rng).expand() for _ in range(6)]
    world = World([p.body for p in phenotypes], backend="torch", graph=True)
    brain = BrainBatch(phenotypes, backend="torch", device="cpu")

    def swim():
        for _ in range(2):
            e = brain.step(*world.sensors(native=True), world.dt / 2)
        world.set_effectors(e)
        world.step()
        return world.centre_of_mass(native=True)

    for _ in range(3):
        swim()
    with CountHostSyncs() as syncs:
        swim()
    assert syncs.count == 0, syncs.calls


def test_simulate_with_brains_gives_the_same_fitness_with_the_graph_ready_step():
    rng = np.random.default_rng(2)
    creatures = [Creature.random(rng) for _ in range(5)]
    a, b = (simulate(creatures, seconds=0.4, settle=0.1, backend="torch", device="cpu", graph=g) for g in (False, True))
    np.testing.assert_allclose(b.com, a.com, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(b.fitness, a.fitness, rtol=1e-10, atol=1e-14)
    assert np.array_equal(a.diverged, b.diverged)


def test_graph_must_be_a_boolean():
    rng = np.random.default_rng(0)
    with pytest.raises(TypeError, match="graph"):
        World([random_body_tree(rng, 3)], graph="yes")


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.sampled_from([3, 6]))
def test_the_static_solve_equals_the_library_solve(seed, k):
    rng = np.random.default_rng(seed)
    G = rng.normal(size=(5, k, k))
    A = G @ np.swapaxes(G, 1, 2) + 0.1 * np.eye(k)  # symmetric positive definite
    b = rng.normal(size=(5, k))
    for xp, f in ((np, np.asarray), (bk.namespace("torch"), torch.as_tensor)):
        x = bk.to_numpy(bk.solve(xp, f(A), f(b), static=True))
        np.testing.assert_allclose(x, np.linalg.solve(A, b[:, :, None])[:, :, 0], rtol=1e-8, atol=1e-10)


def _population(n, seed=4):
    """Random genomes, among them the primitives whose parameters are numbers on the host."""
    rng = np.random.default_rng(seed)
    return [Genome.random(rng, n_strings=4, head_length=8) for _ in range(n)]


@pytest.mark.parametrize("group", [False, True])
def test_a_render_synchronises_with_the_host_never(group):
    genomes = _population(64)
    text = " ".join(g.expression() for g in genomes)
    for symbol in ("blur", "band-pass", "pixmap", "turbulence", "noise", "warp"):  # the kernels that read numbers
        assert symbol in text, symbol
    render(genomes, 32, device="cpu", workers=1, group=group)
    with CountHostSyncs() as syncs:
        render(genomes, 48, device="cpu", workers=1, group=group, as_tensor=True)
    assert syncs.count == 0, syncs.calls[:10]


def test_the_host_copy_of_every_parameter_equals_its_device_tensor():
    # what a kernel reads as numbers is what the device computes with, bit for bit (float32)
    from coursekit.pictures.tree import stack_trees

    seen = 0
    genomes = _population(40, seed=9)
    roots = [stack_trees([g.decode()], "cpu", {}) for g in genomes] + [stack_trees([g.decode() for g in genomes[:1] * 3], "cpu", {})]
    nodes = list(roots)
    while nodes:
        n = nodes.pop()
        nodes.extend(n.children)
        for p in n.params:
            assert host(p) == p.reshape(-1).tolist()
            seen += 1
    assert seen > 100


def test_host_reads_the_device_when_a_tensor_has_no_host_copy():
    p = torch.tensor([0.25, 3.5], dtype=torch.float32).reshape(2, 1, 1, 1)
    assert host(p) == [0.25, 3.5]


def test_count_host_syncs_counts_reads_and_data_dependent_sizes_only():
    x = torch.arange(6.0)
    with CountHostSyncs() as syncs:
        y = (x * 2).reshape(2, 3)[:, 1:]  # arithmetic and views: nothing read
        z = torch.where(x > 2, x, 0.0)
    assert syncs.count == 0 and y.shape == (2, 2) and z.shape == (6,)
    reads = [lambda: x.sum().item(), lambda: bool(x.any()), lambda: float(x[0]), lambda: x.tolist(), lambda: x.numpy(),
             lambda: torch.nonzero(x > 2), lambda: x[x > 2], lambda: torch.unique(x),
             lambda: torch.tensor([1.0, 2.0]), lambda: torch.asarray(0.5),  # host data made a tensor: an upload on a GPU
             lambda: bk.namespace("torch").maximum(x, 0.0)]  # array_api_compat makes a tensor of the 0.0
    for read in reads:
        with CountHostSyncs() as syncs:
            read()
        assert syncs.count >= 1, syncs.calls
    with CountHostSyncs() as syncs:
        bk.namespace("torch").clip(x, 0.0, None)  # a number passed as a number: nothing made
    assert syncs.count == 0
    assert torch.Tensor.numpy.__name__ == "numpy" and torch.tensor.__name__ == "tensor"  # restored on exit

