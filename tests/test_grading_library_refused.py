"""The library's own implementation is not the student's answer (issue 13, part 3).

In summative grading a graded function must be written in the notebook: one whose code comes
from coursekit (an import, an alias, a function rebuilt from the library's code) or from any
file that is not one of the notebook's cells is refused as not attempted, and coursekit's own
versions of the graded function raise while the student's runs (a wrapper scores 0). The rest
of the library stays usable. The process that runs the student's function is locked down, so
the library's code cannot be fetched at call time either (a copy made in a cell, its source
compiled afresh, a fresh Python). End to end: tests/adversarial/library_answers.ipynb and
library_at_call_time.ipynb.

Also here, since it is observed on the same path: "inputs unchanged" is read from outside the
kernel (array arguments in shared memory), so a function that hides its side effect from the
kernel's own observer is still caught (end to end: tests/adversarial/fakes_unchanged.ipynb).
"""

import importlib.util
import inspect
import subprocess
import sys
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
    """Serve the cases' calls to harvest() over the grading child's relay, as in a grading run
    (array arguments in shared memory); return the per-case records the grader would judge."""
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
    from coursekit.grading.values import library_attr

    for name in checks.REGISTRY:
        ref = checks.get(name).reference
        assert ref, f"{name} names no library version to refuse"
        for path in ref:
            assert callable(library_attr(path)), path


COPY = types.FunctionType(ga.tournament.__code__, ga.tournament.__globals__, "copy")  # made "in a cell"
SAVED_CODE = ga.tournament.__code__
RENAMED = types.FunctionType(ga.tournament.__code__.replace(co_name="mine", co_firstlineno=1), ga.tournament.__globals__)


def renamed_copy(fitness, k, rng, size=3):
    return RENAMED(fitness, k, rng, size)  # another code object, made "in a cell": the same content


_CODE = ga.tournament.__code__
PADDED = types.FunctionType(_CODE.replace(co_consts=_CODE.co_consts + ("x",), co_filename="<cell>"), ga.tournament.__globals__)
_SOURCE = inspect.getsource(ga.tournament).replace("Pick k parents", "My k parents").replace("contestants", "who")
_NS = dict(ga.tournament.__globals__)
exec(compile(_SOURCE, "<cell>", "exec"), _NS)  # its docstring and a local variable's name changed, made before grading
RETYPED = _NS["tournament"]


TREE = __import__("ast").parse(inspect.getsource(ga.tournament))  # the library's code as a syntax tree, before grading


def compiled_from_a_tree(fitness, k, rng, size=3):
    fresh = dict(ga.tournament.__globals__)
    exec(compile(TREE, "<cell>", "exec"), fresh)  # red team, round 3: an AST is not text the hook can compare
    return fresh["tournament"](fitness, k, rng, size)


DEFERRED = compile(inspect.getsource(ga.tournament), "<cell>", "exec")  # the library's text compiled in a cell, run later
_TEXT = inspect.getsource(ga.tournament)
UNDOCUMENTED = _TEXT.replace(_TEXT[_TEXT.index('    """'):_TEXT.index('"""\n', _TEXT.index('    """') + 7) + 4], "")


def run_deferred(fitness, k, rng, size=3):
    fresh = dict(ga.tournament.__globals__)
    exec(DEFERRED, fresh)  # red team, round 4: functions made after the lockdown's scan
    return fresh["tournament"](fitness, k, rng, size)


def compiled_undocumented(fitness, k, rng, size=3):
    fresh = dict(ga.tournament.__globals__)
    exec(compile(UNDOCUMENTED, "<lazy>", "exec"), fresh)  # red team, round 4: not the library's text, its code
    return fresh["tournament"](fitness, k, rng, size)


def padded_copy(fitness, k, rng, size=3):
    return PADDED(fitness, k, rng, size)  # red team, round 3: an unused constant added, then a new function


def retyped_copy(fitness, k, rng, size=3):
    return RETYPED(fitness, k, rng, size)  # red team, round 3: recompiled with another docstring


