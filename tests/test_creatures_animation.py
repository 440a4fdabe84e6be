"""Recorded trajectories and swim animations."""

import numpy as np
import pytest
from PIL import Image

from coursekit.creatures import Creature, simulate
from coursekit.creatures.render import animate


def test_recorded_frames_are_the_simulated_states_and_animate_to_a_gif(tmp_path):
    snake = Creature.figure1_snake()
    r = simulate([snake, Creature.random(np.random.default_rng(5))], 1.0, dt=1 / 60, settle=0.1, record_every=6)
    plain = simulate([snake, Creature.random(np.random.default_rng(5))], 1.0, dt=1 / 60, settle=0.1)
    np.testing.assert_array_equal(r.fitness, plain.fitness)  # recording changes nothing
    assert len(r.trajectory) == 2 and r.trajectory[0].shape == (11, 7 + 5)
    np.testing.assert_array_equal(r.trajectory[0][-1], r.qpos[0])  # the last frame is the final state
    np.testing.assert_allclose(r.frame_times, np.arange(11) * 0.1)
    assert np.all(np.isfinite(r.trajectory[1])) and r.trajectory[1].shape[0] == 11

    path = animate(snake, r.trajectory[0], tmp_path / "swim.gif", fps=10, size=(96, 72))
    gif = Image.open(path)
    assert gif.n_frames == 11 and gif.size == (96, 72)
    gif.seek(5)
    frame = np.asarray(gif.convert("RGB"))
    assert (frame.std(axis=(0, 1)) > 5).any()  # something is drawn, not a blank frame
    assert not list(tmp_path.glob("swim.*.gif"))  # no temporary file left behind


def test_bad_arguments_are_named(tmp_path):
    snake = Creature.figure1_snake()
    with pytest.raises(ValueError, match="record_every"):
        simulate([snake], 1.0, record_every=-1)
    with pytest.raises(ValueError, match="qpos"):
        animate(snake, np.zeros((3, 4)), tmp_path / "x.gif")
    with pytest.raises(ValueError, match="fps"):
        animate(snake, np.tile([0.0, 0, 0, 1] + [0] * 8, (3, 1)), tmp_path / "x.gif", fps=0)
