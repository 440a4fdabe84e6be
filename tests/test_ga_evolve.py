"""The evolve loop: it optimises, elitism holds, only new individuals are evaluated, every
evaluation back end gives the same run, and a killed run resumed from its checkpoint ends
exactly like the uninterrupted run."""

import functools
import hashlib
import hmac
import os
import pickle
import signal
import struct
import subprocess
import sys
import time
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from pathlib import Path

import matplotlib
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit import ga
from coursekit import atomic
from coursekit.ga.problems import TargetMatch, onemax, random_bits

matplotlib.use("Agg")
ROOT = Path(__file__).resolve().parent.parent

# One reference problem for determinism, back ends and resume: match a random 64-bit target.
TARGET = np.random.default_rng(12345).integers(0, 2, 64)
FITNESS = TargetMatch(TARGET)
VARY = ga.Variation([(0.5, ga.point_mutation), (0.3, ga.one_point_crossover),
                     (0.2, functools.partial(ga.point_mutation, rate=0.1))])
N, G, ELITE = 24, 12, 2


def run(seed=7, generations=G, **kwargs):
    rng = np.random.default_rng(seed)
    pop = random_bits(rng, N, TARGET.size)
    kwargs.setdefault("progress", False)
    return ga.evolve(pop, FITNESS, VARY, generations=generations, rng=rng, elite=ELITE, **kwargs)


def assert_same_run(a, b):
    assert a.history == b.history  # exact float equality, every generation
    np.testing.assert_array_equal(a.fitness, b.fitness)
    assert len(a.population) == len(b.population)
    for x, y in zip(a.population, b.population):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(a.best, b.best)
    assert a.best_fitness == b.best_fitness and a.generation == b.generation


def test_evolve_solves_onemax():
    rng = np.random.default_rng(0)
    pop = random_bits(rng, 40, 64)
    result = ga.evolve(pop, onemax, VARY, generations=60, rng=rng, progress=False)
    h = result.history
    assert len(h) == 61 and h.generation == list(range(61))
    assert h.best[0] < 0.8  # random 64-bit strings: best of 40 is ~0.7
    assert result.best_fitness >= 0.95 and onemax(result.best) == result.best_fitness
    assert h.mean[-1] > h.mean[0] + 0.2
    assert all(b2 >= b1 for b1, b2 in zip(h.best, h.best[1:]))  # elite=1 never loses the best


def test_sims_scheme_survivors_and_proportional_offspring():
    # Sims 1994: top fifth survive unchanged (elite), offspring per survivor proportional to fitness.
    rng = np.random.default_rng(1)
    n = 50
    pop = random_bits(rng, n, 64)
    result = ga.evolve(pop, onemax, VARY, generations=30, rng=rng, select=ga.sims_select, elite=n // 5, progress=False)
    assert result.history.evaluations == [n] + [n - n // 5] * 30
    assert result.best_fitness > result.history.best[0] + 0.15


def test_genomes_are_opaque_strings_work_too():
    # Any picklable genome plugs in: here plain strings evolve towards a phrase.
    target = "survival of the fittest"
    letters = "abcdefghijklmnopqrstuvwxyz "

    def mutate(s, rng):
        i = int(rng.integers(len(s)))
        return s[:i] + letters[int(rng.integers(len(letters)))] + s[i + 1:]

    def cross(a, b, rng):
        c = int(rng.integers(1, len(a)))
        return a[:c] + b[c:], b[:c] + a[c:]

    rng = np.random.default_rng(0)
    pop = ["".join(rng.choice(list(letters), len(target))) for _ in range(60)]
    score = lambda s: sum(x == y for x, y in zip(s, target)) / len(target)  # noqa: E731
    result = ga.evolve(pop, score, ga.Variation([(0.7, mutate), (0.3, cross)]), generations=150, rng=rng,
                       select=ga.truncation, elite=2, progress=False)
    assert isinstance(result.best, str) and result.best_fitness > 0.8 > result.history.best[0]


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), elite=st.integers(1, 4), n=st.integers(4, 12),
       which=st.sampled_from(["tournament", "truncation", "roulette", "sims_select"]))
