"""Tensorised evaluator (section 3.2) against the per-pixel reference, and its guarantees."""

import zlib

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from coursekit.pictures import operators as O
from coursekit.pictures import primitives as P
from coursekit.pictures.evaluate import render
from coursekit.pictures.genome import Chromosome, ChromosomeString, Genome
from coursekit.pictures.reference import render_reference
from coursekit.profile import sized

C = Chromosome
WINDOW = (-0.3, 0.2, 1.7, 1.1)
POINTWISE = [n for n in P.names() if n not in ("blur", "band-pass", "bump", "grad-mag", "grad-dir")]


def one(*chroms, h):
    """A single-string genome: the head and the start of the tail, the tail padded with y."""
    chroms = list(chroms) + [C("y")] * (2 * h + 1 - len(chroms))
    return Genome((ChromosomeString(h, tuple(chroms)),))


def mismatch(a, b, tol=1e-3):
    return float((np.abs(a - b) > tol).mean())


@pytest.mark.parametrize("name", P.names())
def test_each_primitive_matches_the_per_pixel_reference(name):
    rng = np.random.default_rng(zlib.crc32(name.encode()))
    terms = ["x", "y", "bw-noise", "color-noise", "radius"]
    worst = 0.0
    for _ in range(3):
        head = C.random(rng, name)
        tail = [C.random(rng, terms[rng.integers(len(terms))]) for _ in range(2)]
        g = one(head, *tail, h=1)
        a = render(g, (12, 10), window=WINDOW, time=0.7)[0]
        b = render_reference(g, (12, 10), window=WINDOW, time=0.7)
        worst = max(worst, mismatch(a, b))
    # float32 (torch) vs float64 (reference): bit operations and rounding may land on the other
    # side of a step, and dividing by ~1e-3 amplifies rounding; only on a few pixels
    assert worst <= (0.05 if name in ("and", "or", "xor", "round", "divide", "mod", "expt") else 0.0)


def test_random_genomes_match_the_reference():
    rng = np.random.default_rng(11)
    fractions = []
    for _ in range(30):
        g = Genome.random(rng, n_strings=2, head_length=3)
        a = render(g, (10, 12), window=WINDOW, time=0.4)[0]
        b = render_reference(g, (10, 12), window=WINDOW, time=0.4)
        fractions.append(mismatch(a, b))
    # chaotic genomes (mod, round, bits of large values) may differ at float32 rounding edges
    assert max(fractions) <= 0.1
    assert np.mean(np.array(fractions) == 0.0) >= 0.8


def test_hostile_genomes_stay_finite_in_unit_range():
    big, tiny = C("const", (3.4e38,)), C("const", (0.0,))  # the largest float32 a chromosome holds
    neg = C("const", (-1e30,))
    hostile = [
        one(C("divide"), C("log"), tiny, tiny, tiny, h=2),
        one(C("expt"), big, big, h=1),
        one(C("mod"), C("times"), big, neg, big, h=2),
        one(C("minus"), C("times"), big, big, big, h=2),
        one(C("warp-by", (0.5,)), C("bw-noise", (3, 1, 2)), big, h=1),
        one(C("blur", (0.02,)), C("expt"), big, neg, h=2),
        one(C("hsv-to-rgb"), big, h=1),
        one(C("swirl", (1e30, 1e-30)), C("turbulence", (1e30, 3, 0, 0)), h=1),
        one(C("blur", (3.4e38,)), C("band-pass", (-3.4e38,)), C("x"), h=2),  # wider than any picture
        one(C("grad-dir"), C("divide"), C("x"), tiny, tiny, h=2),
        one(C("xor"), big, neg, h=1),
    ]
    img = render(hostile, (16, 16))
    assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() <= 1.0


@pytest.mark.slow
def test_thousands_of_random_genomes_render_finite_in_unit_range():
    rng = np.random.default_rng(10_000)
    for _ in range(sized(classroom=20, ci=5)):  # batches of 500: 10,000 genomes, 2,500 on CI
        genomes = [Genome.random(rng, n_strings=int(rng.integers(1, 4)), head_length=int(rng.integers(1, 7)))
                   for _ in range(500)]
        img = render(genomes, (16, 16))
        assert img.shape == (500, 16, 16, 3) and img.dtype == np.float32
        assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() <= 1.0


