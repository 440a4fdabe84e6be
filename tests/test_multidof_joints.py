"""Sims' multi-DOF joints (issue 15, item 3): twist, universal, bend-twist, twist-bend, spherical.

A k-DOF joint is k hinges in series through k - 1 massless frames of the body tree; MuJoCo,
given the same joint as k ``<joint>`` elements of one body, is the independent oracle.
"""

import json

import mujoco  # in the [test] extra: the cross-check must run, never skip
import numpy as np
import pytest

import coursekit.data
from coursekit.creatures import Creature, champions, simulate, to_mjcf
from coursekit.creatures import operators
from coursekit.creatures.brain import BrainBatch
from coursekit.creatures.generation import REVOLUTE_LIMITS
from coursekit.creatures.morphology import JOINT_AXES, JOINT_DOF, ChildLink, Node, joint_axes
from coursekit.creatures.neural import Input, Neuron, dof_sensor
from coursekit.creatures.physics import forward_dynamics, random_state
from coursekit.creatures.physics import reference
from coursekit.creatures.physics.contact import Contacts
from coursekit.creatures.physics.limits import effective_inertia
from coursekit.creatures.physics.model import Model
from coursekit.creatures.physics.water import drag_matrix
from tests.test_physics_limits import _square_waves
from coursekit.creatures.physics.world import World
from coursekit.creatures.render import world_poses
from mujoco_oracle import mujoco_qacc

MULTI = [t for t in JOINT_AXES if JOINT_DOF[t] > 1]
ALL = list(JOINT_AXES)


def _creatures(seed, n, joint_types=ALL, **options):
    """Random bodies as these cases were chosen: rhythm wires brains only, but its draws move the
    stream, and with it every later body (with it, seeds 4 and 5 below draw bodies whose unlimited
    multi-DOF joints reach gimbal lock in a vacuum: benchmarks/NOTES.md, "Rhythm")."""
    rng = np.random.default_rng(seed)
    return [Creature.random(rng, joint_types=joint_types, rhythm=0.0, **options) for _ in range(n)]


def _trees(creatures):
    return [c.expand().body for c in creatures]


# ------------------------------------------------------------------------------ the oracle

@pytest.mark.parametrize("backend", ["numpy", "torch"])
def test_forward_dynamics_matches_mujoco_on_random_multidof_creatures(backend):
    creatures = _creatures(0, 60, n_nodes=(2, 6))
    trees = _trees(creatures)
    assert sum(t.massless.sum() for t in trees) > 60  # many multi-DOF joints among them
    rng = np.random.default_rng(1)
    states = [random_state(rng, t, speed=2.0) for t in trees]
    tau = [np.r_[rng.normal(size=6) * 5.0, rng.normal(size=t.n_joints) * 10.0] for t in trees]
    ref = mujoco_qacc(trees, states, tau)
    ours = forward_dynamics(creatures, [s[0] for s in states], [s[1] for s in states], tau, backend=backend)
    book = reference.forward_dynamics(creatures, [s[0] for s in states], [s[1] for s in states], tau)
    offs = np.r_[0, np.cumsum([6 + t.n_joints for t in trees])]
    for c, t in enumerate(trees):
        want = ref[offs[c]:offs[c + 1]]
        err = np.max(np.abs(ours[c] - want)) / np.max(np.abs(want))
        assert err < 1e-8, f"creature {c} ({t.n_parts} parts, {t.n_joints} DOF): relative error {err:.2e}"
        assert np.max(np.abs(book[c] - want)) / np.max(np.abs(want)) < 1e-8


