"""Exercise 08 checks (Sims' swimming fitness, his reproduction scheme), without kernels.

The solution and independent second implementations pass every property; the library's own
fitness and selection meet the same specification; one known-wrong implementation per property
fails exactly that property, and do-nothing answers (a constant, zeros, a fixed index, the best
alone) score 0. The paths the checks draw are cross-checked against what they claim to be.
"""

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit import ga
from coursekit.creatures import Creature, simulate
from coursekit.creatures.fitness import swimming_fitness as library_fitness
from coursekit.grading import checks, evaluate
from coursekit.grading.checks import for_notebook
from coursekit.grading.runner import run_cases
from coursekit.grading.checks.ex08_fitness_and_reproduction import (Paths, circling, in_place, one_push, quotas,
                                                                    sample_times, steady_swimmer, survivors_of)
from solution_cells import solution_functions



SOL = solution_functions("08_fitness_and_reproduction.ipynb", {"np": np, "math": math})
fitness, reproduce = SOL["swimming_fitness"], SOL["reproduce"]


# -- independent second implementations ---------------------------------------------------------


def fitness_loops(com, times):
    """Creature by creature, sample by sample: the maximum distance per second, plus the last third's speed."""
    out = []
    for path in np.asarray(com):
        d = [math.dist(p, path[0]) for p in path]
        duration = times[-1] - times[0]
        cut = int(np.searchsorted(times, times[0] + 2 * duration / 3))
        late = (d[-1] - d[cut]) / (times[-1] - times[cut])
        out.append(max(0.0, 0.5 * max(d) / duration + 0.5 * late))
    return np.array(out)


def reproduce_loops(fitness, k, rng, survival=0.2):
    """Hamilton's method one survivor at a time, then a Fisher-Yates shuffle."""
    f = list(map(float, fitness))
    order = sorted(range(len(f)), key=lambda i: (-f[i], i))[: math.ceil(survival * len(f))]
    total = sum(f[i] for i in order)
    share = {i: (k * f[i] / total if total else k / len(order)) for i in order}
    counts = {i: int(share[i]) for i in order}
    for i in sorted(order, key=lambda i: -(share[i] - counts[i]))[: k - sum(counts.values())]:
        counts[i] += 1
    parents = [i for i in order for _ in range(counts[i])]
    for j in range(len(parents) - 1, 0, -1):
        r = int(rng.integers(j + 1))
        parents[j], parents[r] = parents[r], parents[j]
    return np.array(parents, dtype=np.int64)


def library_select(fitness, k, rng, survival=0.2):
    return ga.sims_select(np.asarray(fitness), k, rng, survival=survival)


@pytest.mark.parametrize("name, fns", [("swimmers.fitness", [fitness, fitness_loops, library_fitness]),
                                       ("swimmers.reproduce", [reproduce, reproduce_loops, library_select])])
@pytest.mark.parametrize("seed", [0, 1])
def test_correct_implementations_get_full_marks(name, fns, seed):
    for fn in fns:
        j = evaluate(name, fn, seed=seed, timeout=30)
        assert j.passed and j.score == j.check.points, (fn.__name__, [(v.prop, v.message) for v in j.verdicts if not v.passed])


def test_exercise_registers_both_checks():
    assert [c.name for c in for_notebook("08_fitness_and_reproduction")] == ["swimmers.fitness", "swimmers.reproduce"]
    assert sum(c.points for c in for_notebook("08_fitness_and_reproduction")) == 10.0


# -- known-wrong implementations fail exactly the property they violate --------------------------


def fitness_unclipped(com, times):  # Sims' recipe, not clipped at 0 (s25: 5/5, no test path came back to its start)
    com, times = np.asarray(com, dtype=float), np.asarray(times, dtype=float)
    distance = np.linalg.norm(com - com[:, :1], axis=2)
    edges = np.linspace(times[0], times[-1], 11)
    speed = np.diff(np.stack([np.interp(edges, times, d) for d in distance]), axis=1) / np.diff(edges)
    late = (speed * np.arange(1, 11) / 55).sum(axis=1)
    return 0.5 * distance.max(axis=1) / (times[-1] - times[0]) + 0.5 * late