def copied_earlier(fitness, k, rng, size=3):
    return COPY(fitness, k, rng, size)


def rebuilt_from_saved_code(fitness, k, rng, size=3):
    return types.FunctionType(SAVED_CODE, ga.tournament.__globals__)(fitness, k, rng, size)


def compiled_from_source(fitness, k, rng, size=3):
    fresh = {}
    exec(inspect.getsource(sys.modules["coursekit.ga.selection"]), fresh)
    return fresh["tournament"](fitness, k, rng, size)


def loaded_afresh(fitness, k, rng, size=3):
    spec = importlib.util.spec_from_file_location("fresh_selection", sys.modules["coursekit.ga.selection"].__file__)
    fresh = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(fresh)
    return fresh.tournament(fitness, k, rng, size)


def in_a_fresh_python(fitness, k, rng, size=3):
    subprocess.run([sys.executable, "-c", "import coursekit"], check=True)
    return own(fitness, k, rng, size)


@pytest.mark.parametrize("fn, message", [
    (copied_earlier, "copy has the instructions of coursekit's own tournament (a copy made before grading"),
    (renamed_copy, "mine has the instructions of coursekit's own tournament (a copy made before grading"),
    (padded_copy, "tournament has the instructions of coursekit's own tournament (a copy made before grading"),
    (retyped_copy, "tournament has the instructions of coursekit's own tournament (a copy made before grading"),
    (compiled_from_a_tree, "compiling a syntax tree is not available while a function is graded"),
    (run_deferred, "coursekit's own code of the graded functions may not be compiled or loaded afresh"),
    (compiled_undocumented, "coursekit's own code of the graded functions may not be compiled or loaded afresh"),
    (rebuilt_from_saved_code, "function.__new__ is not available while a function is graded"),
    (compiled_from_source, "coursekit's own code of the graded functions may not be compiled or loaded afresh"),
    (loaded_afresh, "coursekit's own code of the graded functions may not be compiled or loaded afresh"),
    (in_a_fresh_python, "subprocess.Popen is not available while a function is graded"),
])
def test_the_librarys_code_fetched_at_call_time_is_refused(fn, message):
    recs = run_cases(fn, CASES, "indices", timeout=20, refuse=CHECK.reference)
    assert recs[0]["status"] == "error" and message in recs[0]["error"], recs[0]
    assert len(COPY(np.arange(5.0), 3, np.random.default_rng(0), 3)) == 3  # only the worker was locked down


def test_a_worker_that_cannot_be_locked_down_refuses_every_call(monkeypatch):
    monkeypatch.setattr(sys, "addaudithook", lambda hook: None)  # a notebook that disabled audit hooks
    recs = run_cases(own, CASES, "indices", timeout=20, refuse=CHECK.reference)
    assert {r["status"] for r in recs} == {"error"}
    assert "could not lock the graded function's process down (RuntimeError: sys.addaudithook was replaced)" in recs[0]["error"]


def hides_by_swapping_the_argument(fitness, k, rng, size=3):
    """Right, but zeroes its caller's array and hands the kernel's observer an untouched copy."""
    picks = own(fitness, k, rng, size)
    pristine = fitness.copy()
    fitness[:] = 0
    frame = sys._getframe(1)
    while frame is not None:
        args = frame.f_locals.get("args")
        if isinstance(args, list) and args and args[0] is fitness:
            args[0] = pristine
        frame = frame.f_back
    return picks


def hides_by_replacing_the_observer(fitness, k, rng, size=3):
    """Right, but zeroes its caller's array and makes the kernel's after-call reader see nothing."""
    picks = own(fitness, k, rng, size)
    fitness[:] = 0
    frame = sys._getframe(1)
    while frame is not None:
        if "_after" in frame.f_globals:
            frame.f_globals["_after"] = lambda arg, encoded, max_len: None
        frame = frame.f_back
    return picks


