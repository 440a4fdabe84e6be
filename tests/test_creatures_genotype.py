"""Genotype (paper 2.1.1), files, and expansion to a body tree (2.3)."""

import json
import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures import ChildLink, Creature, Node, Recursion, Symmetry, expand, part_poses
from coursekit.creatures.body import MIN_HALF_EXTENT, PRISMATIC, REVOLUTE, rotation_about
from coursekit.creatures.genotype import FORMAT, JOINT_AXES, ROTATIONS
from coursekit.creatures.audit import body_length
from coursekit.creatures.generation import RHYTHM, RHYTHM_HZ
from coursekit.creatures.neural import N_SENSORS, Input
from coursekit.creatures.simulate import simulate
from coursekit.creatures.render import box_corners

seeds = st.integers(0, 2**32 - 1)


def _corner_set(c):
    """Rounded box corners as a sorted array, for comparing boxes as point sets."""
    return np.array(sorted(map(tuple, np.round(c, 9))))


# ------------------------------------------------------------------------------ random / json


@settings(max_examples=60, deadline=None)
@given(seeds)
def test_random_is_valid_deterministic_and_round_trips(seed):
    a = Creature.random(np.random.default_rng(seed))
    b = Creature.random(np.random.default_rng(seed))
    assert a.to_json() == b.to_json()
    c = Creature.from_json(a.to_json())
    assert c == a
    assert json.loads(a.to_json())["format"] == "coursekit.creature/2"


def test_save_load_atomic_and_refuses_bad_files(tmp_path):
    c = Creature.random(np.random.default_rng(1), n_nodes=4)
    p = tmp_path / "c.json"
    c.save(p)
    assert Creature.load(p) == c
    assert sorted(os.listdir(tmp_path)) == ["c.json"]  # no temporary left behind
    text = p.read_text()
    p.write_text(text[: len(text) // 2])
    with pytest.raises(ValueError, match="truncated"):
        Creature.load(p)
    p.write_text(json.dumps({"format": "coursekit.genome/1", "strings": []}))
    with pytest.raises(ValueError, match="creature.format"):
        Creature.load(p)
    d = c.to_dict()
    del d["nodes"][0]["size"]
    with pytest.raises(ValueError, match=r"nodes\[0\].*size"):
        Creature.from_dict(d)
    # a missing folder or a folder given as the file is named, not the temporary file beside it
    with pytest.raises(FileNotFoundError, match="the folder '.*nowhere' does not exist: '.*nowhere/c.json'"):
        c.save(tmp_path / "nowhere" / "c.json")
    with pytest.raises(IsADirectoryError, match="is a folder; give a file name"):
        c.save(tmp_path)


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda n: setattr(n[0], "size", (0.01, 0.1, 0.1)), r"nodes\[0\]\.size.*0\.025"),
        (lambda n: setattr(n[0], "limits", (0.1, 0.5)), r"limits.*lo < 0 < hi"),
        (lambda n: setattr(n[0], "joint_axis", (1.0, 1.0, 0.0)), r"joint_axis.*unit"),
        (lambda n: setattr(n[0], "joint_type", "ball"), r"joint_type.*revolute.*spherical"),
        (lambda n: setattr(n[0], "joint_type", "universal"), r"extra_limits.*universal.*1 \[lo, hi\]"),
        (lambda n: (setattr(n[0], "joint_type", "universal"), setattr(n[0], "extra_limits", [None])), r"extra_limits\[0\]: need \[lo, hi\]"),
        (lambda n: n[0].children.append(ChildLink(7)), r"children\[\d\]\.child.*\[0, 2\)"),
        (lambda n: n[1].children.append(ChildLink(0)), r"cycle"),
        (lambda n: n[0].symmetry.append(Symmetry(0, 1)), r"symmetry\[\d\]\.child"),
        (lambda n: setattr(n[0].children[0], "rot", ((1, 0, 0), (0, 1, 0), (0, 0, -1))), r"rot.*proper rotation"),
        (lambda n: setattr(n[0], "effectors", [Input(0, 99, 1.0)]), r"effectors\[0\]\.ctrl"),
        (lambda n: setattr(n[0], "effectors", [Input(-2, 5, 1.0)]), r"effectors\[0\]\.ctrl.*brain"),
        (lambda n: setattr(n[0], "force", 0.0), r"force"),
    ],
)
def test_validation_names_the_field(edit, match):
    c = Creature.figure1_snake()
    nodes = c.copy().nodes
    edit(nodes)
    with pytest.raises((ValueError, TypeError), match=match):
        Creature(nodes, c.brain)


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda n: n[0].symmetry.__setitem__(0, Symmetry(1, 3)), r"nodes\[0\]\.symmetry\[0\]\.axis.*0, 1 or 2"),
        (lambda n: n[0].symmetry.__setitem__(0, (1, 2)), r"nodes\[0\]\.symmetry\[0\].*Symmetry"),
        (lambda n: n[0].children.__setitem__(0, (1, (0.5, 1.0, 0.0))), r"nodes\[0\]\.children\[0\].*ChildLink"),
        (lambda n: setattr(n[0], "recursion", (1, 2)), r"nodes\[0\]\.recursion.*list"),
    ],
)
def test_expand_and_render_name_the_field_of_a_genotype_changed_after_it_was_built(edit, match):
    # lesson 05 edits a creature in place and draws it: the error names the field, as simulate's does
    from coursekit.creatures import render

    for draw in (expand, lambda c: c.expand(), render):
        c = Creature.figure1_snake()
        edit(c.nodes)
        with pytest.raises((ValueError, TypeError), match=match):
            draw(c)


