"""Checks, runner and strict validation, without kernels: known-good implementations pass,
known-wrong ones fail exactly the property they violate, and malformed data is refused."""

import json
import math
import os
from pathlib import Path

import nbformat
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coursekit.grading import checks, evaluate, runner, stats
from coursekit.grading.formative import check as formative_check, format_judgement
from coursekit.grading.channel import read_results, validate_call
from coursekit.grading.grader import make_plan
from check_points import assert_a_point_weighs_half
from solution_cells import solution_functions

ROOT = Path(__file__).resolve().parent.parent
NAMES = ["ga.truncation", "ga.tournament", "ga.roulette", "ga.one_point_crossover", "ga.point_mutation"]


SOL = solution_functions("01_selection.ipynb", {"np": np, "math": math})


# Independent second implementations (loops, different rng draws) -- checks must not depend on the draw order.
def truncation_loop(fitness, k, rng, survival=0.2):
    order = sorted(range(len(fitness)), key=lambda i: -fitness[i])[: math.ceil(survival * len(fitness))]
    return [order[int(rng.random() * len(order))] for _ in range(k)]


def tournament_loop(fitness, k, rng, size=3):
    out = []
    for _ in range(k):
        contestants = rng.choice(len(fitness), size=size, replace=True)
        out.append(int(max(contestants, key=lambda i: fitness[i])))
    return np.array(out)


def roulette_cumsum(fitness, k, rng):
    return np.searchsorted(np.cumsum(fitness), rng.random(k) * np.sum(fitness), side="right")


def crossover_mask(a, b, rng):
    c = rng.integers(len(a) - 1) + 1
    left = np.arange(len(a)) < c
    return np.where(left, a, b), np.where(left, b, a)


def mutation_xor(genome, rng, rate=None):
    p = 1 / genome.size if rate is None else rate
    return genome ^ (rng.random(genome.shape) < p).astype(genome.dtype)


OTHERS = {"ga.truncation": truncation_loop, "ga.tournament": tournament_loop, "ga.roulette": roulette_cumsum,
          "ga.one_point_crossover": crossover_mask, "ga.point_mutation": mutation_xor}


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("seed", [0, 1])
def test_correct_implementations_get_full_marks(name, seed):
    for fn in (SOL[name.split(".")[1]], OTHERS[name]):
        j = evaluate(name, fn, seed=seed)
        assert j.passed and j.score == j.check.points, [v for v in j.verdicts if not v.passed]


# -- known-wrong implementations fail the property they violate -------------------------------------


def truncation_floor(fitness, k, rng, survival=0.2):
    m = int(survival * len(fitness))
    return np.argsort(fitness)[::-1][:m][rng.integers(0, m, size=k)]


def truncation_worst(fitness, k, rng, survival=0.2):
    m = math.ceil(survival * len(fitness))
    return np.argsort(fitness)[:m][rng.integers(0, m, size=k)]


def truncation_skewed(fitness, k, rng, survival=0.2):
    m = math.ceil(survival * len(fitness))
    best = np.argsort(fitness)[::-1][:m]
    return best[np.minimum(rng.integers(0, m, size=k), rng.integers(0, m, size=k))]


def tournament_no_replacement(fitness, k, rng, size=3):
    c = np.array([rng.choice(len(fitness), size=size, replace=False) for _ in range(k)])
    return c[np.arange(k), np.argmax(np.asarray(fitness)[c], axis=1)]


def tournament_ignores_size(fitness, k, rng, size=3):
    return SOL["tournament"](fitness, k, rng, size=3)


def tournament_global_rng(fitness, k, rng, size=3):
    return SOL["tournament"](fitness, k, np.random.default_rng(), size=size)


def tournament_short(fitness, k, rng, size=3):
    return SOL["tournament"](fitness, k - 1, rng, size=size)


