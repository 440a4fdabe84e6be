"""The primitive registry (coursekit.pictures.primitives): one place the genome alphabet, the
whole-image evaluator and the per-pixel reference read, so a primitive of one's own is one call."""

import math

import numpy as np
import pytest
import torch

from coursekit.pictures import Genome, primitives as P, render, render_reference
from coursekit.pictures import workers as Wk
from coursekit.pictures.evaluate import _POOL_PIXELS
from coursekit.pictures.genome import Chromosome, ChromosomeString
from coursekit.pictures.primitives import Param, Primitive, register_primitive

WINDOW = (-0.3, 0.1, 1.4, 1.2)


@pytest.fixture
def registry():
    """The registry as it was, restored afterwards (a test's primitives must not leak into the
    random genomes of the tests that share its process)."""
    tables = (P.PRIMITIVES, P.IMAGE_KERNELS, P.PIXEL_KERNELS, P.REGISTERED)
    saved = [t.copy() for t in tables]
    yield
    for table, old in zip(tables, saved):
        table.clear()
        table.update(old)


def one(*chroms, h):
    """A single-string genome: the head and the start of the tail, the tail padded with x."""
    chroms = list(chroms) + [Chromosome("x")] * (2 * h + 1 - len(chroms))
    return Genome((ChromosomeString(h, tuple(chroms)),))


def test_every_primitive_has_both_implementations_and_a_form_that_fits_its_arity():
    for name, prim in P.PRIMITIVES.items():
        assert name in P.IMAGE_KERNELS and name in P.PIXEL_KERNELS, name
        assert prim.form in P.FORMS
        assert (prim.form == "terminal") == (prim.arity == 0), name
        assert prim.cost > 0


def test_a_primitive_of_ones_own_renders_with_both_evaluators_and_joins_the_alphabet(registry):
    # a pointwise function with a parameter, and a terminal reading the coordinates
    # (plain arithmetic: each image of a batch computed as alone, which waves rely on)
    def soft_step(ctx, p, a):
        t = (p[0] * (a - 0.5) + 0.5).clamp(0.0, 1.0)
        return t * t * (3.0 - 2.0 * t)

    def soft_step_pixel(ref, x, y, p, a):
        t = [min(max(p[0] * (v - 0.5) + 0.5, 0.0), 1.0) for v in a]
        return tuple(v * v * (3.0 - 2.0 * v) for v in t)

    register_primitive(Primitive("soft-step", 1, (Param("sharpness", 1.0, 8.0),), "smooth step around 0.5"),
                       image=soft_step, pixel=soft_step_pixel)
    register_primitive(Primitive("checker", 0, (Param("cells", 2.0, 9.0),), "a chequerboard of cells x cells"),
                       image=lambda ctx, p: ((torch.floor(ctx.x * p[0]) + torch.floor(ctx.y * p[0])) % 2.0),
                       pixel=lambda ref, x, y, p: (float((math.floor(x * p[0]) + math.floor(y * p[0])) % 2.0),))
    assert "checker" in P.terminals() and "soft-step" in P.functions()
    genomes = [one(Chromosome("soft-step", (s,)), Chromosome("times"), Chromosome("checker", (c,)),
                   Chromosome("radius"), h=3) for s, c in ((3.0, 4.0), (7.5, 2.5), (1.0, 6.0))]
    genomes.append(one(Chromosome("hsv-to-rgb"), Chromosome("soft-step", (5.0,)), Chromosome("bw-noise", (4.0, 1.0, 2.0)),
                       h=2))
    waves = render(genomes, (12, 14), window=WINDOW, group=True, workers=1)
    one_by_one = render(genomes, (12, 14), window=WINDOW, group=False, workers=1)
    assert np.array_equal(waves, one_by_one)
    for g, pic in zip(genomes, waves):
        assert np.abs(pic - render_reference(g, (12, 14), window=WINDOW)).max() < 1e-4, g.expression()
    assert Genome.from_json(genomes[0].to_json()) == genomes[0]
    rng = np.random.default_rng(3)
    drawn = [Genome.random(rng, n_strings=1, head_length=4, symbols=["soft-step", "checker", "plus"])
             for _ in range(20)]
    symbols = {c.symbol for g in drawn for s in g.strings for c in s.chromosomes}
    assert {"soft-step", "checker"} <= symbols