def test_unreachable_node_rejected():
    c = Creature.figure1_snake()
    with pytest.raises(ValueError, match="unreachable"):
        Creature(c.copy().nodes + [Node(effectors=[None])], c.brain)


def test_random_rejects_bad_params():
    rng = np.random.default_rng(0)
    with pytest.raises(ValueError, match="n_nodes"):
        Creature.random(rng, n_nodes=0)
    with pytest.raises(TypeError, match="rng"):
        Creature.random(np.random.RandomState(0))
    for bad in ("3", None, 2.5, (1,)):
        with pytest.raises(ValueError, match="Creature.random.n_nodes: need 1 <= lo <= hi"):
            Creature.random(rng, n_nodes=bad)
    with pytest.raises(ValueError, match="Creature.random.neurons: need 0 <= lo <= hi"):
        Creature.random(rng, neurons=5)
    with pytest.raises(ValueError, match="Creature.random.p_recursion: must be a probability in \\[0, 1\\], got '0.3'"):
        Creature.random(rng, p_recursion="0.3")
    assert Creature.random(np.random.default_rng(0), n_nodes=[2, 3], neurons=np.array([0, 2])).summary()
    for bad in (-0.1, 1.5, "0.5", None):
        with pytest.raises(ValueError, match="Creature.random.rhythm: must be a probability in \\[0, 1\\]"):
            Creature.random(rng, rhythm=bad)


def _driven(c):
    """The effectors driven by a beat, as (oscillator, effector input) pairs: an ``oscillate_wave``
    neuron with one constant input (its phase), in the brain or in the effector's own network."""
    found = []
    for node in c.nodes:
        for e in node.effectors:
            if e is None or e.morph not in (-2, 0):
                continue
            if e.morph == -2:
                neuron = c.brain[e.ctrl]
            elif N_SENSORS <= e.ctrl < N_SENSORS + len(node.neurons):
                neuron = node.neurons[e.ctrl - N_SENSORS]
            else:
                continue
            if neuron.func == "oscillate_wave" and len(neuron.inputs) == 1 and neuron.inputs[0].morph is None:
                found.append((neuron, e))
    return found