def tournament_sorts_input(fitness, k, rng, size=3):
    fitness.sort()
    return SOL["tournament"](fitness, k, rng, size=size)


def roulette_uniform(fitness, k, rng):
    return rng.integers(0, len(fitness), size=k)


def roulette_smoothed(fitness, k, rng):
    p = np.asarray(fitness) + 0.1
    return rng.choice(len(fitness), size=k, p=p / p.sum())


def crossover_cut_anywhere(a, b, rng):
    c = int(rng.integers(0, len(a) + 1))
    return np.concatenate([a[:c], b[c:]]), np.concatenate([b[:c], a[c:]])


def crossover_adds(a, b, rng):
    c = int(rng.integers(1, len(a)))
    return a[:c] + b[c:] if c == len(a) - c else np.concatenate([a[:c], b[c:]]), a + b


def crossover_biased(a, b, rng):
    c = 1 + min(int(rng.integers(0, len(a) - 1)), int(rng.integers(0, len(a) - 1)))
    return np.concatenate([a[:c], b[c:]]), np.concatenate([b[:c], a[c:]])


def mutation_one_flip(genome, rng, rate=None):
    g = genome.copy()
    i = rng.integers(len(g))
    g[i] = 1 - g[i]
    return g


def mutation_in_place(genome, rng, rate=None):
    rate = 1 / len(genome) if rate is None else rate
    genome[rng.random(len(genome)) < rate] ^= 1
    return genome


def mutation_ignores_rate(genome, rng, rate=None):
    return SOL["point_mutation"](genome, rng)


def mutation_default_two_per_len(genome, rng, rate=None):
    return SOL["point_mutation"](genome, rng, 2 / len(genome) if rate is None else rate)


def roulette_proportional_to_rank(fitness, k, rng):
    r = np.argsort(np.argsort(fitness)) * (np.asarray(fitness) > 0)
    return rng.choice(len(fitness), size=k, p=r / r.sum())


def crossover_global_rng(a, b, rng):
    return SOL["one_point_crossover"](a, b, np.random.default_rng())


def mutation_global_rng(genome, rng, rate=None):
    return SOL["point_mutation"](genome, np.random.default_rng(), rate)


WRONG = [
    ("ga.truncation", truncation_floor, "rounds the survivor count up"),
    ("ga.truncation", truncation_worst, "only the best survive"),
    ("ga.truncation", truncation_skewed, "uniform among survivors"),
    ("ga.tournament", tournament_no_replacement, "the fittest of size contestants wins"),
    ("ga.tournament", tournament_ignores_size, "the fittest of size contestants wins"),
    ("ga.tournament", tournament_global_rng, "deterministic for a seed"),
    ("ga.tournament", tournament_short, "returns k valid indices"),
    ("ga.tournament", tournament_sorts_input, "inputs unchanged"),
    ("ga.roulette", roulette_uniform, "never picks zero fitness"),
    ("ga.roulette", roulette_smoothed, "never picks zero fitness"),
    ("ga.one_point_crossover", crossover_cut_anywhere, "children are one-point crossovers"),
    ("ga.one_point_crossover", crossover_adds, "children are one-point crossovers"),
    ("ga.one_point_crossover", crossover_biased, "cut point uniform"),
    ("ga.point_mutation", mutation_one_flip, "each bit flips independently with probability rate"),
    ("ga.point_mutation", mutation_in_place, "input unchanged"),
    ("ga.point_mutation", mutation_ignores_rate, "each bit flips independently with probability rate"),
    ("ga.point_mutation", mutation_default_two_per_len, "default rate is 1/len"),
    ("ga.roulette", roulette_proportional_to_rank, "proportional to fitness"),
    ("ga.one_point_crossover", crossover_global_rng, "deterministic for a seed"),
    ("ga.point_mutation", mutation_global_rng, "deterministic for a seed"),
]