def test_elitism_keeps_the_best(seed, elite, n, which):
    snapshots = []
    rng = np.random.default_rng(seed)
    ga.evolve(random_bits(rng, n, 16), onemax, VARY, generations=5, rng=rng, select=getattr(ga, which), elite=elite,
              progress=False, callback=lambda r: snapshots.append(r))
    for before, after in zip(snapshots, snapshots[1:]):
        top = ga.ranking(before.fitness)[:elite]
        for j, i in enumerate(top):  # elites come first, unchanged, with their fitness
            np.testing.assert_array_equal(after.population[j], before.population[i])
            assert after.fitness[j] == before.fitness[i]
        assert after.best_fitness >= before.best_fitness


def test_only_new_individuals_are_evaluated():
    calls = []

    def counting(g):
        calls.append(1)
        return onemax(g)

    rng = np.random.default_rng(3)
    result = ga.evolve(random_bits(rng, 10, 8), counting, VARY, generations=4, rng=rng, elite=3, progress=False)
    assert len(calls) == 10 + 4 * 7
    assert result.history.evaluations == [10, 7, 7, 7, 7]
    np.testing.assert_array_equal(result.fitness, [onemax(g) for g in result.population])


def test_same_seed_same_run_different_seed_different_run():
    assert_same_run(run(seed=7), run(seed=7))
    assert run(seed=7).history != run(seed=8).history


def test_custom_map_and_completion_order_do_not_matter():
    reference = run()

    def scrambled_map(func, genomes):  # evaluates in reverse, returns in order
        out = [func(g) for g in reversed(list(genomes))]
        return out[::-1]

    def slow_first(g):  # earlier genomes finish later in a thread pool
        time.sleep(0.002 * (int(g[:3].sum())))
        return FITNESS(g)

    assert_same_run(reference, run(map=scrambled_map))
    with ThreadPoolExecutor(4) as ex:
        rng = np.random.default_rng(7)
        pop = random_bits(rng, N, TARGET.size)
        threaded = ga.evolve(pop, slow_first, VARY, generations=3, rng=rng, elite=ELITE, executor=ex, progress=False)
    assert_same_run(run(generations=3), threaded)


def _pid(_):
    return os.getpid()


@pytest.mark.slow
def test_serial_process_pool_and_dask_give_identical_runs():
    import distributed  # in the [test] extra: never skipped
    serial = run()
    with ProcessPoolExecutor(2) as ex:
        pool = run(executor=ex)
        pool_pids = set(ex.map(_pid, range(8)))
    assert os.getpid() not in pool_pids  # evaluation really ran in other processes
    assert_same_run(serial, pool)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            dask = run(executor=client)
            worker_pids = set(client.run(os.getpid).values())
    assert len(worker_pids) == 2 and os.getpid() not in worker_pids
    assert_same_run(serial, dask)


# --- kill and resume -------------------------------------------------------------------------

def _child(checkpoint, kill_at_generation, kill_at_evaluation):
    """Entry point of the subprocess: the reference run, SIGKILLed at a chosen moment."""

    class KillingFitness:
        calls = 0

        def __call__(self, g):
            KillingFitness.calls += 1
            if KillingFitness.calls == kill_at_evaluation:
                os.kill(os.getpid(), signal.SIGKILL)
            return FITNESS(g)

    def killer(result):
        if result.generation == kill_at_generation:
            os.kill(os.getpid(), signal.SIGKILL)

    rng = np.random.default_rng(7)
    pop = random_bits(rng, N, TARGET.size)
    ga.evolve(pop, KillingFitness(), VARY, generations=G, rng=rng, elite=ELITE, checkpoint=checkpoint,
              callback=killer, progress=False)
    sys.exit(3)  # not reached if the kill happened


