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


# ---- films a student wants to watch (issue 11, item 6) ----------------------------------------

import importlib  # noqa: E402

from scipy import ndimage  # noqa: E402

from coursekit.creatures.body import PRISMATIC, BodyTree  # noqa: E402
from coursekit.creatures.render import Clip, keyframes, render  # noqa: E402

R = importlib.import_module("coursekit.creatures.render")  # (coursekit.creatures.render is the function)
SIZE = (160, 120)


def _creature_pixels(img):
    """Pixels not of the background (the picture's most common colour: white for render, water
    blue for films), with no grid, trail or label drawn."""
    colours, counts = np.unique(img.reshape(-1, 3), axis=0, return_counts=True)
    return np.any(np.abs(img.astype(int) - colours[counts.argmax()]) > 5, axis=2)


def _touches_border(fg):
    return bool(fg[0].any() or fg[-1].any() or fg[:, 0].any() or fg[:, -1].any())


@pytest.fixture(scope="module")
def swims():
    """The Figure 1 snake and random creatures (seeds with prismatic joints, tall and wide bodies), 2 s each."""
    creatures = [Creature.figure1_snake()] + [Creature.random(np.random.default_rng(s), max_parts=16) for s in (1, 3, 5)]
    r = simulate(creatures, 2.0, record_every=4)
    return creatures, r


def test_the_follow_camera_keeps_every_part_in_the_picture_for_the_whole_clip(swims):
    creatures, r = swims
    for c, traj in zip(creatures, r.trajectory):
        clip = Clip(c, traj, frame_times=r.frame_times, size=SIZE, floor=False, trail=False, label=False)
        boxes = []
        for i, img in clip.film():
            fg = _creature_pixels(img)
            assert fg.any() and not _touches_border(fg), f"frame {i}: the creature is cut by the picture's edge"
            ys, xs = np.nonzero(fg)
            boxes.append((xs.min(), xs.max(), ys.min(), ys.max()))
        boxes = np.array(boxes)
        # the creature fills the picture (a fixed camera fitted to the whole path would leave it small) ...
        span = max((boxes[:, 1].max() - boxes[:, 0].min()) / SIZE[0], (boxes[:, 3].max() - boxes[:, 2].min()) / SIZE[1])
        assert span > 0.6
        # ... and stays near the middle of it in every frame
        centre = np.stack([(boxes[:, 0] + boxes[:, 1]) / 2 / SIZE[0], (boxes[:, 2] + boxes[:, 3]) / 2 / SIZE[1]], 1)
        assert np.abs(centre - 0.5).max() < 0.2


def test_the_fitted_distance_is_the_closest_that_keeps_the_creature_whole(swims):
    # moved 30 % closer along its line of sight, the same camera cuts the creature off
    creatures, r = swims
    clip = Clip(creatures[1], r.trajectory[1], frame_times=r.frame_times, size=SIZE, floor=False, trail=False, label=False)
    clip.eye = clip.centre + 0.7 * (clip.eye - clip.centre)
    assert any(_touches_border(_creature_pixels(img)) for _, img in clip.film())


def test_the_camera_follows_the_smoothed_centre_of_mass():
    snake = Creature.figure1_snake()
    r = simulate([snake], 3.0, record_every=3)
    clip = Clip(snake, r.trajectory[0], frame_times=r.frame_times, size=SIZE, follow=1.0)
    body = snake.expand().body
    com = np.stack([R.centre_of_mass(body, q) for q in r.trajectory[0]])
    np.testing.assert_allclose(clip.com, com)
    np.testing.assert_allclose(clip.com, r.com[0, ::3][: len(com)], atol=1e-9)  # the simulator's centre of mass
    # smoothing keeps the path's mean (a Gaussian's weights sum to one) and removes the stroke's wobble
    assert np.linalg.norm(clip.follow.mean(0) - com.mean(0)) < 0.02 * np.ptp(com, axis=0).max() + 1e-9
    assert np.abs(np.diff(clip.follow, 2, axis=0)).sum() < np.abs(np.diff(com, 2, axis=0)).sum()
    exact = Clip(snake, r.trajectory[0], frame_times=r.frame_times, size=SIZE, follow=0.0)
    np.testing.assert_array_equal(exact.follow, exact.com)


