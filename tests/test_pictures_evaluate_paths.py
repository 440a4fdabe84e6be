"""The fast paths of the tensorised evaluator (section 3.2) agree with their definitions.

The evaluator picks among several implementations of one primitive (noise: small matrices,
gathered rows and columns, or grid sampling; pixmap: separable sampling, cached, or grid
sampling; blur: banded tiles or one dense matrix). Each path is checked here against the
per-pixel reference or an independent numpy construction, so a path that is only taken for
some sizes, windows or frequencies cannot drift.
"""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.pictures import context as Cx
from coursekit.pictures.kernels import pointwise as KP
from coursekit.pictures import operators as O
from coursekit.pictures.evaluate import render
from coursekit.pictures.genome import Chromosome, ChromosomeString, Genome
from coursekit.pictures.reference import render_reference

C = Chromosome


def one(*chroms, h):
    """A single-string genome: the head and the start of the tail, the tail padded with y."""
    chroms = list(chroms) + [C("y")] * (2 * h + 1 - len(chroms))
    return Genome((ChromosomeString(h, tuple(chroms)),))


def mismatch(a, b, tol=1e-3):
    return float((np.abs(a - b) > tol).mean())


FLOATS = st.one_of(st.floats(width=32, allow_nan=True, allow_infinity=True),
                   st.sampled_from([0.0, -0.0, 1e-3, -1e-3, 1e6, -1e6]))


@settings(max_examples=60, deadline=None)
@given(a=st.lists(FLOATS, min_size=6, max_size=6), b=st.lists(FLOATS, min_size=2, max_size=2),
       mask=st.lists(st.booleans(), min_size=6, max_size=6))
def test_bit_select_is_torch_where_bit_for_bit(a, b, mask):
    a = torch.tensor(a, dtype=torch.float32).reshape(1, 1, 2, 3)
    b = torch.tensor(b, dtype=torch.float32).reshape(1, 1, 2, 1)  # broadcast like a scalar column
    m = torch.tensor(mask).reshape(1, 1, 2, 3)
    got = KP._select(m, a, b)
    want = torch.where(m, b, a)
    assert torch.equal(got.view(torch.int32), want.view(torch.int32))


@settings(max_examples=60, deadline=None)
@given(v=st.lists(st.floats(-1e6, 1e6, width=32), min_size=1, max_size=50))
def test_fold_is_the_period_two_mirror(v):
    got = Cx.fold(torch.tensor(v, dtype=torch.float32)).double().numpy()
    m = np.mod(np.asarray(v, dtype=np.float64), 2.0)
    want = np.where(m > 1.0, 2.0 - m, m)
    assert np.all((got >= 0.0) & (got <= 1.0))
    assert np.abs(got - want).max() <= 1e-6


@pytest.mark.parametrize("n,r", [(256, 1), (256, 5), (256, 23), (100, 3), (40, 12), (7, 2)])
def test_banded_blur_tiles_are_three_replicate_box_passes(n, r):
    # independent construction: three edge-padded moving averages applied to each unit vector
    def box(v):
        p = np.pad(v, r, mode="edge")
        return np.convolve(p, np.full(2 * r + 1, 1.0 / (2 * r + 1)), mode="valid")

    want = np.stack([box(box(box(e))) for e in np.eye(n)], axis=1)  # column j = response to e_j
    dense = np.zeros((n, n))
    row = 0
    for lo, hi, m in Cx.Resources.on("cpu").box_matrix(n, r):
        assert lo >= 0 and hi <= n
        dense[row:row + m.shape[0], lo:hi] = m.numpy()
        row += m.shape[0]
    assert row == n
    assert np.abs(dense - want).max() < 1e-6


@pytest.mark.parametrize("freq,window", [(3.0, (0.0, 0.0, 1.0, 1.0)),  # few cells: matrices
                                         (11.0, (-2.0, 1.0, 6.0, 9.0))])  # 88 cells: gathers
def test_noise_paths_match_the_reference(freq, window):
    n = C("bw-noise", (freq, 17.25, 3.5))
    plain = one(n, h=1)
    rotated = one(C("rotate", (0.0,)), n, h=1)  # full coordinate fields: the grid-sampling path
    c = one(C("color-noise", (freq, 200.5, 99.0)), h=1)
    t = one(C("turbulence", (freq / 4, 4.0, 7.0, 250.0)), h=1)
    for g in (plain, rotated, c, t):
        a = render(g, (20, 24), window=window)[0]
        b = render_reference(g, (20, 24), window=window)
        assert np.abs(a - b).max() < 1e-4, g.expression()


def test_pixmap_paths_and_cache_agree_with_the_reference():
    cache = Cx.Resources.on("cpu")
    pic = C("pixmap", (1.5,))
    plain, rotated = one(pic, h=1), one(C("rotate", (0.0,)), pic, h=1)
    negative = one(C("invert"), pic, h=1)
    window = (-0.2, 0.1, 1.3, 0.9)
    first = render(plain, (18, 22), window=window)[0]
    render(negative, (18, 22), window=window)  # reads the cached picture
    again = render(plain, (18, 22), window=window)[0]  # must not see the inversion
    assert np.array_equal(first, again)
    assert np.abs(render(rotated, (18, 22), window=window)[0] - first).max() < 1e-5
    assert mismatch(first, render_reference(plain, (18, 22), window=window), 1e-4) == 0.0
    for k in range(40):  # many windows: the cache stays within its byte budget
        render(plain, 64, window=(k, 0.0, k + 1.0, 1.0))
    assert 0 < cache._sampled_bytes <= Cx.CACHE_BYTES
    assert cache._sampled_bytes == sum(v.numel() * v.element_size() for v in cache._sampled.values())


def test_protected_divide_follows_the_reference_at_tiny_and_signed_zero_divisors():
    for b in (0.0, -0.0, 5e-4, -5e-4, 1e-3, -2e-3):
        g = one(C("divide"), C("const", (0.0004,)), C("const", (b,)), h=1)
        assert np.allclose(render(g, 2)[0], render_reference(g, 2), atol=1e-6), b



@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_children_of_one_parent_render_together_as_one_by_one(seed):
    # children share most subtrees with each other (one node, evaluated once) and same-shaped
    # ones batch with uniform parts broadcast; the pictures must not depend on any of that
    rng = np.random.default_rng(seed)
    parent = Genome.random(rng, n_strings=int(rng.integers(1, 4)), head_length=int(rng.integers(2, 6)))
    ops = [O.substitution, O.transposition, O.root_transposition, O.head_tail_rotation]
    family = [parent, parent] + [ops[rng.integers(len(ops))](parent, rng) for _ in range(8)]
    family += [O.random_interpolation(parent, family[-1], rng)[0] for _ in range(2)]
    window = (-0.3, 0.2, 1.7, 1.1)
    together = render(family, (12, 10), window=window, time=0.4, batch=True)
    apart = np.concatenate([render(g, (12, 10), window=window, time=0.4, batch=False, workers=1)
                            for g in family])
    assert np.array_equal(together, apart)  # batch invariance (module docstring of evaluate)