def test_a_multidof_joint_is_several_mujoco_joints_of_one_body():
    rng = np.random.default_rng(2)
    c = Creature.random(rng, joint_types=["spherical"], n_nodes=3, p_recursion=0.0, p_symmetry=0.0)
    tree = c.expand().body
    m = mujoco.MjModel.from_xml_string(to_mjcf(c))
    P = tree.n_parts
    assert P >= 3 and m.nbody == 1 + P  # the world, then one body per box
    assert m.njnt == 1 + 3 * (P - 1) and m.nu == 3 * (P - 1)  # free root, 3 hinges per spherical joint, a motor each
    assert np.bincount(m.jnt_bodyid[1:]).tolist() == [0, 0] + [3] * (P - 1)
    parts = ~tree.massless
    np.testing.assert_allclose(m.body_mass[1:], tree.mass[parts], rtol=1e-15)
    np.testing.assert_allclose(m.jnt_range[1:], tree.limits[1:], rtol=1e-15)
    np.testing.assert_allclose(m.actuator_forcerange[:, 1], tree.strength[1:], rtol=1e-15)


# --------------------------------------------------------------------- joint geometry

def test_joint_axes_are_sims_twist_and_bend_axes():
    for jt in ALL:
        node = Node(joint_type=jt, joint_pos=(0.5, -1.0, 0.0), joint_axis=(0.0, 0.70710678118654752, 0.70710678118654752),
                    extra_limits=[(-0.5, 0.5)] * (JOINT_DOF[jt] - 1), effectors=[None] * JOINT_DOF[jt])
        axes = np.array(joint_axes(node))
        assert len(axes) == JOINT_DOF[jt]
        np.testing.assert_allclose(axes @ axes.T, np.eye(len(axes)), atol=1e-12)  # orthonormal
        for kind, a in zip(JOINT_AXES[jt], axes):
            if kind == "twist":  # about the attachment axis: the joint face's normal (here y)
                np.testing.assert_allclose(np.abs(a), [0, 1, 0])
            if kind == "bend":  # joint_axis made perpendicular to the twist axis
                np.testing.assert_allclose(a, [0, 0, 1], atol=1e-12)


def test_massless_frames_carry_no_box_no_water_and_no_contacts():
    creatures = _creatures(3, 8, joint_types=["spherical", "universal"], max_parts=10)
    trees = _trees(creatures)
    for c, t in zip(creatures, trees):
        s = c.summary()
        assert s["parts"] == t.n_parts and s["dof"] == t.n_joints == (t.n_parts - 1) + t.massless.sum()
        assert np.all(t.mass[t.massless] == 0) and np.all(t.mass[~t.massless] > 0)
    m = Model(trees)
    drag = np.asarray(drag_matrix(m))
    assert np.all(drag[m.massless_np] == 0) and np.all(drag[~m.massless_np] > 0)
    contacts = Contacts(m)
    pairs = np.r_[np.asarray(contacts.a), np.asarray(contacts.b)]
    assert not m.massless_np[pairs].any()
    # a part is never a candidate pair with the part it is jointed to (through the frames)
    up = m.part_parent_np
    assert not np.any((up[np.asarray(contacts.a)] == np.asarray(contacts.b)) | (up[np.asarray(contacts.b)] == np.asarray(contacts.a)))


# ------------------------------------------------------------ conservation and limits

def _vacuum_world(seed, **options):
    creatures = _creatures(seed, 4, joint_types=MULTI, n_nodes=(2, 5), max_parts=12)
    trees = _trees(creatures)
    rng = np.random.default_rng(seed + 100)
    states = [random_state(rng, t, speed=0.5, inside=0.3) for t in trees]
    w = World(trees, **{"drag": False, "limits": False, "contacts": False, **options})
    w.set_state([s[0] for s in states], [s[1] for s in states])
    return w


def test_energy_is_conserved_without_forces():
    w = _vacuum_world(4, dt=1 / 120)
    e0 = w.kinetic_energy()
    for _ in range(600):
        w.step()
    assert not w.diverged.any()
    assert np.all(np.abs(w.kinetic_energy() - e0) <= 1e-6 * e0)