@settings(max_examples=40, deadline=None)
@given(seeds)
def test_rhythm_drives_every_effector_by_oscillators_of_one_frequency(seed):
    c = Creature.random(np.random.default_rng(seed), rhythm=1.0)
    assert Creature.from_json(c.to_json()) == c  # valid, and it round-trips
    driven = _driven(c)
    assert len(driven) == sum(len(node.effectors) for node in c.nodes)
    assert len({n.param for n, _ in driven}) == 1  # one frequency for the whole creature, in range
    assert all(RHYTHM_HZ[0] <= n.param <= RHYTHM_HZ[1] and 0.5 <= abs(e.weight) <= 2.0 for n, e in driven)


def test_rhythm_drives_the_share_of_effectors_it_names():
    rng = np.random.default_rng(0)
    for rhythm in (0.0, 0.25, 0.75):
        creatures = [Creature.random(rng, rhythm=rhythm) for _ in range(300)]
        effectors = sum(len(node.effectors) for c in creatures for node in c.nodes)
        share = sum(len(_driven(c)) for c in creatures) / effectors
        # binomial spread (about 0.02 here), plus the random wiring's own rare beats
        assert rhythm - 0.06 < share < rhythm + 0.06, (rhythm, share)


def test_random_creatures_with_rhythm_swim_further_than_without():
    """What rhythm is for: random creatures that beat their joints at one frequency include
    better swimmers than randomly wired ones, which barely move (reciprocal strokes in viscous
    water). The fastest tenth of 150 random creatures, in body lengths per second over 6 s, is
    2.0-3.1 times faster with rhythm on seeds 0-4 (benchmarks/NOTES.md, "Rhythm")."""
    n, seconds = 150, 6.0
    fastest = {}
    for rhythm in (0.0, RHYTHM):
        rng = np.random.default_rng(0)
        creatures = [Creature.random(rng, max_parts=12, rhythm=rhythm) for _ in range(n)]
        swim = simulate(creatures, seconds)
        lengths = np.array([body_length(c.expand().body) for c in creatures])
        fastest[rhythm] = np.sort(np.linalg.norm(swim.com[:, -1] - swim.com[:, 0], axis=1) / seconds / lengths)[-n // 10:].mean()
    assert fastest[RHYTHM] > 1.4 * fastest[0.0], fastest


# ------------------------------------------------------------------------------------ snake


def test_figure1_snake_two_nodes_two_legs_on_last_limb():
    c = Creature.figure1_snake(segments=4)
    assert len(c.nodes) == 2  # "realized by only two real object instantiations"
    body = c.expand().body
    assert sorted(set(body.node_id.tolist())) == [0, 1]
    assert body.n_bodies == 6
    segs = np.nonzero(body.node_id == 0)[0]
    legs = np.nonzero(body.node_id == 1)[0]
    assert body.parent[segs].tolist() == [-1, 0, 1, 2]  # a chain
    assert body.parent[legs].tolist() == [segs[-1], segs[-1]]  # both legs on the last limb
    R, t = part_poses(body)
    # the two legs are mirror images across the last segment's y plane
    M = np.diag([1.0, -1.0, 1.0])
    corners = box_corners(body)
    local = [(corners[k] - t[segs[-1]]) @ R[segs[-1]] for k in legs]
    np.testing.assert_allclose(_corner_set(local[0] @ M), _corner_set(local[1]), atol=1e-9)
    # negative force coefficient: the mirrored leg is driven opposite
    assert body.gain[legs[0]] == -body.gain[legs[1]]


def test_part_poses_names_a_bad_pose():
    body = Creature.figure1_snake(segments=4).expand().body
    with pytest.raises(ValueError, match=r"q: expected 5 joint coordinates \(one per joint\)"):
        part_poses(body, np.zeros(99))
    with pytest.raises(ValueError, match="q: expected 5 joint coordinates"):
        part_poses(body, "abc")
    with pytest.raises(TypeError, match="body: expected a BodyTree"):
        part_poses(Creature.figure1_snake())


def test_recursion_count_scale_and_terminal_only():
    seg = Node(size=(0.2, 0.1, 0.1), recursive_limit=3, recursion=[Recursion((1.0, 0, 0), 0.75)],
               children=[ChildLink(1, (0, 1.0, 0), terminal_only=True), ChildLink(1, (0, 0, 1.0))], effectors=[None])
    leaf = Node(size=(0.05, 0.05, 0.05), effectors=[None])
    body = Creature([seg, leaf]).expand().body
    segs = np.nonzero(body.node_id == 0)[0]
    assert len(segs) == 4  # root + recursive_limit copies
    np.testing.assert_allclose(body.half_extents[segs, 0], 0.2 * 0.75 ** np.arange(4))
    leaves = np.nonzero(body.node_id == 1)[0]
    # every segment has the plain child; only the terminal one also has the terminal-only one
    assert len(leaves) == 4 + 1
    assert sorted(body.parent[leaves].tolist()) == sorted(segs.tolist() + [segs[-1]])


def test_part_cap_truncates_and_flags():
    n = Node(size=(0.1, 0.1, 0.1), recursive_limit=4, recursion=[Recursion((1.0, 0, 0)), Recursion((0, 1.0, 0))],
             effectors=[None])
    c = Creature([n])
    full = expand(c, 1000).body
    assert full.n_bodies == 2**5 - 1 and not full.meta["truncated"]
    capped = expand(c, 10).body
    assert capped.n_bodies == 10 and capped.meta["truncated"]


def test_thin_parts_clamped_to_minimum_thickness():
    n = Node(size=(0.03, 0.03, 0.03), recursive_limit=4, recursion=[Recursion((1.0, 0, 0), 0.5)], effectors=[None])
    body = Creature([n]).expand().body
    assert body.half_extents.min() >= MIN_HALF_EXTENT


def test_strength_follows_sims_area_law_for_large_parts_and_a_sweep_speed_cap_for_small_ones():
    from coursekit.creatures.body import STRENGTH_PER_AREA, SWEEPS_PER_SECOND

    def body(k):
        a = Node(size=(0.2 * k, 0.1 * k, 0.1 * k), children=[ChildLink(1)], effectors=[None])
        b = Node(size=(0.1 * k, 0.1 * k, 0.1 * k), effectors=[None])
        return Creature([a, b]).expand().body

    big, small = body(2.0), body(0.5)
    # large parts: Sims' law, the smaller of the two parts' largest cross-sections (0.4 x 0.4 m)
    assert big.strength[1] == pytest.approx(STRENGTH_PER_AREA * 0.4 * 0.4)
    assert body(3.0).strength[1] == pytest.approx(2.25 * big.strength[1])  # ~ area
    # small parts: capped at the force that sweeps the child through the water at
    # SWEEPS_PER_SECOND ranges per second: the cube's drag about the joint axis through its face
    # centre (rotational term plus face drag at the lever arm), times the sweep speed
    h = 0.05
    area, k = 4 * h * h, 2.0
    drag = (2 * k / 3) * 2 * area * h * h + 2 * k * area * h * h
    rng_ = small.limits[1, 1] - small.limits[1, 0]
    assert small.strength[1] == pytest.approx(drag * SWEEPS_PER_SECOND * rng_)
    assert small.strength[1] < STRENGTH_PER_AREA * area
    assert big.mass.sum() == pytest.approx(8.0 * body(1.0).mass.sum())


# -------------------------------------------------------------------------------- mirroring


def _rotations():
    return st.one_of(st.sampled_from(ROTATIONS), st.tuples(*[st.floats(-3, 3)] * 3).filter(lambda v: np.linalg.norm(v) > 1e-3).map(
        lambda v: tuple(map(tuple, rotation_about(np.asarray(v) / np.linalg.norm(v), np.linalg.norm(v)))))
    )


coord = st.sampled_from([-1.0, -0.5, 0.0, 0.5, 1.0])
unit = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda v: np.linalg.norm(v) > 0.1).map(
    lambda v: tuple(np.asarray(v) / np.linalg.norm(v)))