@pytest.mark.parametrize("name,fn,prop", WRONG, ids=[w[1].__name__ for w in WRONG])
def test_wrong_implementations_fail_the_violated_property(name, fn, prop):
    j = evaluate(name, fn)
    failed = {v.prop for v in j.verdicts if not v.passed}
    assert prop in failed, j.verdicts
    assert j.score < j.check.points


def truncation_one_short(fitness, k, rng, survival=0.2):
    m = math.ceil(survival * len(fitness))
    return np.argsort(fitness)[::-1][:m][rng.integers(0, max(m - 1, 1), size=k)]  # the last survivor never drawn


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_truncation_says_which_survivor_is_never_picked_without_dictating_code(seed):
    """An upper bound drawn one short (honest-student study) was reported under "rounds the survivor count up",
    with a message that told the fix in code; it is a survivor never picked, judged by "uniform among survivors"."""
    def verdicts(fn):
        return {v.prop: v for v in evaluate("ga.truncation", fn, seed=seed).verdicts}

    short = verdicts(truncation_one_short)
    first = next(v for v in short.values() if not v.passed)  # the one the grader's summary line shows
    assert first.prop == "uniform among survivors"
    assert "the last of them" in short["uniform among survivors"].message and "never picked" in short["uniform among survivors"].message
    assert short["rounds the survivor count up"].message.startswith("not checked:")
    assert not any("integers" in v.message for v in short.values())
    floor = verdicts(truncation_floor)
    assert "round up" in floor["rounds the survivor count up"].message and floor["uniform among survivors"].passed


def test_roulette_detects_wrong_proportions_beyond_zero_handling():
    j = evaluate("ga.roulette", roulette_proportional_to_rank)
    assert {v.prop: v.passed for v in j.verdicts} == {
        "runs": True, "returns k valid indices": True, "prefers fitter individuals": True, "never picks zero fitness": True,
        "proportional to fitness": False, "deterministic for a seed": True, "inputs unchanged": True}
    assert j.score == 1.0  # it does the job, but not roulette's: half the points (the point weighs half)


# Buggy answers of the honest-student study that kept 71-89 % while getting the operator's definition wrong: each
# keeps at most half now (the point weighs as much as everything else together); a bug elsewhere costs less.
CORE_BUGS = [
    ("ga.truncation", truncation_one_short), ("ga.truncation", truncation_skewed),
    ("ga.tournament", tournament_ignores_size), ("ga.tournament", tournament_no_replacement),
    ("ga.roulette", roulette_proportional_to_rank),
    ("ga.one_point_crossover", crossover_biased), ("ga.one_point_crossover", crossover_cut_anywhere),
    ("ga.point_mutation", mutation_one_flip), ("ga.point_mutation", mutation_ignores_rate),
]


@pytest.mark.parametrize("name,fn", CORE_BUGS, ids=[f.__name__ for _, f in CORE_BUGS])
def test_getting_the_definition_wrong_keeps_at_most_half(name, fn):
    j = evaluate(name, fn)
    assert 0 < j.score <= j.check.points / 2, [(v.prop, v.passed) for v in j.verdicts]


@pytest.mark.parametrize("name,fn", [("ga.point_mutation", mutation_in_place), ("ga.truncation", truncation_floor)])
def test_a_detail_wrong_keeps_more_than_half(name, fn):
    assert evaluate(name, fn).score > checks.get(name).points / 2


@pytest.mark.parametrize("name", NAMES)
def test_every_check_has_a_point_weighing_half(name):
    assert_a_point_weighs_half(name)


@pytest.mark.parametrize("name,fn", [("ga.one_point_crossover", crossover_global_rng),
                                     ("ga.point_mutation", mutation_global_rng)])
@pytest.mark.parametrize("seed", range(6))
def test_a_global_generator_is_caught_on_every_seed(name, fn, seed):
    """The determinism case repeats 3 seeds 4 times with many outcomes per call: a cut from np.random (9 possible)
    repeated 4 times by chance for one seed with probability 1/729, and a mutation at rate 1/len flips nothing
    in one call in three."""
    j = evaluate(name, fn, seed=seed)
    assert not {v.prop: v.passed for v in j.verdicts}["deterministic for a seed"]