def test_registering_rejects_what_the_evaluators_cannot_read(registry):
    with pytest.raises(ValueError, match="arity"):
        register_primitive(Primitive("three", 3, (), "three arguments"))
    with pytest.raises(ValueError, match="form"):
        register_primitive(Primitive("odd", 1, (), "?", form="sideways"))
    with pytest.raises(ValueError, match="does not fit arity"):
        register_primitive(Primitive("blurry", 2, (), "?", form="filter"))
    with pytest.raises(ValueError, match="already registered"):
        register_primitive(Primitive("plus", 2, (), "again"))
    with pytest.raises(ValueError, match="name"):
        register_primitive(Primitive("two words", 0, (), "?"))
    with pytest.raises(TypeError, match="image"):
        register_primitive(Primitive("fine", 0, (), "?"), image="not a function")
    with pytest.raises(ValueError, match="unknown name"):
        P.image_kernel("no-such-primitive")
    assert "three" not in P.PRIMITIVES and "fine" not in P.PRIMITIVES


def test_a_primitive_without_an_implementation_says_which_is_missing(registry):
    register_primitive(Primitive("unfinished", 0, (), "declared, not written yet", weight=0.0))
    g = one(Chromosome("unfinished"), h=1)
    with pytest.raises(ValueError, match="'unfinished' has no whole-image implementation"):
        render(g, 4, workers=1)
    with pytest.raises(ValueError, match="'unfinished' has no per-pixel implementation"):
        render_reference(g, 2)


def test_a_population_with_a_primitive_registered_at_run_time_renders_in_process(registry):
    # the worker processes import the built-ins only: sent a tree holding "ripple" they would
    # not know it, so render keeps such a population in this process (17 pictures at 128^2 are
    # past the size from which it would use the workers)
    rng = np.random.default_rng(5)
    pop = [Genome.random(rng, n_strings=2, head_length=4) for _ in range(16)]  # built-ins only
    register_primitive(Primitive("ripple", 1, (Param("rings", 2.0, 12.0),), "stripes of a across x"),
                       image=lambda ctx, p, a: a * torch.cos(p[0] * 6.2832 * ctx.x),
                       pixel=lambda ref, x, y, p, a: tuple(v * math.cos(p[0] * 6.2832 * x) for v in a))
    pop.append(one(Chromosome("ripple", (5.0,)), Chromosome("radius"), h=1))
    size = (128, 128)
    assert (len(pop) - 1) * size[0] * size[1] >= _POOL_PIXELS
    Wk.shutdown()
    pics = render(pop, size, workers=2)
    assert Wk._pool is None  # not sent to the workers
    assert np.array_equal(pics, render(pop, size, workers=1))
    assert np.abs(pics[-1] - render_reference(pop[-1], size)).max() < 1e-4
    # the built-in population alone still goes to the workers
    assert np.array_equal(render(pop[:-1], size, workers=2), pics[:-1])
    assert Wk._pool is not None


def test_a_primitive_redefined_with_another_arity_is_read_anew_by_decoded_genomes(registry):
    register_primitive(Primitive("probe", 1, (), "its argument"), image=lambda ctx, p, a: a)
    g = one(Chromosome("probe"), Chromosome("y"), h=2)
    assert g.expression() == "(probe y)"
    register_primitive(Primitive("probe", 2, (), "the sum of its arguments"), image=lambda ctx, p, a, b: a + b, replace=True)
    assert g.expression() == "(probe y x)"