def test_momentum_is_conserved_with_internal_torques():
    w = _vacuum_world(5, dt=1 / 240)
    m = w.model
    m_eff = effective_inertia(m)[m.joint_order]  # the massless frames' hinges too
    gain = m.gain_np[m.joint_order]
    phase = np.random.default_rng(6).uniform(0, 2 * np.pi, m.n_joints)
    P0, L0 = w.momentum()
    for i in range(600):
        w.set_effectors(m_eff / gain * np.sin(phase + 2 * np.pi * i * w.dt))
        w.step()
    P, L = w.momentum()
    assert not w.diverged.any()
    assert np.abs(w.state.qd).max() > 0.1
    assert np.abs(P - P0).max() <= 1e-9 * np.abs(P0).max()
    assert np.abs(L - L0).max() <= 1e-9 * np.abs(L0).max()


def test_stops_at_the_limits_of_every_axis_are_inelastic_impulses_that_conserve_momentum():
    creatures = _creatures(15, 6, joint_types=MULTI, max_parts=12)
    world = World(_trees(creatures), dt=1 / 60, drag=False, contacts=False)
    rng = np.random.default_rng(16)
    qpos, qvel = world.get_state()
    world.set_state(qpos, [np.r_[rng.normal(size=6) * 0.2, rng.normal(size=len(v) - 6) * 60.0] for v in qvel])
    P0, L0 = world.momentum()
    e0 = world.kinetic_energy()
    world.state = world._stop_at_limits(world.state)
    P, L = world.momentum()
    frames = np.asarray(world.model.massless_np)[world.model.n_creatures:]
    lock = np.asarray(world._lock)
    assert lock[frames].sum() > 5 and lock[~frames].sum() > 5  # further DOFs hit their limits too
    np.testing.assert_allclose(P, P0, atol=1e-13)
    np.testing.assert_allclose(L, L0, atol=1e-13)
    e = world.kinetic_energy()
    assert np.all(e <= e0 * (1 + 1e-12)) and e.sum() < 0.95 * e0.sum()


def test_torch_backend_follows_numpy():
    out = {}
    for backend in ("numpy", "torch"):
        w = _vacuum_world(7, dt=1 / 60, backend=backend, drag=True, limits=True, contacts=True)
        for _ in range(20):
            w.step()
        qpos, qvel = w.get_state()
        out[backend] = np.concatenate(qpos + qvel)
    np.testing.assert_allclose(out["torch"], out["numpy"], rtol=0, atol=1e-10)


def test_limits_hold_on_every_axis_under_full_effort():
    # the 1-DOF version (test_physics_limits) allows one creature in 12 to be whipped past the
    # speed cap; with a spherical bend free to reach ±π/2 (gimbal lock) 7 in 16 were
    creatures = _creatures(8, 8, joint_types=MULTI, max_parts=16)
    bodies = _trees(creatures)
    # every DOF's effector at full effort, switching at its own rate
    r = simulate(bodies, 2.0, controller=_square_waves(bodies, np.random.default_rng(9)), record_every=1)
    assert r.diverged.sum() <= 1
    for c in np.flatnonzero(~r.diverged):
        b = bodies[c]
        q = r.trajectory[c][:, 7:]
        lo, hi = b.limits[1:, 0], b.limits[1:, 1]
        excess = np.max(np.maximum(q - hi, lo - q), axis=0, initial=-np.inf) / (hi - lo)
        assert excess.max(initial=0.0) <= 1e-9, (c, excess.max())
        frames = b.massless[1:]  # the further DOFs, on the massless frames, moved and held too
        assert np.ptp(q[:, frames], axis=0).min(initial=1.0) > 1e-3


# ---------------------------------------------------------------------------- the files

def test_version_1_files_read_as_the_same_creatures_and_swim_bit_for_bit():
    olds = champions() + [coursekit.data.creature("limit_exploit_creature")]
    for c in olds:
        d = c.to_dict()
        d["format"] = "coursekit.creature/1"
        for n in d["nodes"]:
            del n["extra_limits"]
        old = Creature.from_dict(json.loads(json.dumps(d)))
        assert old.to_dict() == c.to_dict()
        assert json.loads(old.to_json())["format"] == "coursekit.creature/2"
        assert not old.expand().body.massless.any()
    a = simulate(olds, 1.0)
    b = simulate([Creature.from_json(c.to_json()) for c in olds], 1.0)
    np.testing.assert_array_equal(a.fitness, b.fitness)
    with pytest.raises(ValueError, match=r"nodes\[0\].*extra_limits"):  # version 2 requires the field
        d = champions()[0].to_dict()
        del d["nodes"][0]["extra_limits"]
        Creature.from_dict(d)