# -- formative messages ---------------------------------------------------------------------------


def test_formative_reports_counts_not_attempted_and_exceptions_with_input(capsys):
    formative_check("ga.tournament", tournament_short)
    out = capsys.readouterr().out
    assert "returned 19 individuals, expected k=20" in out

    def todo(fitness, k, rng, size=3):
        raise NotImplementedError()

    formative_check("ga.tournament", todo)
    assert "not attempted yet" in capsys.readouterr().out

    def broken(fitness, k, rng, size=3):
        return 1 / 0

    formative_check("ga.tournament", broken)
    out = capsys.readouterr().out
    assert "raised ZeroDivisionError" in out and "tournament(fitness=[" in out and "k=20" in out and "default_rng(" in out


def test_formative_never_prints_the_solution(capsys):
    nb = nbformat.read(ROOT / "solutions" / "01_selection.ipynb", as_version=4)
    answers = [ln.strip() for c in nb.cells if "# BEGIN SOLUTION" in c.source
               for ln in c.source.split("# BEGIN SOLUTION")[1].split("# END SOLUTION")[0].splitlines() if ln.strip()]
    assert len(answers) > 10
    for name, fn, _ in WRONG:
        formative_check(name, fn)
    out = capsys.readouterr().out
    assert out.count("✗") >= len(WRONG)
    leaked = [ln for ln in answers if ln in out]
    assert not leaked and "argmax" not in out and "rng.choice" not in out and "concatenate" not in out, leaked


def test_timeouts_crashes_and_exits_cost_one_case_not_the_process():
    def loop(fitness, k, rng, size=3):
        while True:
            pass

    j = evaluate("ga.tournament", loop, timeout=0.5)
    assert j.score == 0 and "did not return in time" in j.verdicts[0].message

    def die(fitness, k, rng):
        os._exit(5)

    j = evaluate("ga.roulette", die)
    assert "exited with status 5" in j.verdicts[0].message

    def exits(fitness, k, rng):
        raise SystemExit(0)

    assert "raised SystemExit" in evaluate("ga.roulette", exits).verdicts[0].message

    def hog(genome, rng, rate=None):
        return np.ones(2**38)

    assert "MemoryError" in evaluate("ga.point_mutation", hog, memory_mb=512).verdicts[0].message


def test_a_memory_limit_past_what_rlimit_holds_means_no_extra_limit():
    # coursekit grade --memory-mb 99999999999999: setrlimit overflowed in every worker, so every
    # call "exited with status 0" and a correct notebook scored 0
    j = evaluate("ga.point_mutation", mutation_xor, memory_mb=10**14)
    assert j.passed and j.score == j.check.points, [v for v in j.verdicts if not v.passed]


def test_thread_isolation_gives_the_same_verdicts_and_reports_timeouts(monkeypatch):
    monkeypatch.setenv("COURSEKIT_CHECK_ISOLATION", "thread")
    assert evaluate("ga.tournament", tournament_loop).passed
    assert "each bit flips independently with probability rate" in {
        v.prop for v in evaluate("ga.point_mutation", mutation_one_flip).verdicts if not v.passed}

    def slow(fitness, k, rng, size=3):
        import time
        time.sleep(1.0)

    j = evaluate("ga.tournament", slow, timeout=0.2)  # the abandoned threads finish their sleep on their own
    assert j.score == 0 and "did not return in time" in j.verdicts[0].message