def _slid_out(q=0.3):
    body = BodyTree(parent=[-1, 0], half_extents=[[0.2, 0.1, 0.1], [0.1, 0.08, 0.08]], joint_type=[0, PRISMATIC],
                    joint_axis=[[0, 0, 0], [1, 0, 0]], joint_pos_parent=[[0, 0, 0], [0.2, 0, 0]],
                    joint_pos_child=[[0, 0, 0], [-0.1, 0, 0]], joint_rot=[np.eye(3)] * 2, limits=[[0, 0], [-0.5, 0.5]],
                    gain=[0, 1], strength=[0, 1])
    return body, np.array([q])


def test_a_slid_out_part_is_drawn_joined_to_its_parent():
    body, q = _slid_out(0.3)
    img = render(body, q=q, size=SIZE, joint_axes=False)
    labels, n = ndimage.label(_creature_pixels(img), structure=np.ones((3, 3)))
    assert n == 1  # the slider rod joins the boxes 0.3 m apart
    grey = (np.abs(img.astype(int) - 110) < 25).all(axis=2)
    assert grey.sum() > 20  # and the rod is drawn


def test_every_part_of_random_creatures_is_drawn_joined_to_the_rest(swims):
    creatures, r = swims
    for c, traj in zip(creatures, r.trajectory):
        clip = Clip(c, traj[::4], size=SIZE, floor=False, trail=False, label=False)
        for i, img in clip.film():
            assert ndimage.label(_creature_pixels(img), structure=np.ones((3, 3)))[1] == 1, f"frame {i}: a part looks detached"


def test_the_trail_draws_the_path_so_far():
    snake = Creature.figure1_snake()
    r = simulate([snake], 2.0, record_every=3)
    clip = Clip(snake, r.trajectory[0], frame_times=r.frame_times, size=(240, 180), floor=False, label=False)
    orange = lambda img: ((img[..., 0] > 200) & (np.abs(img[..., 1].astype(int) - 85) < 40) & (img[..., 2] < 60)).sum()  # noqa: E731
    first, last = [img for _, img in clip.film([0, len(clip) - 1])]
    assert orange(first) < 10 < orange(last)  # nothing yet at t = 0; a path by the end
    clip.trail = False
    assert orange(next(clip.film([len(clip) - 1]))[1]) < 10


