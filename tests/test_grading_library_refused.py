"""The library's own implementation is not the student's answer (issue 13, part 3).

In summative grading a graded function must be written in the notebook: one whose code comes
from coursekit (an import, an alias, a function rebuilt from the library's code) or from any
file that is not one of the notebook's cells is refused as not attempted, and coursekit's own
versions of the graded function raise while the student's runs (a wrapper scores 0). The rest
of the library stays usable. End to end: tests/adversarial/library_answers.ipynb.
"""

import types

import numpy as np
import pytest

from coursekit import ga
from coursekit.grading import checks
from coursekit.grading.executor import Relay
from coursekit.grading.runner import assemble, calls_of, harvest, run_cases

CHECK = checks.get("ga.tournament")
CASES = CHECK.cases(np.random.default_rng(5))


def wrapper(fitness, k, rng, size=3):
    return ga.tournament(fitness, k, rng, size=size)


def own(fitness, k, rng, size=3):
    fitness = np.asarray(fitness)
    c = rng.integers(0, len(fitness), size=(k, size))
    return c[np.arange(k), np.argmax(fitness[c], axis=1)]


@pytest.mark.parametrize("isolation", ["fork", "thread"])
def test_a_wrapper_of_the_library_version_raises_while_graded_and_the_library_comes_back(monkeypatch, isolation):
    monkeypatch.setenv("COURSEKIT_CHECK_ISOLATION", isolation)
    recs = run_cases(wrapper, CASES, "indices", timeout=20, refuse=CHECK.reference)
    assert {r["status"] for r in recs} == {"error"}
    assert "coursekit's own tournament is not available while your wrapper is graded" in recs[0]["error"]
    assert len(ga.tournament(np.arange(5.0), 3, np.random.default_rng(0))) == 3  # put back afterwards
    assert {r["status"] for r in run_cases(own, CASES, "indices", timeout=20, refuse=CHECK.reference)} == {"ok"}


def test_the_library_is_usable_outside_the_refused_functions():
    def uses_selection_helpers(fitness, k, rng, size=3):
        return own(fitness, k, rng, size) if ga.truncation is not None else None  # another selection is fine

    assert {r["status"] for r in run_cases(uses_selection_helpers, CASES, "indices", timeout=20,
                                           refuse=CHECK.reference)} == {"ok"}


class _Collect:
    """Stands in for the grader's results pipe."""

    def __init__(self):
        self.records = []

    def send(self, obj):
        self.records.append(obj)


def _harvest(tmp_path, fn, cells):
    """Serve the cases' calls to harvest() over the grading child's relay, as in a grading run;
    return the per-case records the grader would judge."""
    calls = [{**call, "group": g} for g, case in enumerate(CASES) for call in calls_of([case])]
    header = {"name": CHECK.name, "function": "tournament", "output": CHECK.output, "refuse": list(CHECK.reference),
              "timeout": 20.0, "memory_mb": 2048, "budget": 110.0}
    out = _Collect()
    relay = Relay(str(tmp_path / "h.sock"), "token", header, calls, out, 60)
    relay.start()
    harvest({"tournament": fn}, str(tmp_path / "h.sock"), "token", cells)
    relay.join(10)
    (tmp_path / "h.sock").unlink()
    by_call = {}
    for rec in out.records:
        case_id, _, index = rec["id"].rpartition("#")
        by_call[(case_id, int(index))] = rec
    return assemble(CASES, by_call)


def test_a_graded_function_not_written_in_the_notebook_is_refused(tmp_path):
    rebuilt = types.FunctionType(ga.tournament.__code__, ga.tournament.__globals__, "tournament", ga.tournament.__defaults__)
    for fn, where in [(ga.tournament, "is coursekit's own, from coursekit.ga.selection"),
                      (rebuilt, "is coursekit's own, from coursekit.ga.selection"),
                      (own, "is not defined in this notebook (its code comes from test_grading_library_refused.py)")]:
        recs = _harvest(tmp_path, fn, cells={"/tmp/ipykernel_1/123.py"})
        assert {r["status"] for r in recs} == {"missing"} and where in recs[0]["error"], recs[0]
    recs = _harvest(tmp_path, own, cells={own.__code__.co_filename})  # written in a cell: graded
    assert {r["status"] for r in recs} == {"ok"}
    judged = checks.judge(CHECK, CASES, {r["case"]: r for r in _harvest(tmp_path, ga.tournament, {"x"})})
    assert judged.score == 0.0 and "write your own with def in a cell" in judged.verdicts[0].message


def test_every_check_names_the_library_versions_it_refuses():
    from coursekit.grading.runner import _library_attr

    for name in checks.REGISTRY:
        ref = checks.get(name).reference
        assert ref, f"{name} names no library version to refuse"
        for path in ref:
            assert callable(_library_attr(path)), path