def test_time_budget_bounds_a_whole_check_of_slow_calls():
    import time

    def slow(a, b, rng):
        time.sleep(0.05)
        return crossover_mask(a, b, rng)

    check = checks.get("ga.one_point_crossover")
    cases = check.cases(np.random.default_rng(0))  # 600 calls: 30 s of sleeping
    records = runner.run_cases(slow, cases, check.output, timeout=5, budget=1.0)
    assert [r["status"] for r in records] == ["ok", "ok", "timeout"]
    assert "time budget of 1 s" in records[2]["error"]


def test_check_argument_errors_are_clear():
    with pytest.raises(ValueError, match="unknown check 'ga.nope'.*ga.tournament"):
        evaluate("ga.nope", truncation_loop)
    with pytest.raises(TypeError, match="must be callable"):
        evaluate("ga.tournament", 42)
    with pytest.raises(ValueError, match="timeout must be a positive"):
        evaluate("ga.tournament", tournament_loop, timeout=0)
    with pytest.raises(ValueError, match="no exercise is registered for notebook '99_x'"):
        checks.for_notebook("99_x")


# -- strict conversion and validation --------------------------------------------------------------


class EvilInt(int):
    def __eq__(self, other):
        return True

    __hash__ = int.__hash__


class RiggedArray(np.ndarray):
    def __eq__(self, other):
        return True


@pytest.mark.parametrize("kind,value", [
    ("indices", [EvilInt(1)]), ("indices", [True, False]), ("indices", [1.0, 2.0]), ("indices", np.zeros(3)),
    ("indices", np.zeros(3, int).view(RiggedArray)), ("indices", np.zeros((2, 2), int)), ("indices", {1, 2}),
    ("indices", list(range(11))), ("array", [EvilInt(1)]), ("array", np.array(["a"])), ("array", np.array([np.nan])),
    ("array_pair", (np.zeros(2),)), ("array_pair", [np.zeros(2), ["0", 1]]), ("array", np.zeros(11)),
    ("array", [0.0] * 11), ("array", [float("inf")]), ("array", np.zeros(2).view(RiggedArray)),
])
def test_convert_refuses_anything_but_plain_numbers(kind, value):
    with pytest.raises(runner.BadOutput):
        runner.convert(kind, value, max_len=10)


def test_a_list_or_tuple_of_plain_numbers_is_read_as_an_array():
    assert runner.convert("array", [0, 1], 10) == [0, 1] and runner.convert("array", (0.5, np.float32(2)), 10) == [0.5, 2.0]
    assert runner.convert("array_pair", [np.zeros(2), [0, 1]], 10) == [[0.0, 0.0], [0, 1]]
    assert runner.convert("array", [True, False], 10) == [1, 0]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(-2**62, 2**62), max_size=10), st.sampled_from(["int8", "int64", "uint16", "list"]))
def test_convert_keeps_integer_values_exactly(values, how):
    if how == "list":
        out = runner.convert("indices", list(values), 10)
    else:
        info = np.iinfo(how)
        values = [min(max(v, info.min), info.max) for v in values]
        out = runner.convert("indices", np.array(values, dtype=how), 10)
    assert out == values and all(type(v) is int for v in out)


def _plan():
    check = checks.get("ga.tournament")
    cases = check.cases(np.random.default_rng(3))
    _, lookup = make_plan([check], {check.name: cases}, np.random.default_rng(0))
    basic = next(cid for cid, (case, i, _) in lookup[check.name].items() if case == "basic" and i == 0)
    return check, cases, lookup, basic


