"""The audit tells swimming from exploiting the simulator: one creature per exploit, and two that swim."""

import numpy as np
import pytest

from coursekit.creatures import Creature
from coursekit.creatures.audit import audit


@pytest.fixture(scope="module")
def swimmers():
    return audit([Creature.figure1_snake(), Creature.paddle_turtle()], 3.0)


def test_the_hand_designed_swimmers_pass(swimmers):
    snake, turtle = swimmers
    assert snake.passed and turtle.passed, (str(snake), str(turtle))
    assert snake.body_lengths_per_second > 0.15 and turtle.body_lengths_per_second > 0.01
    assert snake.fine_speed > 0.75 * snake.speed  # the speed is the water's, not the step's
    assert snake.vacuum_drift_fine < 0.05 * snake.speed * 3.0
    assert snake.energy > 0 and np.isfinite(snake.cost_of_transport)


def test_a_speed_that_is_integration_error_fails():
    # at a step far too coarse for its stroke the snake "swims" in a vacuum: the rerun with the
    # physics in finer sub-steps shows it (the same creature passes at the default step, above)
    (r,) = audit([Creature.figure1_snake()], 3.0, dt=1 / 12)
    assert not r.passed and any("vacuum" in x or "sub-steps" in x for x in r.reasons), str(r)


def test_joints_through_their_limits_fail():
    (r,) = audit([Creature.figure1_snake()], 3.0, limits=False)
    assert r.limit_excess > 0.25 and not r.passed and any("limit" in x for x in r.reasons), str(r)


def test_a_creature_past_the_speed_caps_fails():
    (r,) = audit([Creature.figure1_snake()], 3.0, max_joint_speed=1.0)
    assert r.diverged and not r.passed and any("diverged" in x for x in r.reasons), str(r)


def test_drifting_without_effort_fails():
    # a body launched at 1 m/s into thin water coasts with its effectors off: not swimming
    snake = Creature.figure1_snake()
    nq = 7 + snake.expand().body.n_joints
    qvel = np.zeros(nq - 1)
    qvel[0] = 1.0
    (r,) = audit([snake], 3.0, initial_state=([np.r_[0, 0, 0, 1, 0, 0, 0, np.zeros(nq - 7)]], [qvel]), settle=0.0, drag_coefficient=0.05)
    assert not r.passed and any("effectors off" in x for x in r.reasons), str(r)


def test_an_audit_spread_over_worker_processes_reports_the_same():
    from concurrent.futures import ProcessPoolExecutor

    creatures = [Creature.figure1_snake(), Creature.paddle_turtle()]
    alone = audit(creatures, 1.0)
    with ProcessPoolExecutor(2) as pool:
        spread = audit(creatures, 1.0, executor=pool)
    assert [vars(r) for r in spread] == [vars(r) for r in alone]
    assert alone[0].energy > 0 and alone[0].fine_speed > 0  # the runs came back, the metered swim's work with them


def test_a_speed_from_parts_passing_through_each_other_fails():
    # a champion evolution bred: a limb sweeps through another part within a step and stays sunk in
    # it, pressed by its muscle (1.26 m/s at the step, 1.19 in eight sub-steps); in 24 sub-steps the
    # held contacts keep its parts apart and it swims 0.13 m/s
    from coursekit.creatures import audit as a
    from coursekit.data import creature

    (r,) = audit([creature("step_exploit_creature")], 10.0)
    assert r.fine_speed > a.FINE_SPEED_SHARE * r.speed  # eight sub-steps alone do not see it
    assert r.sunk > a.SUNK_SHARE and r.deep_speed < 0.25 * r.speed
    assert not r.passed and any(f"{a.DEEP_REFINE} sub-steps" in x for x in r.reasons), str(r)


def test_parts_apart_are_not_sunk(swimmers):
    assert [r.sunk for r in swimmers] == [0.0, 0.0] and all(r.deep_speed is None for r in swimmers)


def test_overlaps_measure_a_fold_into_the_body():
    # a plate (A, 0.6 x 0.4 x 0.12 m), a 5 cm link on its +x edge and a box (B, 0.2 x 0.2 x 0.1 m) on the
    # link: at rest B lies beside A; the link turned a quarter turn about y swings B under (or over) A's
    # edge, 1 cm into it (A: |z| <= 0.06; B, now upright: x 0.25..0.35, |z| 0.05..0.25); B is the thinner
    from coursekit.creatures.audit import overlaps
    from coursekit.creatures.body import REVOLUTE, BodyTree

    tree = BodyTree(
        parent=[-1, 0, 1], half_extents=[(0.3, 0.2, 0.06), (0.025, 0.025, 0.025), (0.1, 0.1, 0.05)],
        joint_type=[0, REVOLUTE, REVOLUTE], joint_axis=[(0, 0, 0), (0, 1, 0), (0, 1, 0)],
        joint_pos_parent=[(0, 0, 0), (0.3, 0, 0), (0.025, 0, 0)], joint_pos_child=[(0, 0, 0), (-0.025, 0, 0), (-0.1, 0, 0)],
        joint_rot=[np.eye(3)] * 3, limits=[(0, 0), (-2, 2), (-2, 2)], gain=[0, 1, 1], strength=[0, 1, 1],
    )
    root = [0, 0, 0, 1, 0, 0, 0]
    share, metres = overlaps([tree], [np.array([root + [0.0, 0.0], root + [np.pi / 2, 0.0]])])
    assert share.shape == metres.shape == (2, 1) and share[0, 0] == metres[0, 0] == 0.0
    assert metres[1, 0] == pytest.approx(0.01) and share[1, 0] == pytest.approx(0.1)