def test_the_grid_stays_in_the_picture_when_a_swimmer_rises_out_of_a_floors_view():
    """A champion that swims upwards climbs metres above any floor below its start: the grid is then a
    wall behind it holding its path, in view in every frame; a swimmer that stays level keeps a floor."""
    from coursekit.creatures.champions import hall_of_fame

    riser = next(c.creature for c in hall_of_fame() if c.name.startswith("Sims-scale seed-2"))
    snake = Creature.figure1_snake()
    r = simulate([riser, snake], 10.0, record_every=20)
    assert np.ptp(r.com[0][:, 2]) > 3.0  # it climbs
    grid = lambda img: (np.abs(img.astype(int) - (127, 167, 201)).sum(axis=2) < 80).mean()  # noqa: E731  (shaded lines)
    clip = Clip(riser, r.trajectory[0], frame_times=r.frame_times, size=(160, 120), label=False, trail=False)
    assert abs(clip.floor[1][2]) < 0.9  # not a floor
    assert all(grid(img) > 0.02 for _, img in clip.film([0, len(clip) // 2, len(clip) - 1]))
    level = Clip(snake, r.trajectory[1], frame_times=r.frame_times, size=(160, 120), label=False, trail=False)
    assert np.array_equal(np.abs(level.floor[1]), [0.0, 0.0, 1.0])  # a floor
    assert all(grid(img) > 0.02 for _, img in level.film([0, len(level) - 1]))


def test_the_key_frame_strip_is_figure_3(tmp_path):
    snake = Creature.figure1_snake()
    r = simulate([snake], 2.0, record_every=3)
    strip = keyframes(snake, r.trajectory[0], n=4, size=(120, 90), gap=4, frame_times=r.frame_times, stroke=False)
    assert strip.shape == (90, 4 * 120 + 3 * 4, 3) and strip.dtype == np.uint8
    panels = [strip[:, k * 124: k * 124 + 120] for k in range(4)]
    for k in range(3):
        assert (strip[:, k * 124 + 120: (k + 1) * 124] == 200).all()  # the gaps
    for a, b in zip(panels, panels[1:]):
        assert np.mean(np.any(a != b, axis=2)) > 0.01  # time moves on from panel to panel
    water = np.array([int(R.WATER[k: k + 2], 16) for k in (1, 3, 5)])
    assert all(np.mean(np.abs(p.astype(int) - water).sum(axis=2) < 6) > 0.5 for p in panels)  # swimming in water, not on paper
    # without the stroke phases: evenly spaced, as the film shows them
    clip = Clip(snake, r.trajectory[0], frame_times=r.frame_times, size=(120, 90))
    picks = np.round(np.linspace(0, len(clip) - 1, 4)).astype(int)
    for panel, (_, img) in zip(panels, clip.film(picks)):
        np.testing.assert_array_equal(panel, img)
    path = keyframes(snake, r.trajectory[0], tmp_path / "fig3.png", n=3, size=(120, 90), frame_times=r.frame_times)
    assert Image.open(path).size == (3 * 120 + 2 * 4, 90)
    with pytest.raises(ValueError, match="n: must be an integer"):
        keyframes(snake, r.trajectory[0][:2], n=3)


def test_one_pass_writes_an_mp4_that_decodes_to_the_gifs_frames(tmp_path):
    import imageio_ffmpeg

    snake = Creature.figure1_snake()
    r = simulate([snake], 1.0, record_every=3)
    n = len(r.trajectory[0])
    mp4, gif = animate(snake, r.trajectory[0], [tmp_path / "swim.mp4", tmp_path / "swim.gif"], fps=20, size=(96, 72),
                       frame_times=r.frame_times)
    reader = imageio_ffmpeg.read_frames(str(mp4))
    meta = next(reader)
    decoded = [np.frombuffer(f, np.uint8).reshape(72, 96, 3) for f in reader]
    assert tuple(meta["size"]) == (96, 72) and len(decoded) == n and abs(meta["fps"] - 20) < 1e-6
    g = Image.open(gif)
    assert g.n_frames == n and g.info["duration"] == 50 and g.info["loop"] == 0
    for i in (0, n - 1):
        g.seek(i)
        # the same picture (H.264 and a 255-colour palette each lose a little)
        assert np.abs(np.asarray(g.convert("RGB"), int) - decoded[i]).mean() < 8
    assert sorted(p.name for p in tmp_path.iterdir()) == ["swim.gif", "swim.mp4"]  # no temporaries left


def test_film_arguments_are_checked(tmp_path):
    snake = Creature.figure1_snake()
    traj = simulate([snake], 0.5, record_every=3).trajectory[0]
    with pytest.raises(ValueError, match="even width and height"):
        animate(snake, traj, tmp_path / "x.mp4", size=(97, 72))
    with pytest.raises(ValueError, match="must end in one of .gif, .mp4"):
        animate(snake, traj, tmp_path / "x.avi")
    with pytest.raises(ValueError, match="frame_times"):
        Clip(snake, traj, frame_times=np.zeros(len(traj)))
    with pytest.raises(ValueError, match="follow"):
        Clip(snake, traj, follow=-1.0)
    assert not list(tmp_path.iterdir())


def test_one_plotter_draws_every_picture_and_keeps_nothing_from_the_last():
    snake, other = Creature.figure1_snake(), Creature.random(np.random.default_rng(4), max_parts=16)
    first = render(snake, size=SIZE)
    plotter = R._SHARED[__import__("os").getpid()]
    render(other, size=(200, 100))
    again = render(snake, size=SIZE)
    assert R._SHARED[__import__("os").getpid()] is plotter  # the same plotter (one GL context) ...
    np.testing.assert_array_equal(first, again)  # ... and the picture bit for bit the same: nothing left over


def test_long_films_show_a_progress_bar_that_ends_full_and_short_ones_none(tmp_path, capsys):
    snake = Creature.figure1_snake()
    still = np.tile(np.r_[[0.0, 0, 0, 1], np.zeros(8)], (R.BAR_FRAMES, 1))  # at rest, BAR_FRAMES frames
    animate(snake, still[:5], tmp_path / "short.gif", size=(48, 36))  # a short clip: no bar by default
    keyframes(snake, still, n=3, size=(48, 36))  # 3 frames filmed of 60: no bar
    assert capsys.readouterr().err == ""
    animate(snake, still, tmp_path / "long.gif", size=(48, 36))
    bar = capsys.readouterr().err.rstrip().split("\r")[-1]
    assert f"{R.BAR_FRAMES}/{R.BAR_FRAMES}" in bar and "100%" in bar, bar  # ends in the finished state
    keyframes(snake, still, n=3, size=(48, 36), progress=True)
    assert "3/3" in capsys.readouterr().err
    animate(snake, still, tmp_path / "quiet.gif", size=(48, 36), progress=False)
    assert capsys.readouterr().err == ""