@pytest.mark.parametrize("mutate", [
    lambda r: r.update(check="ga.roulette"), lambda r: r.update(id="nope"), lambda r: r.update(id=["x"]),
    lambda r: r.update(status="passed"), lambda r: r.pop("output"),
    lambda r: r.update(output=[True] * 20), lambda r: r.update(output=[0.5] * 20),
    lambda r: r.update(output=[0] * 5000), lambda r: r.pop("inputs_after"),
    lambda r: r.update(inputs_after=[{"ndarray": ["x"], "dtype": "float64"}, None, None]),
    lambda r: r.update(inputs_after=[None, None]), lambda r: r.update(error=5),
], ids=range(12))
def test_validate_call_refuses_malformed_records(mutate):
    check, cases, lookup, basic = _plan()
    call = lookup[check.name][basic][2]
    good = {"check": "ga.tournament", "id": basic, "status": "ok", "output": [0] * 20,
            "inputs_after": [cases[0]["args"][0], None, None]}
    assert validate_call(dict(good), check, call) is not None
    bad = json.loads(json.dumps(good))
    mutate(bad)
    assert validate_call(bad, check, lookup[check.name].get(bad["id"], (0, 0, None))[2] if type(bad["id"]) is str else None) is None


def test_read_results_ignores_garbage_and_records_for_calls_never_sent():
    check, cases, lookup, basic = _plan()
    other = next(cid for cid, (case, _, _) in lookup[check.name].items() if case == "size3")
    lines = [b"not json", b'{"check": "ga.tournament", "id": "%s", "status": "ok", "output": [NaN]}' % basic.encode(),
             json.dumps({"check": "ga.tournament", "id": other, "status": "error", "error": "boom"}).encode(),
             json.dumps({"check": "ga.tournament", "id": other, "status": "ok", "output": [0]}).encode(),
             # a forged record in the old format, for a case name instead of a call id: never sent, never counted
             json.dumps({"check": "ga.tournament", "case": "basic", "status": "ok", "outputs": [[0] * 20]}).encode(),
             json.dumps({"report": {"format": "coursekit.execution/1", "harvested": True}}).encode(),
             b"[" * 100000]
    results, report, rejected = read_results(b"\n".join(lines), [check], lookup)
    assert rejected == 5 and report == {"format": "coursekit.execution/1", "harvested": True}
    assert results == {"ga.tournament": {("size3", 0): {"id": other, "status": "error", "error": "boom"}}}


def test_every_call_has_an_opaque_id_and_the_order_is_shuffled():
    check = checks.get("ga.one_point_crossover")
    cases = check.cases(np.random.default_rng(3))
    plans, lookup = make_plan([check], {check.name: cases}, np.random.default_rng(1))
    calls = plans[0]["calls"]
    assert len(calls) == sum(len(c["seeds"]) for c in cases) == len(lookup[check.name])
    assert all(len(c["id"]) == 16 and not any(case["id"] in c["id"] for case in cases) for c in calls)
    order = [lookup[check.name][c["id"]][:2] for c in calls]
    assert order != sorted(order, key=lambda ci: ([c["id"] for c in cases].index(ci[0]), ci[1]))
    again, _ = make_plan([check], {check.name: cases}, np.random.default_rng(1))
    assert {c["id"] for c in again[0]["calls"]}.isdisjoint({c["id"] for c in calls})  # fresh ids every run


# -- statistics --------------------------------------------------------------------------------------


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 2**32 - 1), st.lists(st.floats(0.05, 1.0), min_size=2, max_size=12))
def test_chi_square_accepts_true_distribution(seed, weights):
    p = np.array(weights) / np.sum(weights)
    counts = np.random.default_rng(seed).multinomial(20000, p)
    assert stats.chi_square(counts, p)[0]


def test_chi_square_and_binomial_reject_clear_deviations():
    assert not stats.chi_square([5200, 4800], [0.45, 0.55])[0]
    ok, lo, hi = stats.binomial_ok(271, 1000, 0.271)
    assert ok and lo < 271 < hi
    assert not stats.binomial_ok(400, 1000, 0.271)[0]
    with pytest.raises(ValueError, match="sum to 1"):
        stats.chi_square([1, 2], [0.5, 0.6])


