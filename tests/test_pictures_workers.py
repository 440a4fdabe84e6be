"""Rendering a population in worker processes (coursekit.pictures.workers, section 3.2).

The pool must give exactly the pictures of in-process rendering, in population order (with
same-shaped genomes stacked or not), never run a user's script again in its workers, free its shared
memory, and fall back to in-process rendering where processes cannot be started.
"""

import multiprocessing as mp
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from coursekit.pictures import Genome, render
from coursekit.pictures import operators as O
from coursekit.pictures import workers as Wk
from coursekit.pictures.evaluate import _POOL_PIXELS

ROOT = Path(__file__).resolve().parents[1]


def population(seed, n):
    rng = np.random.default_rng(seed)
    pop = [Genome.random(rng, n_strings=3, head_length=5) for _ in range(n - 4)]
    # clones and children of one parent: same-shaped trees that batch together
    pop += [pop[0], O.substitution(pop[0], rng), pop[1], O.transposition(pop[1], rng)]
    order = rng.permutation(len(pop))
    return [pop[i] for i in order]


@pytest.mark.parametrize("batch", [False, True])
def test_pool_renders_the_in_process_pictures_in_population_order(batch):
    pop = population(3, 12)
    size = (128, 176)
    assert len(pop) * size[0] * size[1] >= _POOL_PIXELS
    window = (-0.4, 0.1, 1.3, 1.2)
    pooled = render(pop, size, window=window, time=0.7, workers=2, batch=batch)
    alone = render(pop, size, window=window, time=0.7, workers=1)
    assert pooled.shape == (12, 128, 176, 3) and pooled.dtype == np.float32
    assert np.array_equal(pooled, alone)
    assert Wk._pool is not None and Wk._pool.n == 2  # the pool really ran
    block = Wk._pool.shm.name
    again = render(pop[::-1], size, window=window, time=0.7, workers=2, batch=batch)  # reuses pool and block
    assert Wk._pool.shm.name == block
    assert np.array_equal(again, alone[::-1])


def test_workers_decode_the_stock_pictures_when_they_start():
    from coursekit.pictures.primitives import PIXMAPS

    pop = population(5, 12)
    render(pop, (128, 176), workers=2)  # starts the pool
    if Wk._pool is None:
        pytest.skip("no worker processes here")
    sizes = [job.result() for job in [Wk._pool.executor.submit(_decoded_pictures) for _ in range(4)]]
    assert sizes == [len(PIXMAPS)] * 4


def _decoded_pictures():  # in a worker
    from coursekit.pictures import textures as T

    return T.pixmap.cache_info().currsize


def test_chunks_balance_costs_and_keep_every_unit_once():
    costs = [9.0, 1.0, 1.0, 4.0, 4.0, 3.0, 2.0, 8.0]
    chunks = Wk._chunks(costs, 3)
    assert sorted(i for c in chunks for i in c) == list(range(len(costs)))
    loads = [sum(costs[i] for i in c) for c in chunks]
    assert max(loads) - min(loads) <= max(costs)  # longest-first greedy bound
    assert Wk._chunks([1.0], 4) == [[0]]


def test_the_cost_estimate_counts_the_grid_a_filter_extends():
    """Workers are balanced by :func:`cost`; a blur's argument is evaluated on a grid extended by
    the blur's reach (:func:`primitives.padding`), and the estimate counts its pixels."""
    from coursekit.pictures import primitives as P
    from coursekit.pictures.evaluate import cost
    from coursekit.pictures.genome import Chromosome, Node

    def node(symbol, *children, params=()):
        return Node(Chromosome(symbol, params), children, ("pre", 0))

    H = W = 64
    frame = (1 / W, 1 / H, H, W)
    x = node("x")
    assert cost(x, frame=frame) == cost(x) == P.get("x").cost
    plain = node("sin", node("plus", x, node("y")))
    assert cost(plain, frame=frame) == pytest.approx(cost(plain))  # nothing extends its grid
    r, c = P.padding("blur", [0.05], 1 / W, 1 / H, H, W)
    assert r > 0 and c > 0
    area = (H + 2 * r) * (W + 2 * c) / (H * W)
    blurred = node("blur", x, params=(0.05,))
    assert cost(blurred) == pytest.approx(P.get("blur").cost + P.get("x").cost)
    assert cost(blurred, frame=frame) == pytest.approx(area * (P.get("blur").cost + P.get("x").cost))
    # nested filters: the inner one's argument on a grid extended by both reaches (at most H, W)
    r2, c2 = P.padding("band-pass", [0.03], 1 / W, 1 / H, H, W, (r, c))
    inner = (H + 2 * (r + r2)) * (W + 2 * (c + c2)) / (H * W)
    nested = node("blur", node("band-pass", x, params=(0.03,)), params=(0.05,))
    assert cost(nested, frame=frame) == pytest.approx(area * P.get("blur").cost
                                                       + inner * (P.get("band-pass").cost + P.get("x").cost))
    assert 1.0 < inner <= 9.0


@pytest.mark.parametrize("bad", [0, -2, 1.5, True, "2"])
def test_workers_must_be_a_positive_integer(bad):
    g = Genome.random(np.random.default_rng(0))
    with pytest.raises(ValueError, match="workers"):
        render([g, g], 8, workers=bad)


def _render_in_daemon(queue):
    pop = population(5, 16)
    import warnings

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        pics = render(pop, 128, workers=2)
    queue.put((pics, [str(w.message) for w in caught]))


def test_daemonic_process_falls_back_to_in_process_rendering():
    ctx = mp.get_context("spawn")
    queue = ctx.Queue()
    p = ctx.Process(target=_render_in_daemon, args=(queue,), daemon=True)
    p.start()
    pics, messages = queue.get(timeout=120)
    p.join(timeout=60)
    assert p.exitcode == 0
    assert any("worker processes unavailable" in m for m in messages)
    assert np.array_equal(pics, render(population(5, 16), 128, workers=1))


def test_script_without_main_guard_runs_once_and_frees_its_shared_memory(tmp_path):
    marker = tmp_path / "ran.txt"
    script = tmp_path / "breed.py"
    script.write_text(textwrap.dedent(f"""
        import numpy as np
        from coursekit.pictures import Genome, render
        from coursekit.pictures import workers
        with open({str(marker)!r}, "a") as f:
            f.write("ran\\n")
        rng = np.random.default_rng(1)
        pics = render([Genome.random(rng) for _ in range(16)], 128, workers=2)
        assert workers._pool is not None, "the pool did not run"
        print(workers._pool.shm.name)
        print(pics.shape, float(pics.min()) >= 0.0, float(pics.max()) <= 1.0)
    """))
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, env=env,
                          timeout=300, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    name, pictures = done.stdout.splitlines()
    assert pictures == "(16, 128, 128, 3) True True"
    assert marker.read_text() == "ran\n"  # the workers did not run the script again
    assert "leaked" not in done.stderr and "Traceback" not in done.stderr
    if Path("/dev/shm").is_dir():
        assert not (Path("/dev/shm") / name.lstrip("/")).exists()