@settings(max_examples=120, deadline=None)
@given(rot1=_rotations(), rot2=_rotations(), axis=st.integers(0, 2), pos=st.tuples(coord, coord, coord),
       jp=st.tuples(coord, coord, coord), a1=unit, a2=unit, jt=st.sampled_from(["revolute", "prismatic"]),
       q=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5)), force=st.sampled_from([-1.0, 1.0]))
def test_symmetric_copy_is_exact_mirror_image_in_any_pose(rot1, rot2, axis, pos, jp, a1, a2, jt, q, force):
    """A symmetric subtree (two levels) is the mirror image of the original at equal joint
    coordinates, with proper rotations; the gain sign follows the force coefficient."""
    root = Node(size=(0.3, 0.2, 0.1), children=[ChildLink(1, pos, rot1)], symmetry=[Symmetry(1, axis)], effectors=[None])
    mid = Node(size=(0.15, 0.05, 0.08), joint_type=jt, joint_pos=jp, joint_axis=a1, force=force,
               children=[ChildLink(2, (1.0, 0.5, 0.0), rot2)], effectors=[None])
    tip = Node(size=(0.05, 0.1, 0.04), joint_pos=(0.0, -1.0, 0.5), joint_axis=a2, effectors=[None])
    body = Creature([root, mid, tip]).expand().body
    assert body.node_id.tolist() == [0, 1, 2, 1, 2]
    qq = np.array([q[0], q[1], q[0], q[1]])
    corners = box_corners(body, qq)
    M = np.ones(3)
    M[axis] = -1.0
    for orig, copy in ((1, 3), (2, 4)):
        np.testing.assert_allclose(_corner_set(corners[orig] * M), _corner_set(corners[copy]), atol=1e-9)
    assert np.all(np.linalg.det(body.joint_rot) > 0)
    assert body.gain[1] == abs(force) and body.gain[3] == force