def test_the_report_gives_one_note_per_distinct_cell_error_and_keeps_skipped_cells_as_problems():
    """Five demo cells that all hit the same withheld function make one note naming them all, not
    five copies; a skipped cell stays a problem (the notebook is then not graded)."""
    from coursekit.grading.channel import read_report

    withheld = "error: RuntimeError: coursekit's own Creature.figure1_snake is withheld while this notebook is graded"
    cells = [{"index": i, "status": withheld} for i in (4, 6, 8)] + [
        {"index": 10, "status": "error: ValueError: bad"}, {"index": 11, "status": "ok"},
        {"index": 12, "status": "skipped: the notebook's time ran out"}]
    notes, problems = read_report({"format": "coursekit.execution/1", "harvested": True, "cells": cells})
    assert notes == [f"cells 5, 7, 9: {withheld}", "cell 11: error: ValueError: bad"]
    assert problems == ["cell 13: skipped: the notebook's time ran out"]


def test_a_cell_skipped_after_hundreds_of_others_still_stops_the_grade_standing():
    # red team, round 7: only the first 200 cells were read, so a cell skipped for time at the end of a long
    # notebook left it graded (exit 0)
    from coursekit.grading.channel import read_report

    cells = [{"index": i, "status": f"error: ValueError: {i}"} for i in range(300)] + [
        {"index": 300, "status": "skipped: did not finish within 10 s"}]
    notes, problems = read_report({"format": "coursekit.execution/1", "harvested": True, "cells": cells})
    assert problems == ["cell 301: skipped: did not finish within 10 s"]
    assert len(notes) == 21 and notes[-1] == "and 280 more kinds"
    notes, _ = read_report({"format": "coursekit.execution/1", "harvested": True,
                            "cells": [{"index": i, "status": "error: E"} for i in range(50)]})
    assert notes == [f"cells {', '.join(map(str, range(1, 21)))} and 30 more: error: E"]


def test_cells_stopped_by_withheld_functions_make_one_calm_line():
    """s25: 'cells 5, 7, 9, 12, 17: error: uses coursekit's own ..., withheld while grading (this costs
    nothing)', one such line per function, read like an error in the output students see."""
    from coursekit.grading.channel import read_report
    from coursekit.grading.executor import _error_name
    from coursekit.grading.withheld import MESSAGE

    def status(name):
        return "error: " + _error_name({"outputs": [{"output_type": "error", "ename": "RuntimeError",
                                                      "evalue": MESSAGE.format(name=name)}]})

    cells = [{"index": 3, "status": status("Creature.expand")}] + [{"index": i, "status": status("expand")} for i in (6, 8)] + [
        {"index": 10, "status": "error: ValueError: bad"}]
    notes, problems = read_report({"format": "coursekit.execution/1", "harvested": True, "cells": cells})
    assert notes == ["cells 4, 7, 9 call coursekit's own Creature.expand and expand, which are switched off while your "
                     "functions are graded: those cells stop there, and that does not change your score",
                     "cell 11: error: ValueError: bad"] and problems == []


def test_a_failed_call_names_its_object_arguments_in_a_few_words():
    """s25: 'runs' quoted the grader's JSON, Creature.from_json('{\\n "format": ...'...)."""
    from coursekit.grading.checks import describe_call

    check = checks.get("creatures.crossover")
    said = describe_call(check, check.cases(np.random.default_rng(0))[0])
    assert said.startswith("crossover(a=Creature(") and "brain neuron" in said and "json" not in said and "{" not in said
    check = checks.get("physics.rkn_step")
    assert "f=CountingODE('damped')" in describe_call(check, check.cases(np.random.default_rng(0))[-1])
    check = checks.get("swimmers.fitness")
    assert "com=Paths: 5 creatures, 601 samples each" in describe_call(check, check.cases(np.random.default_rng(0))[0])


