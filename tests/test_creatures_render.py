"""Off-screen pyvista pictures of creatures."""

import os

import numpy as np
import pytest

from coursekit.creatures import Creature
from coursekit.creatures.render import render


def _foreground(img):
    return np.any(img != 255, axis=2)  # white background


def test_snake_render_shows_the_creature(tmp_path):
    c = Creature.figure1_snake()
    img = render(c, size=(320, 240))
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    fg = _foreground(img)
    assert 0.03 < fg.mean() < 0.9  # visible, and framed (not filling the whole image)
    ys, xs = np.nonzero(fg)
    assert xs.min() > 0 and xs.max() < 319  # the camera frames the whole body
    # depth colouring: the boxes show several distinct colours (root dark to legs bright)
    colours = {tuple(int(v) // 32 for v in px) for px in img[fg]}
    assert len(colours) >= 4
    # joint axes are drawn in red
    red = (img[..., 0] > 200) & (img[..., 1] < 60) & (img[..., 2] < 60)
    assert red.sum() > 20
    plain = render(c, size=(320, 240), joint_axes=False)
    assert ((plain[..., 0] > 200) & (plain[..., 1] < 60) & (plain[..., 2] < 60)).sum() < red.sum() / 4


def test_render_to_file_is_atomic_and_readable(tmp_path):
    import matplotlib.image as mpimg

    p = tmp_path / "snake.png"
    assert render(Creature.figure1_snake(), p, size=(160, 120)) == p
    assert os.listdir(tmp_path) == ["snake.png"]
    img = mpimg.imread(p)
    assert img.shape[:2] == (120, 160)


def test_pose_changes_the_picture_and_bad_input_is_refused():
    c = Creature.figure1_snake()
    ph = c.expand()
    rest = render(ph, size=(160, 120))
    bent = render(ph, size=(160, 120), q=np.full(ph.body.n_joints, 0.5))
    assert np.mean(np.any(rest != bent, axis=2)) > 0.01
    with pytest.raises(TypeError, match="Creature, Phenotype or BodyTree"):
        render("snake")
    with pytest.raises(ValueError, match="render.size"):
        render(c, size=(0, 10))
    for size in (64, None):
        with pytest.raises(ValueError, match="render.size: need \\(width, height\\)"):
            render(c, size=size)
    for name, angle in (("azimuth", float("nan")), ("elevation", None), ("azimuth", "x")):
        with pytest.raises(ValueError, match=f"{name}: must be a finite number of degrees"):
            render(c, size=(32, 24), **{name: angle})


def test_a_picture_file_must_be_named_png(tmp_path):
    """render writes PNG: a name ending in .jpg would hold PNG data under a JPEG name."""
    with pytest.raises(ValueError, match="path: a picture is written as PNG; give a file name ending in .png"):
        render(Creature.figure1_snake(), tmp_path / "snake.jpg", size=(32, 24))
    assert not list(tmp_path.iterdir())
    assert render(Creature.figure1_snake(), tmp_path / "snake.PNG", size=(32, 24)).is_file()


def test_torch_compile_machinery_after_a_render_does_not_crash_the_process():
    # CUDA builds of torch import triton with torch._dynamo; triton's LLVM loaded after Mesa's
    # (the off-screen renderer) crashed the process (torch 2.14.1+cu130: a segmentation fault in
    # test_pictures_grouped, run after a creature render in the same worker)
    import subprocess
    import sys

    code = ("from coursekit.creatures import Creature, render; render(Creature.figure1_snake(), size=(64, 48)); "
            "import torch._dynamo; print('ok')")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout.strip().endswith("ok"), (r.returncode, r.stderr[-2000:])
