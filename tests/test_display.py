"""Rich display: what a notebook shows for a Genome, a Creature, a History and a creature view."""

from __future__ import annotations

import base64
import importlib
import importlib.util
import io
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from PIL import Image

from coursekit.creatures import Creature, render
from coursekit.creatures.render import frame, view
from coursekit.ga.history import History
from coursekit.pictures import Genome
from coursekit.pictures import render as render_pictures

render_module = importlib.import_module("coursekit.creatures.render")  # the package's `render` is the function


def decode(png: bytes) -> np.ndarray:
    assert png.startswith(b"\x89PNG\r\n\x1a\n")
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5), st.integers(1, 8))
def test_a_genomes_repr_is_one_short_line_starting_its_expression(seed, strings, head):
    g = Genome.random(np.random.default_rng(seed), n_strings=2 * strings - 1, head_length=head)
    text = repr(g)
    assert "\n" not in text and len(text) <= 130
    assert text.startswith(f"Genome({2 * strings - 1} string")
    expr = g.expression()
    assert expr[:50] in text


def test_a_genome_displays_as_its_picture():
    g = Genome.random(np.random.default_rng(3))
    shown = decode(g._repr_png_())
    want = np.round(render_pictures([g], size=(Genome.REPR_SIZE, Genome.REPR_SIZE), workers=1)[0] * 255).astype(np.uint8)
    assert shown.shape == (Genome.REPR_SIZE, Genome.REPR_SIZE, 3)
    assert np.array_equal(shown, want)


def test_a_creatures_summary_counts_its_expanded_body():
    c = Creature.figure1_snake()
    body = c.expand().body
    s = c.summary()
    assert s == {"parts": body.n_bodies, "joints": body.n_bodies - 1, "dof": body.n_bodies - 1,
                 "mass": pytest.approx(float(body.mass.sum())), "neurons": c.expand().brain.n_neurons, "nodes": 2}
    assert s["parts"] == 6  # Figure 1: four segments and two legs


def test_a_creature_displays_once_as_picture_and_summary(monkeypatch):
    """IPython asks the bundle once (one rendering) and gets the picture, the HTML and a short text."""
    from IPython.core.formatters import DisplayFormatter

    calls = []
    real = render_module.render
    monkeypatch.setattr(render_module, "render", lambda *a, **k: calls.append(1) or real(*a, **k))
    c = Creature.figure1_snake()
    data, _ = DisplayFormatter().format(c)
    assert len(calls) == 1
    assert data["text/plain"] == "Creature(2 nodes, 1 brain neuron)"
    picture = decode(data["image/png"])
    assert picture.shape == (Creature.REPR_SIZE[1], Creature.REPR_SIZE[0], 3)
    assert base64.b64encode(data["image/png"]).decode() in data["text/html"]
    assert "6 parts, 5 joints, 5 DOF" in data["text/html"]
    assert c._repr_png_() == data["image/png"]  # the same picture through either method


@settings(max_examples=15, deadline=None)
@given(st.integers(0, 2**32 - 1))
def test_a_creatures_repr_is_short(seed):
    c = Creature.random(np.random.default_rng(seed))
    assert len(repr(c)) < 60 and repr(c).startswith(f"Creature({len(c.nodes)} node")


def test_a_history_plots_itself():
    h = History()
    assert h._repr_png_() is None and repr(h) == "History(no generations)"
    for g, f in enumerate([[0.1, 0.2], [0.3, 0.5], [0.4, 0.45]]):
        h.record(g, f, 1.0 / (g + 1), 2)
    assert repr(h) == "History(3 generations, best 0.5 in generation 1)"
    picture = decode(h._repr_png_())
    assert picture.shape == (350, 600, 3)
    assert len(np.unique(picture.reshape(-1, 3), axis=0)) > 10  # lines, band and text, not a blank canvas


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(-180, 180), st.floats(-80, 80), st.floats(0.5, 2.5))
def test_framing_keeps_every_point_in_view_and_fills_it(seed, azimuth, elevation, aspect):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(rng.integers(2, 40), 3)) * rng.uniform(0.01, 3, size=3) + rng.normal(size=3)
    eye, centre, up = frame(points, azimuth, elevation, aspect, margin=0.9)
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, up)
    p = points - eye
    depth = p @ forward
    radius = np.linalg.norm(points - 0.5 * (points.min(0) + points.max(0)), axis=1).max()
    assert np.all(depth >= 0.25 * radius - 1e-9)  # all in front of the camera, none at the eye
    t = np.tan(np.radians(15.0))
    x, y = (p @ right) / depth / (t * aspect), (p @ up) / depth / t  # in [-1, 1] inside the picture
    reach = max(np.abs(x).max(), np.abs(y).max())
    assert reach <= 0.9 + 1e-9  # inside the frame's 90 %
    if depth.min() > 0.25 * radius + 1e-9:  # unless a point close to the line of sight holds the camera back,
        assert reach == pytest.approx(0.9, abs=1e-9)  # out to it in one direction
    binding = x if np.abs(x).max() >= np.abs(y).max() else y
    assert abs(binding.max() + binding.min()) < 0.05  # centred: out to it on both sides


def test_the_figure1_snake_fills_its_picture():
    """The issue's complaint: the snake was drawn small in a large empty frame."""
    image = render(Creature.figure1_snake(), size=(480, 360))
    drawn = np.argwhere(np.any(image < 250, axis=2))
    (top, left), (bottom, right) = drawn.min(0), drawn.max(0)
    assert max((right - left + 1) / 480, (bottom - top + 1) / 360) >= 0.85


def test_the_static_view_is_the_picture():
    v = view(Creature.figure1_snake(), size=(200, 150))
    assert v.widget is None
    assert decode(v._repr_mimebundle_()["image/png"]).shape == (150, 200, 3)


def test_the_interactive_view_degrades_to_the_picture_without_its_backend(monkeypatch):
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "trame_pyvista" else real(name, *a))
    with pytest.warns(UserWarning, match=r"pip install 'coursekit\[interactive\]'"):
        v = view(Creature.figure1_snake(), interactive=True, size=(200, 150))
    assert v.widget is None and set(v._repr_mimebundle_()) == {"image/png", "text/plain"}


def test_the_interactive_view_is_a_widget_that_carries_the_picture():
    if importlib.util.find_spec("trame_pyvista") is None:
        pytest.fail("the [test] extra installs pyvista's notebook backend (pyvista[jupyter])")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # VTK's "bad X server connection" on a machine without a display
        v = view(Creature.figure1_snake(), interactive=True, size=(200, 150))
    bundle = v._repr_mimebundle_()
    assert "application/vnd.jupyter.widget-view+json" in bundle  # a widget front-end shows the 3D view
    assert decode(bundle["image/png"]).shape == (150, 200, 3)  # any other shows the picture
