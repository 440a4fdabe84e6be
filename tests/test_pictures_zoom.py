"""Zooming and panning a picture with blurs: a window equals the crop of a larger render.

``blur`` and ``band-pass`` read their argument beyond the pixel they compute; both evaluators
evaluate it on the grid extended by the filter's reach beyond the window
(:func:`coursekit.pictures.primitives.padding`), as a renderer filters, so the window's border
pixels see the picture beyond it, not its own border replicated.

Tolerance: the zoomed window below is aligned with the large render's pixel grid, so it samples
the very same world points (its coordinates agree to float32 rounding, 6e-8). What is left is
rounding: continuous primitives differ by about 1e-6, far under the 1e-3 allowed per pixel (a
quarter of an 8-bit level), and a step (``round``, ``mod``, bit operations, ``dissolve``
cells, ``ramp``) may flip a pixel whose value lies within rounding of the step, hence the 1 % of
pixels allowed to differ more (the zoom test of ``test_pictures_render.py`` allows the same).
Before the extension the border pixels within the filter's reach differed: a third of the
pixels of such windows on average (``benchmarks/NOTES.md``).
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.pictures import primitives as P
from coursekit.pictures.evaluate import render
from coursekit.pictures.genome import Chromosome as C
from coursekit.pictures.genome import ChromosomeString, Genome
from coursekit.pictures.reference import render_reference

FILTERS = {"blur", "band-pass"}
# the gradients take one-sided differences on the window's edges (no extension): left out here
SYMBOLS = [n for n in P.names() if n not in ("bump", "grad-mag", "grad-dir")]
BIG, SMALL = 96, 32


def one(*chroms, h):
    """A single-string genome: the head and the start of the tail, the tail padded with y."""
    chroms = list(chroms) + [C("y")] * (2 * h + 1 - len(chroms))
    return Genome((ChromosomeString(h, tuple(chroms)),))


def holds(genome: Genome, names: set) -> bool:
    def walk(n):
        return n.symbol in names or any(walk(c) for c in n.children)
    return walk(genome.decode())


def filtered(rng: np.random.Generator) -> Genome:
    """A random genome whose picture holds a blur or a band-pass."""
    while True:
        g = Genome.random(rng, n_strings=int(rng.integers(1, 4)), head_length=int(rng.integers(2, 6)),
                          symbols=SYMBOLS)
        if holds(g, FILTERS):
            return g


def zoom_and_crop(genomes, top: int, left: int, big: int = BIG, small: int = SMALL):
    """The ``small`` x ``small`` window at pixel (top, left) of a ``big`` render of the unit
    square: rendered zoomed, and cropped out of the big render."""
    window = (left / big, top / big, (left + small) / big, (top + small) / big)
    zoomed = render(genomes, small, window=window, workers=1)
    crops = render(genomes, big, workers=1)[:, top:top + small, left:left + small]
    return zoomed, crops


def off(a, b, tol=1e-3):
    return float((np.abs(a - b) > tol).mean())


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), top=st.integers(0, BIG - SMALL), left=st.integers(0, BIG - SMALL))
def test_a_zoomed_window_of_a_blurred_picture_is_the_crop_of_a_larger_render(seed, top, left):
    g = filtered(np.random.default_rng(seed))
    zoomed, crop = zoom_and_crop([g], top, left)
    assert off(zoomed[0], crop[0]) <= 0.01, g.expression()


@pytest.mark.parametrize("genome", [
    one(C("band-pass", (0.03,)), C("color-noise", (7.0, 10.0, 20.0)), h=1),
    one(C("blur", (0.05,)), C("turbulence", (5.0, 3.0, 40.0, 9.0)), h=1),
    one(C("band-pass", (0.02,)), C("blur", (0.03,)), C("bw-noise", (9.0, 3.0, 4.0)), h=2),  # nested
    one(C("warp-by", (0.3,)), C("blur", (0.04,)), C("bw-noise", (3.0, 1.0, 2.0)), C("color-noise", (4.0, 5.0, 6.0)),
        h=2),  # under a warp: the warp is made again on the extended grid
    one(C("rotate", (0.2,)), C("band-pass", (0.025,)), C("warp-swirl", (3.0,)), C("color-noise", (6.0, 1.0, 9.0)),
        C("radius"), h=3),
], ids=["band-pass", "blur", "nested", "warp-by", "rotate-warp-swirl"])
def test_the_border_pixels_of_a_zoomed_filter_see_the_picture_beyond_the_window(genome):
    zoomed, crop = zoom_and_crop([genome], 40, 8)
    assert np.abs(zoomed[0] - crop[0]).max() < 1e-3
    # and panned by a pixel, the window shifts by a pixel
    panned = render(genome, SMALL, window=(9 / BIG, 40 / BIG, (9 + SMALL) / BIG, (40 + SMALL) / BIG), workers=1)[0]
    assert np.abs(panned[:, :-1] - zoomed[0][:, 1:]).max() < 1e-3


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), batch=st.booleans())
def test_extended_grids_in_waves_give_the_pictures_of_genome_by_genome_evaluation_bit_for_bit(seed, batch):
    # filters under warps extend warped grids, which waves make in a later wave
    rng = np.random.default_rng(seed)
    pop = [filtered(rng) for _ in range(6)]
    pop.append(one(C("warp-swirl", (2.0,)), C("rotate", (0.1,)), C("band-pass", (0.03,)), C("blur", (0.02,)),
                   C("warp-by", (0.2,)), C("color-noise", (3.0, 1.0, 2.0)), C("bw-noise", (5.0, 6.0, 7.0)),
                   C("radius"), h=5))
    window = (0.2, 0.3, 0.45, 0.5)  # zoomed: blurs of several pixels
    apart = render(pop, (24, 20), window=window, workers=1, group=False)
    waves = render(pop, (24, 20), window=window, workers=1, group=True, batch=batch)
    assert np.array_equal(apart, waves)


def test_extended_filters_match_the_per_pixel_reference():
    window = (0.3, 0.35, 0.5, 0.55)  # a pixel of 1/80: sigma 0.03 is 2.4 pixels, its band-pass 7.2
    genomes = [one(C("blur", (0.03,)), C("bw-noise", (6.0, 2.0, 3.0)), h=1),
               one(C("band-pass", (0.03,)), C("color-noise", (5.0, 7.0, 1.0)), h=1),
               one(C("grad-mag", (0.05,)), C("blur", (0.02,)), C("warp-by", (0.3,)), C("x"), C("bw-noise", (4.0, 1.0, 1.0)),
                   h=3)]
    for g in genomes:
        a = render(g, 16, window=window, workers=1)[0]
        b = render_reference(g, 16, window=window)
        assert np.abs(a - b).max() < 1e-4, g.expression()


def test_extension_is_bounded_by_the_picture_and_follows_one_rule():
    # a blur wider than the window extends the grid by at most the picture's size on each side
    assert P.padding("blur", [10.0], 1 / 32, 1 / 32, 32, 32) == (32, 32)
    assert P.padding("blur", [10.0], 1 / 32, 1 / 32, 32, 32, pad=(32, 32)) == (0, 0)
    assert P.padding("blur", [float("inf")], 1 / 32, 1 / 32, 32, 32) == (32, 32)  # a kernel's own overflow
    assert P.padding("blur", [float("nan")], 1 / 32, 1 / 32, 32, 32) == (0, 0)
    assert P.padding("plus", [], 1 / 32, 1 / 32, 32, 32) == (0, 0)
    # nor beyond the largest picture: a poster of 4096 x 4096 is not extended, one of 3000 by 548
    assert P.padding("blur", [1.0], 1 / 4096, 1 / 4096, 4096, 4096) == (0, 0)
    assert P.padding("blur", [1.0], 1 / 3000, 1 / 3000, 3000, 3000) == (548, 548)
    # otherwise at least the reach of the three box passes (3 r pixels), rounded up to a step
    rows, cols = P.padding("band-pass", [0.03], 1 / 64, 1 / 128, 64, 128)
    assert rows >= 3 * 11 and cols >= 3 * 5 and rows % 4 == 0 and cols % 8 == 0
    # a hostile blur still renders, finite and in range
    g = one(C("band-pass", (3e38,)), C("blur", (1e30,)), C("bw-noise", (6.0, 2.0, 3.0)), h=2)
    pic = render(g, 24, window=(0.4, 0.4, 0.41, 0.41), workers=1)
    assert np.isfinite(pic).all() and 0.0 <= pic.min() and pic.max() <= 1.0