def test_notes_on_the_grader_stay_out_of_what_students_read_and_the_summary_keeps_its_columns():
    from coursekit.grading.checks import Judgement
    from coursekit.grading.report import NotebookResult, gradescope, summary

    graded = [checks.get("pictures.root_transposition"), checks.get("ga.tournament")]
    r = NotebookResult("nb.ipynb", [Judgement(c, True, [], c.points) for c in graded],
                       ["cell 4: error: ValueError: bad"], grader_notes=["ran as root: user 'nobody' could not run this Python"])
    g = gradescope([r])
    assert "ran as root" not in g["output"] and "cell 4" in g["output"]
    assert g["extra_data"]["notebooks"][0]["grader_notes"] == ["ran as root: user 'nobody' could not run this Python"]
    text = summary([r])
    assert "grader: ran as root" in text
    rows = [ln for ln in text.splitlines() if "all properties hold" in ln]
    assert len(rows) == 2 and len({ln.index(" / ") for ln in rows}) == 1 and len({ln.index("all") for ln in rows}) == 1, rows


def test_a_cells_error_is_shown_short_and_cut_between_words():
    """A demo cell that hits a withheld function is named by the function (the message would fill
    the results' line, cut mid-word: a student's walk); any other long message ends in "…" at a
    word boundary."""
    from coursekit.grading.executor import ERROR_CHARS, _error_name
    from coursekit.grading.withheld import MESSAGE

    def cell(ename, evalue):
        return {"outputs": [{"output_type": "error", "ename": ename, "evalue": evalue}]}

    said = _error_name(cell("RuntimeError", MESSAGE.format(name="Creature.figure1_snake")))
    assert said == "uses coursekit's own Creature.figure1_snake, withheld while grading (this costs nothing)"
    long = _error_name(cell("ValueError", "the shape " + "is wrong " * 40))
    assert len(long) <= ERROR_CHARS and long[:-1].rsplit(" ", 1)[1] in ("is", "wrong") and long.endswith("…"), long
    assert _error_name(cell("ValueError", "bad")) == "ValueError: bad" and _error_name({"outputs": []}) is None


# -- one easy part of the job is not nearly full marks ----------------------------------------------


def crossover_fixed_cut(a, b, rng):
    return np.concatenate([a[:1], b[1:]]), np.concatenate([b[:1], a[1:]])  # always after the first gene


def fitness_final_distance(com, times):
    return np.linalg.norm(com[:, -1] - com[:, 0], axis=1) / (times[-1] - times[0])  # no late weighting


def mutate_force_only(c, rng, rate=1.0):
    from coursekit.creatures.genotype import FORCES

    child = c.copy()
    if rng.random() < min(1.0, rate):
        node = child.nodes[int(rng.integers(len(child.nodes)))]
        others = [f for f in FORCES if abs(f - node.force) > 1e-9]
        node.force = others[int(rng.integers(len(others)))]
    return child


@pytest.mark.parametrize("name, fn, prop, weight, at_most", [
    ("ga.one_point_crossover", crossover_fixed_cut, "cut point uniform", 6, 0.5),
    ("swimmers.fitness", fitness_final_distance, "one push and coasting scores below a steady swimmer", 4, 0.78),
    ("creatures.mutate", mutate_force_only, "deletes, adds and modifies in six steps, about one node per call, "
                                            "scaled by rate", 8, 0.5),
])
def test_the_operators_point_weighs_more_than_one_property(name, fn, prop, weight, at_most):
    """Red team, round 2: answers that did one easy part of the job -- a fixed cut, the final distance
    without Sims' late weighting, one kind of change -- earned 86-91 %; the property that is the
    operator's point counts several times, and says so."""
    j = evaluate(name, fn, seed=7)
    failed = [v for v in j.verdicts if not v.passed]
    assert [v.prop for v in failed] == [prop] and failed[0].weight == weight
    total = sum(v.weight for v in j.verdicts)
    assert j.score == pytest.approx(j.check.points * (total - weight) / total, abs=1e-4) and j.score <= at_most * j.check.points
    assert f"{prop} (counts {weight}x)" in format_judgement(j)
