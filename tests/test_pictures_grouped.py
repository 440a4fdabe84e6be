"""Population-wide evaluation in waves (``render(..., group=True)``, :mod:`coursekit.pictures.grouped`).

It must give the pictures of genome-by-genome evaluation bit for bit, whatever the population
(random shapes, clones, children of one parent, warps of every kind), and it must need far fewer
tensor operations: that count is the number of kernel launches on a GPU, which is what it is for.
"""

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.operations import CountOperations
from coursekit.pictures import operators as O
from coursekit.pictures.evaluate import render
from coursekit.pictures.genome import Chromosome, ChromosomeString, Genome

C = Chromosome


def _population(seed: int, n: int) -> list[Genome]:
    rng = np.random.default_rng(seed)
    pop = [Genome.random(rng, n_strings=int(rng.integers(1, 4)), head_length=int(rng.integers(2, 6)))
           for _ in range(n)]
    ops = [O.substitution, O.transposition, O.root_transposition, O.head_tail_rotation]
    pop += [ops[rng.integers(len(ops))](pop[0], rng) for _ in range(3)]  # children: shared subtrees
    return pop + [pop[1]]  # a clone


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(1, 12), size=st.sampled_from([(9, 7), (16, 16), (37, 41)]),
       window=st.sampled_from([(0.0, 0.0, 1.0, 1.0), (-1.5, 0.3, 2.5, 1.9)]), time=st.floats(0.0, 3.0),
       batch=st.booleans())
def test_waves_give_the_pictures_of_genome_by_genome_evaluation_bit_for_bit(seed, n, size, window, time, batch):
    pop = _population(seed, n)
    one_by_one = render(pop, size, window=window, time=time, workers=1, group=False)
    waves = render(pop, size, window=window, time=time, workers=1, group=True, batch=batch)
    assert np.array_equal(one_by_one, waves)


def test_every_warp_and_its_displacement_in_waves():
    def one(*chroms, h):
        chroms = list(chroms) + [C("y")] * (2 * h + 1 - len(chroms))
        return Genome((ChromosomeString(h, tuple(chroms)),))

    noise = C("turbulence", (3.0, 3.0, 5.0, 6.0))
    pop = [one(C("swirl", (2.0, 0.4)), noise, h=1),
           one(C("rotate", (0.3,)), C("pixmap", (1.5,)), h=1),
           one(C("warp-swirl", (1.5,)), C("color-noise", (4.0, 1.0, 2.0)), C("x"), h=2),
           one(C("warp-by", (0.2,)), C("bw-noise", (6.0, 1.0, 2.0)), C("gradient", (0.1, 0.2, 0.3, 0.9, 0.8, 0.7, 0.25)), h=2),
           one(C("warp-by", (0.2,)), C("warp-swirl", (1.0,)), noise, C("x"), C("angle"), h=3),  # a warp in a warp
           one(C("dissolve", (0.5, 0.2, 3.0, 4.0)), noise, C("rotate", (0.1,)), C("x"), h=3)]
    assert np.array_equal(render(pop, (12, 10), workers=1, group=False),
                          render(pop, (12, 10), workers=1, group=True))


def test_waves_need_several_times_fewer_operations_than_genome_by_genome_evaluation():
    rng = np.random.default_rng(3)
    pop = [Genome.random(rng, n_strings=4, head_length=8) for _ in range(256)]
    counts = {}
    for group in (False, True):
        with CountOperations() as ops:
            render(pop, 8, workers=1, group=group)
        counts[group] = ops.count
    assert counts[False] > 3 * counts[True], counts


def test_group_is_validated():
    g = Genome.random(np.random.default_rng(0))
    with pytest.raises(ValueError, match="group"):
        render(g, 4, group="yes")
    assert render(g, 4, group=True, as_tensor=True).dtype == torch.float32


def test_waves_in_worker_processes_and_edge_cases():
    pop = _population(11, 16)  # 20 genomes at 128^2: enough work for the worker processes
    assert np.array_equal(render(pop, 128, group=True), render(pop, 128, workers=1, group=False))
    assert render([], 4, group=True).shape == (0, 4, 4, 3)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), copies=st.integers(1, 9), hw=st.sampled_from([(1, 1), (5, 3), (37, 41), (64, 64)]),
       fn=st.sampled_from(["sin", "cos", "exp", "log", "sqrt", "atan", "atan2"]))
def test_transcendental_kernels_round_an_element_the_same_wherever_it_sits(seed, copies, hw, fn):
    # a value reaches a kernel compact (one genome alone), broadcast to the image (waves) or
    # stacked with others (batches); torch's CPU loops and numpy's stride-0 loops compute some
    # elements with the scalar function, which rounds differently: a picture then depends on
    # its batch (measured: 4 of 260 random genomes at 37 x 41 before)
    from coursekit.pictures.kernels import fast

    f = getattr(fast, fn)
    rng = np.random.default_rng(seed)
    x = torch.from_numpy(rng.uniform(0.01, 40.0, (1, 3, 1, 1)).astype(np.float32))
    y = torch.from_numpy(rng.uniform(-3.0, 3.0, (1, 3, 1, 1)).astype(np.float32))
    args = (x, y) if fn == "atan2" else (x,)
    compact = f(*args).expand(1, 3, *hw)
    broadcast = f(*(a.expand(1, 3, *hw) for a in args))
    others = torch.from_numpy(rng.uniform(0.01, 40.0, (copies, 3, *hw)).astype(np.float32))
    stacked = f(*(torch.cat([others, a.expand(1, 3, *hw)]) for a in args))[-1:]
    assert torch.equal(compact, broadcast) and torch.equal(compact, stacked)