def test_version_2_round_trip_keeps_every_axis_and_its_behaviour(tmp_path):
    creatures = _creatures(10, 4, joint_types=MULTI)
    for k, c in enumerate(creatures):
        c.save(tmp_path / f"c{k}.json")
    back = [Creature.load(tmp_path / f"c{k}.json") for k in range(len(creatures))]
    assert [b.to_dict() for b in back] == [c.to_dict() for c in creatures]
    assert any(n.extra_limits for c in back for n in c.nodes)
    np.testing.assert_array_equal(simulate(back, 1.0).fitness, simulate(creatures, 1.0).fitness)


@pytest.mark.parametrize("edit, match", [
    (lambda n: n.__setitem__("extra_limits", [None]), r"nodes\[1\]\.extra_limits\[0\]: need \[lo, hi\]"),
    (lambda n: n.__setitem__("extra_limits", [[0.5, -0.5]]), r"nodes\[1\]\.extra_limits\[0\].*lo < 0 < hi"),
    (lambda n: n.__setitem__("extra_limits", [[-0.5]]), r"nodes\[1\]\.extra_limits\[0\]"),
    (lambda n: n.__setitem__("extra_limits", [[-0.5, "x"]]), r"nodes\[1\]\.extra_limits\[0\]"),
    (lambda n: n.__setitem__("extra_limits", [[-9.0, 0.5]]), r"nodes\[1\]\.extra_limits\[0\].*within"),
    (lambda n: n.__setitem__("extra_limits", []), r"nodes\[1\]\.extra_limits: a universal joint \(2 DOF\)"),
    (lambda n: n.__setitem__("extra_limits", None), r"nodes\[1\]\.extra_limits"),
    (lambda n: n.__setitem__("effectors", [None]), r"nodes\[1\]\.effectors: need one per DOF \(2\)"),
])
def test_corrupted_multidof_fields_are_refused_naming_the_field(edit, match):
    c = _two_part("universal")
    d = c.to_dict()
    edit(d["nodes"][1])
    with pytest.raises((ValueError, TypeError), match=match):
        Creature.from_dict(d)


# --------------------------------------------------------------- generation and mutation

def test_random_creatures_draw_the_joint_types_asked_for():
    for jt in MULTI:
        for c in _creatures(11, 5, joint_types=[jt]):
            assert {n.joint_type for n in c.nodes} == {jt}
            for n in c.nodes:
                assert len(n.extra_limits) == JOINT_DOF[jt] - 1 == len(n.effectors) - 1
                assert all(-lo in REVOLUTE_LIMITS and hi in REVOLUTE_LIMITS for lo, hi in n.dof_limits)
            t = c.expand().body
            assert t.n_joints == JOINT_DOF[jt] * (t.n_parts - 1)
    defaults = _creatures(12, 30, joint_types=None)
    assert {n.joint_type for c in defaults for n in c.nodes} == {"revolute", "prismatic"}
    with pytest.raises(ValueError, match=r"joint_types.*'ball'"):
        Creature.random(np.random.default_rng(0), joint_types=["revolute", "ball"])


def test_mutation_can_change_the_joint_type_and_keeps_one_effector_per_dof():
    rng = np.random.default_rng(13)
    parent = Creature.figure1_snake()
    seen = set()
    for _ in range(200):
        child = operators.mutate(parent, rng, rate=3.0, joint_types=["revolute", "universal", "spherical"])
        for n in child.nodes:
            seen.add(n.joint_type)
            assert len(n.effectors) == n.dof and len(n.extra_limits) == n.dof - 1
    assert {"universal", "spherical"} <= seen
    assert "prismatic" not in seen
    # without joint_types mutation keeps to the 1-DOF joints
    assert all(n.joint_type in ("revolute", "prismatic") for _ in range(50)
               for n in operators.mutate(parent, rng, rate=3.0).nodes)