def _run_child(checkpoint, kill_at_generation=-1, kill_at_evaluation=-1):
    code = f"import tests.test_ga_evolve as t; t._child({str(checkpoint)!r}, {kill_at_generation}, {kill_at_evaluation})"
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == -signal.SIGKILL, proc.stderr
    return ga.load_checkpoint(checkpoint)


@pytest.mark.parametrize("where", ["after generation 5", "during generation 8"])
def test_killed_run_resumes_to_the_uninterrupted_result(tmp_path, where):
    reference_ckpt = tmp_path / "reference.ckpt"
    reference = run(checkpoint=reference_ckpt)
    ckpt = tmp_path / "run.ckpt"
    if where == "after generation 5":
        state = _run_child(ckpt, kill_at_generation=5)
        assert state["generation"] == 5
    else:  # evaluation number N + 7 * (N - ELITE) + 3 is the 3rd child of generation 8
        state = _run_child(ckpt, kill_at_evaluation=N + 7 * (N - ELITE) + 3)
        assert state["generation"] == 7
    resumed = ga.resume(ckpt, FITNESS, VARY, generations=G, progress=False)
    assert_same_run(reference, resumed)
    final, ref_final = ga.load_checkpoint(ckpt), ga.load_checkpoint(reference_ckpt)
    assert final["generation"] == G and final["rng_state"] == ref_final["rng_state"]


def test_keyboard_interrupt_then_resume_and_extend(tmp_path):
    ckpt = tmp_path / "run.ckpt"

    def interrupt(result):
        if result.generation == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        run(checkpoint=ckpt, callback=interrupt)
    assert ga.load_checkpoint(ckpt)["generation"] == 3
    assert_same_run(run(), ga.resume(ckpt, FITNESS, VARY, generations=G, progress=False))
    # a finished run can be extended: G -> G + 5 equals a run of G + 5 from the start
    assert_same_run(run(generations=G + 5), ga.resume(ckpt, FITNESS, VARY, generations=G + 5, progress=False))


def test_callback_can_stop_early(tmp_path):
    result = run(callback=lambda r: r.generation == 4)
    assert result.generation == 4 and len(result.history) == 5


def test_the_progress_bar_ends_full_whether_the_run_finishes_or_stops_early(capsys):
    run(generations=5, progress=True)
    assert "5/5" in capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]
    run(generations=G, progress=True, callback=lambda r: r.generation == 4)
    last = capsys.readouterr().err.replace("\r", "\n").strip().splitlines()[-1]
    assert "4/4" in last and "100%" in last and f"stopped at generation 4 of {G}" in last


def test_resume_needs_select_that_did_not_pickle(tmp_path):
    ckpt = tmp_path / "run.ckpt"
    run(generations=2, checkpoint=ckpt, select=lambda f, k, rng: ga.tournament(f, k, rng, size=2))
    with pytest.raises(ValueError, match="select: the checkpoint does not store it"):
        ga.resume(ckpt, FITNESS, VARY, generations=4, progress=False)
    with pytest.raises(ValueError, match="generations: the checkpoint is already at generation 2"):
        ga.resume(ckpt, FITNESS, VARY, generations=1, select=ga.tournament, progress=False)
    assert ga.resume(ckpt, FITNESS, VARY, generations=4, select=ga.tournament, progress=False).generation == 4


# --- checkpoint files ------------------------------------------------------------------------

def test_checkpoint_write_is_atomic(tmp_path, monkeypatch):
    ckpt = tmp_path / "run.ckpt"
    run(generations=2, checkpoint=ckpt)
    before = ckpt.read_bytes()

    def boom(*args):
        raise OSError("disk full")

    for name in ("replace", "fsync"):
        with monkeypatch.context() as m:
            m.setattr(atomic.os, name, boom)
            with pytest.raises(OSError, match="disk full"):
                ga.resume(ckpt, FITNESS, VARY, generations=3, progress=False)
        assert ckpt.read_bytes() == before  # the old checkpoint is intact ...
        assert sorted(p.name for p in tmp_path.iterdir()) == ["run.ckpt"]  # ... and no temp file is left
    assert ga.load_checkpoint(ckpt)["generation"] == 2


