"""The BodyTree contract: validation errors name the field; mass properties match the textbook."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.creatures.body import MIN_HALF_EXTENT, PRISMATIC, REVOLUTE, BodyTree, rotation_about


def two_box(**over):
    kw = dict(
        parent=[-1, 0],
        half_extents=[[0.1, 0.2, 0.3], [0.2, 0.05, 0.05]],
        joint_type=[0, REVOLUTE],
        joint_axis=[[0, 0, 0], [0, 0, 1]],
        joint_pos_parent=[[0, 0, 0], [0.1, 0, 0]],
        joint_pos_child=[[0, 0, 0], [-0.2, 0, 0]],
        joint_rot=[np.eye(3)] * 2,
        limits=[[0, 0], [-1, 1]],
        gain=[0, 1],
        strength=[0, 1],
    )
    kw.update(over)
    return BodyTree(**kw)


def test_box_mass_and_inertia_match_the_solid_cuboid_formula():
    t = two_box(density=2.0)
    a, b, c = 0.2, 0.4, 0.6  # full side lengths of box 0
    m = a * b * c * 2.0
    assert t.mass[0] == pytest.approx(m)
    # I_xx = m (b^2 + c^2) / 12 etc. for a solid cuboid about its centre
    assert t.inertia[0] == pytest.approx([m * (b**2 + c**2) / 12, m * (a**2 + c**2) / 12, m * (a**2 + b**2) / 12])
    assert t.depth.tolist() == [0, 1]
    assert t.n_joints == 1


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("parent", [0, 0], "parent[0]"),
        ("parent", [-1, 1], "parent[1]"),
        ("joint_type", [0, 7], "joint_type"),
        ("half_extents", [[0.1, 0.2, 0.3], [0.2, MIN_HALF_EXTENT / 2, 0.05]], "half_extents[1]"),
        ("joint_axis", [[0, 0, 0], [0, 0, 2]], "joint_axis[1]"),
        ("joint_rot", [np.eye(3), np.diag([1.0, 1.0, -1.0])], "joint_rot[1]"),
        ("limits", [[0, 0], [0.5, 1]], "limits[1]"),
        ("strength", [0, 0], "strength[1]"),
    ],
)
def test_invalid_fields_are_refused_by_name(field, value, words):
    with pytest.raises(ValueError, match=words.replace("[", r"\[").replace("]", r"\]")):
        two_box(**{field: value})


def test_prismatic_joint_is_accepted():
    assert two_box(joint_type=[0, PRISMATIC]).joint_type[1] == PRISMATIC


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3),
    st.floats(-10, 10),
    st.floats(-10, 10),
)
def test_rodrigues_is_a_proper_rotation_about_its_axis(axis, q1, q2):
    a = np.asarray(axis) / np.linalg.norm(axis)
    R = rotation_about(a, q1)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(R) == pytest.approx(1.0)
    assert np.allclose(R @ a, a, atol=1e-12)  # the axis is fixed
    # rotations about one axis compose by adding angles
    assert np.allclose(rotation_about(a, q1) @ rotation_about(a, q2), rotation_about(a, q1 + q2), atol=1e-10)
    # a perpendicular vector turns by exactly q1
    p = np.cross(a, [1.0, 0, 0] if abs(a[0]) < 0.9 else [0, 1.0, 0])
    p /= np.linalg.norm(p)
    assert np.dot(p, R @ p) == pytest.approx(np.cos(q1), abs=1e-12)