def test_zoom_re_evaluates_instead_of_upscaling():
    rng = np.random.default_rng(5)
    smooth = [n for n in POINTWISE if n != "dissolve"]
    for _ in range(5):
        g = Genome.random(rng, n_strings=2, head_length=4, symbols=smooth)
        full = render(g, (32, 32))[0]
        quarter = render(g, (16, 16), window=(0.0, 0.0, 0.5, 0.5))[0]
        # the quarter window at half the pixels samples exactly the same world points
        assert mismatch(full[:16, :16], quarter, 1e-4) <= 0.01


def test_noise_is_deterministic_continuous_and_path_independent():
    n = C("bw-noise", (5.0, 17.25, 3.5))
    plain = render(one(n, h=1), 64)[0]
    again = render(one(n, h=1), 64)[0]
    assert np.array_equal(plain, again)
    # rotate by zero turns forces full coordinate fields (the gather path): same values
    via_gather = render(one(C("rotate", (0.0,)), n, h=1), 64)[0]
    assert np.abs(plain - via_gather).max() < 1e-5
    # continuous: neighbouring pixels 1/64 apart differ by far less than the value range
    assert np.abs(np.diff(plain[..., 0], axis=0)).max() < 0.2
    assert np.abs(np.diff(plain[..., 0], axis=1)).max() < 0.2
    # a different offset gives a different field
    other = render(one(C("bw-noise", (5.0, 99.0, 3.5)), h=1), 64)[0]
    assert np.abs(plain - other).mean() > 0.05


def test_type_promotion_scalar_vector_matrix():
    # scalar + vector = vector (a uniform colour)
    g = one(C("plus"), C("const", (0.25,)), C("color", (0.1, 0.2, 0.3)), h=1)
    img = render(g, 8)[0]
    assert np.allclose(img, [0.35, 0.45, 0.55], atol=1e-6)
    # vector * matrix = colour matrix: channel c = colour_c * x
    g = one(C("times"), C("color", (1.0, 0.5, 0.0)), C("x"), h=1)
    img = render(g, (4, 8))[0]
    xs = (np.arange(8) + 0.5) / 8
    assert np.allclose(img[2, :, 0], xs, atol=1e-6) and np.allclose(img[2, :, 1], 0.5 * xs, atol=1e-6)
    assert np.allclose(img[..., 2], 0.0)


def test_final_mapping_folds_values_into_unit_range():
    for value, expected in [(0.3, 0.3), (1.25, 0.75), (-0.4, 0.4), (2.5, 0.5), (-3.25, 0.75)]:
        img = render(one(C("const", (value,)), h=1), 2)[0]
        assert np.allclose(img, expected, atol=1e-6), value


def test_time_input_animates():
    g = one(C("time"), h=1)
    assert np.allclose(render(g, 4, time=0.3)[0], 0.3)
    d = one(C("dissolve", (0.0, 1.0, 3.0, 4.0)), C("const", (0.0,)), C("const", (1.0,)), h=1)
    fractions = [render(d, 64, time=t)[0].mean() for t in (0.1, 0.5, 0.9)]
    assert fractions[0] < fractions[1] < fractions[2]  # more of b as time goes on


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_batched_equals_one_by_one(seed):
    rng = np.random.default_rng(seed)
    a = Genome.random(rng, n_strings=2, head_length=4)
    b = Genome.random(rng, n_strings=2, head_length=4)
    # interpolation children share a's tree shape with new parameters: they batch together
    family = [a] + [O.random_interpolation(a, b, rng)[0] for _ in range(4)] + [b]
    together = render(family, (16, 16), batch=True)
    apart = np.concatenate([render(g, (16, 16), batch=False, workers=1) for g in family])
    assert np.array_equal(together, apart)  # batch invariance (module docstring of evaluate)


def test_render_validates_its_arguments():
    g = Genome.random(np.random.default_rng(0))
    with pytest.raises(ValueError, match="size"):
        render(g, (0, 4))
    with pytest.raises(ValueError, match="window"):
        render(g, 4, window=(0, 0, 0, 1))
    with pytest.raises(TypeError, match=r"genomes\[1\]"):
        render([g, "nope"], 4)
    assert render([], 4).shape == (0, 4, 4, 3)