@pytest.fixture
def own_key(tmp_path, monkeypatch):
    """A private checkpoint key for the test (the key file of the user running the tests stays untouched)."""
    key = tmp_path / "keys" / "checkpoint.key"
    monkeypatch.setenv("COURSEKIT_CHECKPOINT_KEY", str(key))
    return key


def test_corrupt_truncated_and_foreign_checkpoints_are_refused(tmp_path, own_key):
    ckpt = tmp_path / "run.ckpt"
    run(generations=1, checkpoint=ckpt)
    assert own_key.stat().st_mode & 0o077 == 0  # the key is this user's alone
    data = ckpt.read_bytes()
    bad = tmp_path / "bad.ckpt"
    cases = [
        (data[: len(data) // 2], "truncated or padded"),
        (data[:30], r"truncated \(header incomplete\)"),
        (data[:-1] + bytes([data[-1] ^ 1]), "not signed with this user's key"),
        (b"", "not a coursekit GA checkpoint"),
        (b'{"format": "coursekit.genome/1"}', "not a coursekit GA checkpoint"),
        (pickle.dumps({"format": "coursekit.ga.checkpoint/2"}), "not a coursekit GA checkpoint"),
        (data.replace(b"checkpoint/2\n", b"checkpoint/9\n", 1), "format version '9' is not supported"),
        (data.replace(b"checkpoint/2\n", b"checkpoint/1\n", 1), "format 1 .* no longer loaded"),
    ]
    for content, message in cases:
        bad.write_bytes(content)
        with pytest.raises(ValueError, match=message):
            ga.load_checkpoint(bad)
        with pytest.raises(ValueError, match=message):
            ga.resume(bad, FITNESS, VARY, generations=3, progress=False)
    # a well-formed, signed file whose payload is not a checkpoint state
    payload = pickle.dumps(["not", "a", "state"])
    mac = hmac.new(own_key.read_bytes(), payload, hashlib.sha256).digest()
    bad.write_bytes(b"coursekit.ga.checkpoint/2\n" + struct.pack("<Q32s", len(payload), mac) + payload)
    with pytest.raises(ValueError, match="no 'coursekit.ga.checkpoint/2' format field"):
        ga.load_checkpoint(bad)


class _Payload:
    """A pickle that runs code when loaded: it creates the file ``marker``."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def test_a_forged_checkpoint_runs_no_code(tmp_path, own_key):
    """Forged payloads -- SHA-256 recomputed, the old unsigned format, another machine's key -- are
    refused before unpickling: the payload's code never runs. Only trust_foreign=True loads them."""
    ckpt = tmp_path / "run.ckpt"
    run(generations=1, checkpoint=ckpt)
    marker = tmp_path / "pwned"
    state = ga.load_checkpoint(ckpt)
    payload = pickle.dumps({**state, "population": [_Payload(marker)]}, protocol=5)
    forged = {
        "sha256 recomputed": b"coursekit.ga.checkpoint/2\n" + struct.pack("<Q32s", len(payload), hashlib.sha256(payload).digest()) + payload,
        "format 1": b"coursekit.ga.checkpoint/1\n" + struct.pack("<Q32s", len(payload), hashlib.sha256(payload).digest()) + payload,
        "another key": b"coursekit.ga.checkpoint/2\n" + struct.pack("<Q32s", len(payload), hmac.new(b"k" * 32, payload, hashlib.sha256).digest()) + payload,
    }
    for what, content in forged.items():
        ckpt.write_bytes(content)
        with pytest.raises(ValueError):
            ga.load_checkpoint(ckpt)
        with pytest.raises(ValueError):
            ga.resume(ckpt, FITNESS, VARY, generations=3, progress=False)
        assert not marker.exists(), what
    # the explicit escape hatch for a trusted author does unpickle (and so would run the code)
    ckpt.write_bytes(forged["another key"])
    ga.load_checkpoint(ckpt, trust_foreign=True)
    assert marker.exists()


def test_checkpoints_need_the_key_that_signed_them(tmp_path, monkeypatch):
    ckpt = tmp_path / "run.ckpt"
    monkeypatch.setenv("COURSEKIT_CHECKPOINT_KEY", str(tmp_path / "alice.key"))
    run(generations=2, checkpoint=ckpt)
    assert ga.load_checkpoint(ckpt)["generation"] == 2
    monkeypatch.setenv("COURSEKIT_CHECKPOINT_KEY", str(tmp_path / "bob.key"))
    with pytest.raises(ValueError, match="not signed with this user's key"):
        ga.load_checkpoint(ckpt)
    assert not (tmp_path / "bob.key").exists()  # reading never creates a key
    assert ga.load_checkpoint(ckpt, trust_foreign=True)["generation"] == 2
    (tmp_path / "bob.key").write_bytes(b"short")
    with pytest.raises(ValueError, match="expected 32 bytes"):
        run(generations=1, checkpoint=ckpt)


# --- history ---------------------------------------------------------------------------------

def test_history_statistics_json_and_plot():
    rng = np.random.default_rng(5)
    snapshots = []
    result = ga.evolve(random_bits(rng, 12, 10), onemax, VARY, generations=3, rng=rng, progress=False,
                       diversity=ga.mean_pairwise(ga.diversity.hamming), callback=snapshots.append)
    h = result.history
    assert [len(s.history) for s in snapshots] == [1, 2, 3, 4]  # snapshots are not changed later
    for i, snap in enumerate(snapshots):
        f = snap.fitness
        assert (h.best[i], h.mean[i], h.median[i], h.std[i]) == (f.max(), f.mean(), np.median(f), f.std())
        pairs = [np.mean(a != b) for j, a in enumerate(snap.population) for b in snap.population[j + 1:]]
        assert h.diversity[i] == pytest.approx(np.mean(pairs))
    assert ga.History.from_json(h.to_json()) == h
    with pytest.raises(ValueError, match="format: expected 'coursekit.ga.history/1', got 'nope'"):
        ga.History.from_dict({**h.to_dict(), "format": "nope"})
    with pytest.raises(ValueError, match="same length"):
        ga.History.from_dict({**h.to_dict(), "best": h.best[:-1]})
    ax = h.plot(label="run")
    assert [line.get_label() for line in ax.get_lines()] == ["run: best", "run: mean", "run: median"]
    np.testing.assert_array_equal(ax.get_lines()[0].get_ydata(), h.best)
    assert len(ax.figure.axes) == 2  # the diversity twin axis
    matplotlib.pyplot.close(ax.figure)


def test_default_diversity_is_the_distinct_fraction():
    pop = [np.zeros(4, np.int8)] * 3 + [np.ones(4, np.int8)]
    result = ga.evolve(pop, onemax, VARY, generations=0, rng=np.random.default_rng(0), progress=False)
    assert result.history.diversity == [0.5]
    assert ga.distinct_fraction(pop) == 0.5 and ga.distinct_fraction([{"a": 1}, {"a": 1}]) == 0.5


def test_progress_bar(capsys):
    run(generations=2, progress=True)
    assert "evolve" in capsys.readouterr().err


# --- bad input -------------------------------------------------------------------------------

def _pop():
    return random_bits(np.random.default_rng(0), 6, 8)


@pytest.mark.parametrize(
    "kwargs, exc, pattern",
    [
        (dict(generations=-1), ValueError, "generations: expected an int >= 0, got -1"),
        (dict(rng=42), TypeError, "rng: expected a numpy.random.Generator"),
        (dict(elite=7), ValueError, "elite: cannot keep 7 elites in a population of 6"),
        (dict(elite=-1), ValueError, "elite: expected an int >= 0, got -1"),
        (dict(population=[]), ValueError, "population: expected at least 1 genome"),
        (dict(population=iter(_pop())), TypeError, "population: expected a sequence"),
        (dict(fitness="onemax"), TypeError, "fitness: expected a callable"),
        (dict(fitness=lambda g: float("nan")), ValueError, r"fitness: genome #0 got fitness nan"),
        (dict(fitness=lambda g: "high"), TypeError, r"fitness: genome #0 got fitness 'high'"),
        (dict(vary=lambda parents, rng: parents[:-1]), ValueError, "vary: returned 4 children for 5 parents"),
        (dict(select=lambda f, k, rng: np.full(k, 99)), ValueError, r"select: indices must lie in \[0, 6\)"),
        (dict(select=lambda f, k, rng: [0]), ValueError, "select: expected 5 integer indices"),
        (dict(map=map, executor=object()), ValueError, "give at most one of map= and executor="),
        (dict(executor=object()), TypeError, "executor: expected a concurrent.futures.Executor"),
        (dict(map=lambda f, gs: [1.0]), ValueError, "map: returned 1 fitness values for 6 genomes"),
        (dict(vary=lambda parents, rng: None), TypeError, "vary: expected a list of 5 children, got NoneType"),
        (dict(checkpoint=5), TypeError, "checkpoint: expected a file path"),
        (dict(diversity=lambda population: "high"), ValueError, "diversity: diversity\\(population\\) returned 'high'"),
        (dict(diversity=lambda population: float("nan")), ValueError, "diversity: .* returned nan; expected a finite number"),
    ],
)
def test_evolve_bad_input(kwargs, exc, pattern):
    args = dict(population=_pop(), fitness=onemax, vary=VARY, generations=2, rng=np.random.default_rng(0), progress=False)
    args.update(kwargs)
    population, fitness, vary = args.pop("population"), args.pop("fitness"), args.pop("vary")
    with pytest.raises(exc, match=pattern):
        ga.evolve(population, fitness, vary, **args)


@pytest.mark.parametrize(
    "call, exc, pattern",
    [
        (lambda: ga.evaluate(None, [1]), TypeError, "fitness: expected a callable"),
        (lambda: ga.evaluate(onemax, None), TypeError, "genomes: expected a list of genomes, got NoneType"),
        (lambda: ga.mean_pairwise(5), TypeError, "distance: expected a callable"),
        (lambda: random_bits(None, 2, 3), TypeError, "rng: expected a numpy.random.Generator"),
        (lambda: random_bits(np.random.default_rng(0), 2, -1), ValueError, "length: must be an integer >= 0, got -1"),
        (lambda: random_bits(np.random.default_rng(0), 1.5, 3), ValueError, "n: must be an integer >= 0, got 1.5"),
        (lambda: ga.problems.smiley(-1), ValueError, "size: must be an integer >= 1, got -1"),
        (lambda: ga.problems.smiley(16.0), ValueError, "size: must be an integer >= 1, got 16.0"),
        (lambda: TargetMatch(None), ValueError, "target: expected a non-empty array of 0/1 values, got None"),
        (lambda: TargetMatch([0, 2]), ValueError, "target: expected a non-empty array of 0/1 values"),
        (lambda: TargetMatch([]), ValueError, "target: expected a non-empty array"),
        (lambda: onemax(None), TypeError, "onemax: genome must be an array of 0/1 bits, got NoneType"),
        (lambda: ga.diversity.distinct_fraction(None), TypeError, "population: expected a sequence of genomes, got NoneType"),
    ],
)
def test_helpers_name_bad_arguments(call, exc, pattern):
    with pytest.raises(exc, match=pattern):
        call()