def test_reflect_flag_mirrors_single_child():
    base = Node(size=(0.3, 0.2, 0.1), children=[ChildLink(1, (1.0, 0.5, 0.0), ROTATIONS[5])], effectors=[None])
    child = Node(size=(0.1, 0.05, 0.2), joint_pos=(-1.0, 0.5, 0.0), effectors=[None])
    plain = Creature([base, child]).expand().body
    refl = Creature([Node(**{**base.__dict__, "children": [ChildLink(1, (1.0, 0.5, 0.0), ROTATIONS[5], reflect=1)]}),
                     child]).expand().body
    M = np.array([1.0, -1.0, 1.0])
    np.testing.assert_allclose(_corner_set(box_corners(plain)[1] * M), _corner_set(box_corners(refl)[1]), atol=1e-9)


def test_joint_types_and_axes_units():
    c = Creature.random(np.random.default_rng(5), n_nodes=6)
    body = c.expand().body
    assert set(body.joint_type[1:].tolist()) <= {REVOLUTE, PRISMATIC}
    np.testing.assert_allclose(np.linalg.norm(body.joint_axis[1:], axis=1), 1.0)
    assert FORMAT == "coursekit.creature/2"


json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 30) | st.floats(allow_nan=True, allow_infinity=True) | st.text(max_size=3),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=3), inner, max_size=3),
    max_leaves=6,
)


@settings(max_examples=500, deadline=None)
@given(seed=seeds, value=json_values, pick=st.integers(0, 10**6))
def test_corrupted_files_give_clear_errors_or_valid_creatures(seed, value, pick):
    """Replace one random field anywhere in a valid file: loading either raises ValueError /
    TypeError naming the field or yields a creature that passes validation and expands."""
    joint_types = list(JOINT_AXES) if seed % 2 else None  # multi-DOF joints (their extra_limits) half the time
    d = Creature.random(np.random.default_rng(seed), n_nodes=(1, 4), neurons=(0, 2), brain_neurons=(0, 2),
                        joint_types=joint_types).to_dict()
    slots = []

    def walk(obj):
        items = obj.items() if isinstance(obj, dict) else enumerate(obj) if isinstance(obj, list) else []
        for k, v in items:
            slots.append((obj, k))
            walk(v)

    walk(d)
    obj, k = slots[pick % len(slots)]
    obj[k] = value
    try:
        c = Creature.from_dict(d)
    except (ValueError, TypeError) as e:
        assert "reature" in str(e), str(e)  # the message names the field's path in the creature
        return
    c.validate()
    c.expand()