def fitness_path_length(com, times):  # the distance travelled: circling and wobbling pay
    return np.linalg.norm(np.diff(com, axis=1), axis=2).sum(axis=1) / (times[-1] - times[0])


def fitness_per_sample(com, times):  # duration from the number of samples, as if 60 Hz from 0
    return fitness(com, np.arange(len(times)) / 60.0)


def fitness_along_x(com, times):  # Sims' recipe on the progress along +x only
    ahead = np.zeros_like(com)
    ahead[:, :, 0] = np.maximum(com[:, :, 0] - com[:, :1, 0], 0.0)
    return fitness(ahead, times)


def fitness_final_distance(com, times):  # one push ties with the swimmer
    return np.linalg.norm(com[:, -1] - com[:, 0], axis=1) / (times[-1] - times[0])


def fitness_from_origin(com, times):  # distances from the origin, where every path used to start (a student's walk: 5/5)
    com, times = np.asarray(com, dtype=float), np.asarray(times, dtype=float)
    distance = np.linalg.norm(com, axis=2)
    edges = np.linspace(times[0], times[-1], 11)
    speed = np.diff(np.stack([np.interp(edges, times, d) for d in distance]), axis=1) / np.diff(edges)
    late = (speed * np.arange(1, 11) / 55).sum(axis=1)
    return np.maximum(0.5 * distance.max(axis=1) / (times[-1] - times[0]) + 0.5 * late, 0.0)


def fitness_doubled(com, times):  # the sum of the two halves of Sims' recipe, not their average
    return 2 * fitness(com, times)


def fitness_batch_ranks(com, times):  # ties broken by the rank in the batch
    f = fitness(com, times)
    return f + 1e-7 * np.argsort(np.argsort(f))


def fitness_in_place(com, times):
    times -= times[0]  # the clock starts at 0 -- in the caller's array
    return fitness(com, times)


def fitness_rescales_paths(com, times):
    com *= 1.0 + 1e-9  # "normalises" the paths -- in the caller's array
    return fitness(com, times)


def reproduce_too_few(fitness, k, rng, survival=0.2):
    return reproduce(fitness, k - 1, rng, survival)


def reproduce_roulette_survivors(fitness, k, rng, survival=0.2):
    s = survivors_of(fitness, survival)
    f = np.asarray(fitness)[s]
    p = f / f.sum() if f.sum() > 0 else None
    return rng.choice(s, size=k, p=p)


def reproduce_uniform_survivors(fitness, k, rng, survival=0.2):  # counts as equal as possible, fitness ignored
    s = survivors_of(fitness, survival)
    return rng.permutation(np.resize(s, k))


def reproduce_sorted(fitness, k, rng, survival=0.2):
    return np.sort(reproduce(fitness, k, rng, survival))


def reproduce_global_rng(fitness, k, rng, survival=0.2):
    return np.random.default_rng().permutation(reproduce(fitness, k, np.random.default_rng(0), survival))


def reproduce_divides_by_zero(fitness, k, rng, survival=0.2):  # an all-zero generation: nobody reproduces
    f = np.asarray(fitness, dtype=float)
    if f[survivors_of(f, survival)].sum() == 0:
        return np.resize(survivors_of(f, survival)[:1], k)
    return reproduce(f, k, rng, survival)


def reproduce_floor_survivors(fitness, k, rng, survival=0.2):  # int() in place of ceil: 7 creatures, 1 survivor
    n_surv = max(1, int(survival * len(fitness)))
    return reproduce(fitness, k, rng, n_surv / len(fitness) - 1e-12)


def reproduce_sorts_input(fitness, k, rng, survival=0.2):
    parents = reproduce(fitness, k, rng, survival)
    fitness.sort()  # "sorted once, for the next caller", in the caller's array
    return parents