def test_evolution_can_use_multidof_joints():
    from coursekit.creatures.evolution import evolve_swimmers

    r = evolve_swimmers(generations=1, rng=np.random.default_rng(14), population_size=6, seconds=0.5,
                        progress=False, joint_types=["spherical"], random_options={"max_parts": 6})
    assert all(n.joint_type == "spherical" for n in r.best.nodes)


# ----------------------------------------------------------------------------- the brain

def _two_part(joint_type):
    k = JOINT_DOF[joint_type]
    root = Node(size=(0.2, 0.1, 0.05), children=[ChildLink(1, pos=(1.0, 0.0, 0.0))], effectors=[None])
    limb = Node(size=(0.15, 0.05, 0.05), joint_type=joint_type, joint_pos=(-1.0, 0.0, 0.0), joint_axis=(0.0, 0.0, 1.0),
                limits=(-1.0, 1.0), extra_limits=[(-0.6, 0.6)] * (k - 1), effectors=[None] * k)
    return Creature([root, limb])


def test_one_effector_and_one_angle_and_velocity_sensor_per_dof():
    c = _two_part("spherical")
    limb = c.nodes[1]
    # effector d reads this part's sensor of DOF (d + 1) % 3, angle for d = 0, 1 and velocity for d = 2
    reads = [(1, 0), (2, 0), (0, 1)]
    limb.effectors = [Input(0, dof_sensor(d, w), 1.0) for d, w in reads]
    limb.neurons = [Neuron("sum", [Input(0, dof_sensor(2, 1), 1.0)])]
    c.validate()
    ph = c.expand()
    assert ph.body.n_parts == 2 and ph.body.n_joints == 3
    batch = BrainBatch([ph])
    angle, velocity = np.array([0.1, 0.2, 0.3]), np.array([-1.0, -2.0, -3.0])
    out = batch.step(angle, velocity, -np.ones((ph.body.n_bodies, 6)), 1 / 60)  # contacts per body
    np.testing.assert_array_equal(out, [angle[1], angle[2], velocity[0]])
    assert batch.neuron_outputs()[0] == velocity[2]
    # the sensor ids of further DOFs are refused on a 1-DOF part's own network
    c1 = _two_part("revolute")
    c1.nodes[1].effectors = [Input(0, dof_sensor(1, 0), 1.0)]
    with pytest.raises(ValueError, match=r"effectors\[0\]\.ctrl"):
        c1.validate()


def test_a_universal_joint_turns_about_both_axes():
    c = _two_part("universal")
    tree = c.expand().body
    m = mujoco.MjModel.from_xml_string(to_mjcf(c))
    d = mujoco.MjData(m)
    d.qpos[:] = np.r_[0, 0, 0, 1, 0, 0, 0, 0.4, -0.3]
    mujoco.mj_kinematics(m, d)
    R, t = world_poses(tree, d.qpos)
    np.testing.assert_allclose(R[~tree.massless], d.xmat[1:].reshape(-1, 3, 3), atol=1e-12)
    np.testing.assert_allclose(t[~tree.massless], d.xipos[1:], atol=1e-12)
    assert m.njnt == 3 and np.allclose(m.jnt_axis[1] @ m.jnt_axis[2], 0.0)


def test_random_and_mutated_networks_read_the_further_dofs_and_stay_valid():
    creatures = _creatures(17, 30, joint_types=["spherical"], neurons=(1, 3))
    own = [i.ctrl for c in creatures for n in c.nodes
           for i in [x for neuron in n.neurons for x in neuron.inputs] + n.effectors if i is not None and i.morph == 0]
    assert {16, 17, 18, 19} <= set(own)  # every further-DOF sensor gets wired somewhere
    rng = np.random.default_rng(18)
    c = creatures[0]
    for _ in range(60):  # type changes drop DOFs: repair redraws the inputs that named them
        c = operators.mutate(c, rng, rate=2.0, joint_types=ALL)
        c.validate()
        c.expand()