def test_grad_dir_of_a_flat_field_is_flat_at_every_size_not_its_rounding_noise():
    # grad-mag of a ramp is the constant gain * slope away from the ramp's one jump; in float32 its
    # differences are rounding error, whose direction was noise at every size (a student's walk)
    flat = one(C("grad-dir"), C("grad-mag", (0.01538,)), C("ramp", (0.6445, 0.9036)), h=2)
    for size in (32, 128, 512):
        pic = render(flat, size)[0]
        # black but for the jump's line and the borders (measured: 74 % black at 32^2, 98 % at 512^2;
        # the noise was 12-18 % black, its neighbours 0.24-0.31 apart)
        assert np.mean(pic == 0.0) >= 0.6, size
        assert np.abs(np.diff(pic, axis=1)).mean() < 0.1, size
    turn = np.abs(render(flat, 24)[0] - render_reference(flat, 24))
    assert np.minimum(turn, 1.0 - turn).max() < 1e-3  # directions agree (a full turn is no change)
    # a faint slope along y (0.05 per world unit) still has its direction, a quarter turn; one
    # under the threshold (P.FLAT_GRADIENT) has none
    for gain, direction in ((0.05, 0.25), (0.5 * P.FLAT_GRADIENT, 0.0)):
        g = one(C("grad-dir"), C("times"), C("const", (gain,)), C("y"), h=2)
        for pic in (render(g, 16)[0], render_reference(g, 16)):
            assert np.allclose(pic, direction, atol=1e-5), (gain, pic.min(), pic.max())


def test_shared_subtrees_are_evaluated_once_with_the_same_result():
    # a clone made by transposition: the same subtree twice, under plain and warped coordinates
    noise = C("turbulence", (3.0, 3.0, 5.0, 6.0))
    warped = one(C("plus"), C("swirl", (2.0, 0.4)), noise, noise, noise, h=2)
    same = one(C("minus"), noise, noise, h=1)  # shared and cached: noise - noise = 0
    assert warped.expression().count("turbulence") == 2
    for g in (warped, same):
        a = render(g, (12, 10), window=WINDOW)[0]
        b = render_reference(g, (12, 10), window=WINDOW)
        assert mismatch(a, b) == 0.0
    assert np.all(render(same, 8)[0] == 0.0)


@pytest.mark.parametrize("window", [(-1e5, -1e5, 1e5, 1e5), (0.3, 0.3, 0.3 + 1e-7, 0.3 + 1e-7),
                                    (1.0, 1.0, 0.0, 0.0), (-3e5, 7.0, -2.9e5, 9.0)])
def test_extreme_windows_and_times_stay_finite(window):
    rng = np.random.default_rng(17)
    genomes = [Genome.random(rng, n_strings=2, head_length=4) for _ in range(60)]
    img = render(genomes, (12, 16), window=window, time=1e7)
    assert np.isfinite(img).all() and img.min() >= 0.0 and img.max() <= 1.0


@pytest.mark.parametrize("call, exc, pattern", [
    (lambda g: render(None, 8), TypeError, "genomes: expected a Genome or a list of them, got NoneType"),
    (lambda g: render(g, 8, time=None), ValueError, "time: None must be a finite number"),
    (lambda g: render(g, 8, time="1"), ValueError, "time: '1' must be a finite number"),
    (lambda g: render(g, 8, device="foo"), ValueError, "device: 'foo' is not a torch device"),
    (lambda g: render_reference(g, 4, time=float("nan")), ValueError, "time: nan must be a finite number"),
])
def test_bad_arguments_are_named(call, exc, pattern):
    with pytest.raises(exc, match=pattern):
        call(Genome.random(np.random.default_rng(0)))


def test_a_cuda_device_without_cuda_is_named(monkeypatch):
    import torch

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)  # the machine without CUDA, on any machine
    with pytest.raises(ValueError, match="device: 'cuda' needs CUDA, which this machine does not have"):
        render(Genome.random(np.random.default_rng(0)), 8, device="cuda")