WRONG = [
    ("swimmers.fitness", fitness_unclipped, "never negative"),
    ("swimmers.fitness", fitness_doubled, "a steady swimmer scores its speed in m/s"),
    ("swimmers.fitness", fitness_per_sample, "time in seconds: any sample rate, duration and start"),
    ("swimmers.fitness", fitness_along_x, "any direction counts"),
    ("swimmers.fitness", fitness_from_origin, "the distance counts from where the creature starts"),
    ("swimmers.fitness", fitness_final_distance, "one push and coasting scores below a steady swimmer"),
    ("swimmers.fitness", fitness_batch_ranks, "each creature is scored on its own"),
    ("swimmers.fitness", fitness_in_place, "inputs unchanged"),
    ("swimmers.fitness", fitness_rescales_paths, "inputs unchanged"),
    ("swimmers.reproduce", reproduce_too_few, "returns k valid indices"),
    ("swimmers.reproduce", reproduce_uniform_survivors, "offspring in proportion to fitness"),
    ("swimmers.reproduce", reproduce_sorted, "shuffled, so that mates are random"),
    ("swimmers.reproduce", reproduce_global_rng, "deterministic for a seed"),
    ("swimmers.reproduce", reproduce_divides_by_zero, "an all-zero generation shares equally"),
    ("swimmers.reproduce", reproduce_floor_survivors, "rounds the survivor count up"),
    ("swimmers.reproduce", reproduce_sorts_input, "input unchanged"),
]


@pytest.mark.parametrize("name, fn, prop", WRONG, ids=[w[1].__name__ for w in WRONG])
def test_known_wrong_fails_exactly_its_property(name, fn, prop):
    j = evaluate(name, fn, seed=3, timeout=30)
    failed = [v.prop for v in j.verdicts if not v.passed]
    if prop in [p for p, _ in j.check.props[:j.check.gates]]:  # a gate (validity, the job) fails everything after it
        assert failed[0] == prop and j.score == 0.0, failed
    else:
        assert failed == [prop], [(v.prop, v.message) for v in j.verdicts if not v.passed]
    msg = next(v.message for v in j.verdicts if v.prop == prop)
    assert "BEGIN SOLUTION" not in msg and "argsort" not in msg and "interp" not in msg


def test_the_exploits_sims_named_each_fail_their_property():
    """The path length pays circling and wobbling; a sampled roulette gets the counts wrong and random."""
    for seed in range(4, 12):
        failed = {v.prop for v in evaluate("swimmers.fitness", fitness_path_length, seed=seed).verdicts if not v.passed}
        assert {"circling scores below a steady swimmer", "wobbling in place scores about 0"} <= failed
        # the five speeds share one sway: the path length passes the job gate on every seed (s25: 0 / 5 on some)
        assert "faster steady swimmers score higher" not in failed
        # its durations are right: the resampled swims are the same swim, sway included (s25: each had its own
        # sway, and the path length failed "time in seconds" with "measure durations with the times array")
        assert "time in seconds: any sample rate, duration and start" not in failed
    failed = {v.prop for v in evaluate("swimmers.reproduce", reproduce_roulette_survivors, seed=4).verdicts if not v.passed}
    assert {"offspring in proportion to fitness", "the same counts whatever the seed"} <= failed
    # equal shares for every survivor ignores fitness, the operator's point: about two thirds (it kept 90 %, round 6)
    j = evaluate("swimmers.reproduce", reproduce_uniform_survivors, seed=4)
    assert j.score <= 0.7 * j.check.points, j.score


def reproduce_ignores_survival(fitness, k, rng, survival=0.2):  # always the best fifth (s25: 69 %)
    return reproduce(fitness, k, rng)


def reproduce_extras_to_the_best(fitness, k, rng, survival=0.2):  # quotas floored, the rest to the best (s25: 69 %)
    s = survivors_of(fitness, survival)
    f = np.asarray(fitness, dtype=float)[s]
    quota = k * f / f.sum() if f.sum() > 0 else np.full(len(s), k / len(s))
    counts = np.floor(quota).astype(int)
    counts[0] += k - counts.sum()
    return rng.permutation(np.repeat(s, counts))