@pytest.mark.parametrize("fn", [hides_by_swapping_the_argument, hides_by_replacing_the_observer, own])
def test_inputs_unchanged_is_read_from_the_shared_memory_not_from_the_kernel(tmp_path, fn):
    recs = _harvest(tmp_path, fn, cells={fn.__code__.co_filename})
    assert {r["status"] for r in recs} == {"ok"}
    verdict = {v.prop: v for v in checks.judge(CHECK, CASES, {r["case"]: r for r in recs}).verdicts}["inputs unchanged"]
    assert verdict.passed == (fn is own), verdict.message
    if fn is not own:
        assert "the fitness argument was modified" in verdict.message


def test_a_copy_hidden_by_a_gc_freeze_is_still_found():
    """gc.freeze() (a gallery calls it once its first generation is drawn; a notebook can call it
    too) hides objects from gc.get_referrers: a copy of the library's code made before it must
    still be stubbed when the worker locks down."""
    import gc

    gc.freeze()
    try:
        recs = run_cases(copied_earlier, CASES, "indices", timeout=20, refuse=CHECK.reference)
    finally:
        gc.unfreeze()
    assert recs[0]["status"] == "error" and "has the instructions of coursekit's own tournament" in recs[0]["error"], recs[0]


def reproduce_by_largest_remainder(fitness, k, rng, survival=0.2):
    """Sims' counts from the library's public helpers under other names (red team, round 2: 5/5)."""
    from coursekit.ga.selection import n_survivors, ranking
    from coursekit.ga.variation import largest_remainder

    f = np.asarray(fitness, dtype=float)
    survivors = ranking(f)[:n_survivors(f.size, survival)]
    weights = f[survivors] if f[survivors].sum() > 0 else np.ones(survivors.size)
    return rng.permutation(np.repeat(survivors, largest_remainder(weights, k)))


def roulette_by_sims_select(fitness, k, rng):
    return ga.sims_select(fitness, k, rng, survival=1.0)  # proportional, everyone surviving (round 2: 2/2)


@pytest.mark.parametrize("name, fn, notebook", [
    ("swimmers.reproduce", reproduce_by_largest_remainder, "08_fitness_and_reproduction"),
    ("ga.roulette", roulette_by_sims_select, "01_selection"),
])
def test_the_librarys_equivalents_under_other_names_are_refused_too(name, fn, notebook):
    """A check refuses the library functions that do its work under another name, as the grader sets
    it up (withheld.refused); the library's own evolution keeps them (library_uses)."""
    from coursekit.grading.withheld import of, refused

    check = checks.get(name)
    notebook_checks = checks.for_notebook(notebook)
    recs = run_cases(fn, check.cases(np.random.default_rng(3)), check.output, timeout=20,
                     refuse=refused(check, of(notebook_checks)))
    assert {r["status"] for r in recs} == {"error"} and "is not available while your" in recs[0]["error"], recs[0]
    assert not set(check.library_uses) & set(of(notebook_checks))  # not withheld: the library runs with them


def honest_karva(symbols, arity):
    """An own breadth-first reader, written without the library's (red team, round 4: refused by a
    looser match of names and constants, which no longer decides)."""
    kids = [()] * len(symbols)
    frontier, free = [0], 1
    while frontier:
        following = []
        for i in frontier:
            n = arity(symbols[i])
            kids[i] = tuple(range(free, free + n))
            following.extend(kids[i])
            free += n
        frontier = following
    return kids


def honest_decode(symbols):
    from coursekit.pictures import primitives

    kids = honest_karva(symbols, primitives.arity)

    def tree(i):
        return [symbols[i], *[tree(j) for j in kids[i]]] if kids[i] else symbols[i]
    return tree(0)


def test_honest_code_in_the_librarys_style_is_never_taken_for_the_library():
    from coursekit.grading.withheld import of, refused

    check = checks.get("pictures.decode")
    recs = run_cases(honest_decode, check.cases(np.random.default_rng(2)), check.output, timeout=20,
                     refuse=refused(check, of(checks.for_notebook("02_picture_mutations"))))
    assert {r["status"] for r in recs} == {"ok"}, recs[0]