@pytest.mark.parametrize("fn", [reproduce_ignores_survival, reproduce_extras_to_the_best])
def test_wrong_offspring_counts_keep_at_most_half(fn):
    """Sims' counts are the scheme's definition and weigh half the check; an ignored survival argument is
    caught on every seed (s25: 5 / 5 on some)."""
    for seed in range(4, 12):
        j = evaluate("swimmers.reproduce", fn, seed=seed)
        failed = [v for v in j.verdicts if not v.passed]
        assert "offspring in proportion to fitness" in [v.prop for v in failed] and j.score <= 0.5 * j.check.points, j.score
        if fn is reproduce_ignores_survival:
            assert [v.prop for v in failed] == ["offspring in proportion to fitness"]
            assert "use the survival argument" in failed[0].message


def test_a_swimmer_that_comes_back_is_negative_by_sims_recipe_before_clipping():
    from coursekit.grading.checks.ex08_fitness_and_reproduction import out_and_back

    t = sample_times(10.0)
    rng = np.random.default_rng(0)
    for _ in range(50):
        p = np.stack([out_and_back(t, rng.uniform(0.5, 2.0), rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.15))])
        d = np.linalg.norm(p[0], axis=1)
        assert d[0] == 0 and d[-1] < 1e-12 and fitness_unclipped(p, t)[0] < 0 and fitness(p, t)[0] == 0


def constant(com, times):
    return np.full(len(com), 0.3)


def zeros(com, times):
    return np.zeros(len(com))


def random_fitness(com, times):
    return np.random.default_rng().uniform(0, 1, len(com))


def first_index(fitness, k, rng, survival=0.2):
    return np.zeros(k, dtype=np.int64)


def best_only(fitness, k, rng, survival=0.2):
    return np.full(k, int(np.argmax(fitness)))


def anyone(fitness, k, rng, survival=0.2):
    return rng.integers(0, len(fitness), size=k)


@pytest.mark.parametrize("name, fn", [("swimmers.fitness", constant), ("swimmers.fitness", zeros),
                                      ("swimmers.fitness", random_fitness), ("swimmers.reproduce", first_index),
                                      ("swimmers.reproduce", best_only), ("swimmers.reproduce", anyone)])
def test_do_nothing_answers_score_zero_at_the_job_gate(name, fn):
    j = evaluate(name, fn, timeout=30)
    assert j.attempted and j.score == 0.0
    failed = [v for v in j.verdicts if not v.passed]
    job = j.check.props[1][0]
    assert failed[0].prop == job and "Nothing else is judged" in failed[0].message, failed[0]
    assert all(v.message.startswith("not checked until") for v in failed[1:])


def test_messages_are_specific():
    msg = {v.prop: v.message for v in evaluate("swimmers.fitness", fitness_final_distance).verdicts}
    assert "kicked once" in msg["one push and coasting scores below a steady swimmer"]
    msg = {v.prop: v.message for v in evaluate("swimmers.fitness", fitness_per_sample).verdicts}
    assert "times array" in msg["time in seconds: any sample rate, duration and start"]
    msg = {v.prop: v.message for v in evaluate("swimmers.reproduce", reproduce_uniform_survivors).verdicts}
    assert "should get" in msg["offspring in proportion to fitness"]


# -- the drawn paths are what they claim -----------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(st.floats(0.01, 1.0), st.floats(0.0, 0.03), st.floats(0.5, 2.0), st.sampled_from([30.0, 60.0, 120.0]),
       st.floats(2.0, 12.0), st.floats(0.0, 5.0))
def test_a_steady_swimmer_moves_at_its_speed(speed, wobble, freq, rate, seconds, start):
    t = sample_times(seconds, rate, start)
    p = steady_swimmer(t, speed, (1.0, 2.0, -0.5), wobble=wobble, frequency=freq, phase=0.7)
    assert np.allclose(p[0], 0.0, atol=1e-15) and t[0] == start
    forward = p @ (np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5]))
    np.testing.assert_allclose(forward, speed * (t - t[0]), atol=1e-12)  # the sway is sideways only
    assert np.max(np.linalg.norm(p - forward[:, None] * (np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])),
                                 axis=1)) <= 2 * wobble + 1e-12


def test_one_push_covers_its_distance_mostly_early_and_circling_stays_on_its_circle():
    t = sample_times(10.0)
    p = one_push(t, 2.0, tau=0.5)
    d = np.linalg.norm(p, axis=1)
    assert d[0] == 0 and math.isclose(d[-1], 2.0) and np.all(np.diff(d) > 0) and d[60] > 0.85 * 2.0
    c = circling(t, 0.25, 0.75, phase=1.0)
    centre = -0.25 * np.array([math.cos(1.0), math.sin(1.0), 0.0])
    np.testing.assert_allclose(np.linalg.norm(c - centre, axis=1), 0.25, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(np.diff(c, axis=0), axis=1).sum(), 0.75 * 10.0, rtol=1e-3)
    w = in_place(t, 0.02, 1.0)
    assert np.max(np.linalg.norm(w, axis=1)) <= 0.03 and np.linalg.norm(np.diff(w, axis=0), axis=1).sum() > 1.0


def test_paths_travel_as_json_and_compute_plain_arrays():
    p = Paths.from_json(Paths.to_json(np.arange(24.0).reshape(2, 4, 3).view(Paths)))
    assert isinstance(p, np.ndarray) and p.shape == (2, 4, 3)
    for result in (p - p[:, :1], np.linalg.norm(p, axis=2), p.max(axis=1), np.diff(p, axis=1), np.maximum(p, 0)):
        assert type(result) is np.ndarray  # what a student's function returns converts like any array
    q = Paths.from_json(p.to_json())
    q -= 1.0  # in place: the object the grader holds sees it
    assert type(q) is Paths and json.loads(q.to_json()) != json.loads(p.to_json())
    with pytest.raises(ValueError, match="coursekit.paths/1"):
        Paths.from_json('{"format": "other/1", "paths": []}')


def test_quotas_share_out_k_and_survivors_are_the_best():
    f = np.array([0.1, 0.5, 0.0, 0.3, 0.2, 0.4, 0.0])
    assert survivors_of(f).tolist() == [1, 5]  # ceil(1.4) = 2
    q = quotas(f, 5)
    assert math.isclose(sum(q.values()), 5) and math.isclose(q[1] / q[5], 0.5 / 0.4)
    assert quotas(np.zeros(10), 8) == {0: 4.0, 1: 4.0}


# -- the student's functions breed real swimmers ---------------------------------------------------


def test_the_solution_fitness_scores_real_swims_like_the_library():
    rng = np.random.default_rng(3)
    crowd = [Creature.figure1_snake()] + [Creature.random(rng, max_parts=8) for _ in range(3)]
    result = simulate(crowd, 1.5)
    ok = ~result.diverged
    np.testing.assert_allclose(fitness(result.com, result.times)[ok], result.fitness[ok], rtol=1e-9, atol=1e-12)


def test_the_solution_reproduction_drives_evolve_swimmers_like_the_library_selector():
    """Same counts as ga.sims_select, so evolve_swimmers with either breeds the same kind of generation."""
    rng = np.random.default_rng(9)
    for n in (5, 12, 30, 300):
        f = rng.gamma(2.0, 0.05, n) * (rng.random(n) > 0.3)
        k = n - math.ceil(n / 5)
        mine = np.bincount(reproduce(f, k, np.random.default_rng(1)), minlength=n)
        lib = np.bincount(ga.sims_select(f, k, np.random.default_rng(1)), minlength=n)
        assert mine.tolist() == lib.tolist()


def wrapped_library_fitness(com, times):
    return library_fitness(com, times)


@pytest.mark.parametrize("name, wrapper", [("swimmers.fitness", wrapped_library_fitness), ("swimmers.reproduce", library_select)])
def test_the_library_versions_are_refused_while_graded(name, wrapper):
    """Summative grading refuses coursekit's own fitness and Sims selection inside the student's function."""
    check = checks.get(name)
    cases = check.cases(np.random.default_rng(7))
    records = run_cases(wrapper, cases, check.output, timeout=30, refuse=check.reference)
    assert {r["status"] for r in records} == {"error"}
    assert "is not available while your" in records[0]["error"]
    honest = fitness if name == "swimmers.fitness" else reproduce
    assert {r["status"] for r in run_cases(honest, cases, check.output, timeout=30, refuse=check.reference)} == {"ok"}
