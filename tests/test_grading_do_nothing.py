"""Points for what matters (issue 13, part 1): do-nothing answers score 0 on every exercise.

The answers are those of ``tests/adversarial/make_notebooks.py`` (``DO_NOTHING``): identity
mutations, ``return a, b`` crossovers, deep copies, random picks for selection, an ``expand``
that returns the root alone, zero drag, explicit Euler in place of Runge-Kutta-Nystrom. Each
check's job gate must fail, and no property after it may pass (nothing passes vacuously).
The same notebooks are graded end to end by ``tests/test_grading_integrity.py``.
"""

import sys
from pathlib import Path

import pytest

from coursekit.grading import checks, evaluate

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests" / "adversarial"))
from make_notebooks import DO_NOTHING  # noqa: E402

sys.path.pop(0)


def _functions(stem):
    ns = {}
    for src in DO_NOTHING[stem]:
        exec(compile(src, f"<do_nothing_{stem}>", "exec"), ns)
    return ns


CASES = [(stem, c.name) for stem in DO_NOTHING for c in checks.for_notebook(stem)]


@pytest.mark.parametrize("stem, name", CASES, ids=[n for _, n in CASES])
def test_do_nothing_scores_zero_and_no_property_passes_vacuously(stem, name):
    check = checks.get(name)
    j = evaluate(name, _functions(stem)[check.function], timeout=30)
    assert j.attempted and j.score == 0.0, [(v.prop, v.passed, v.message) for v in j.verdicts]
    gates = [p for p, _ in check.props[:check.gates]]
    props = [v.prop for v in j.verdicts]
    failed_gate = next(v for v in j.verdicts if not v.passed and v.prop in gates)
    after = j.verdicts[props.index(failed_gate.prop) + 1:]
    assert after and all(not v.passed and v.message == f"not checked until {failed_gate.prop!r} holds" for v in after)


def test_every_exercise_and_check_has_a_do_nothing_answer():
    assert {stem for stem, _ in CASES} == set(checks.EXERCISES)
    assert [n for _, n in CASES] == [n for stem in DO_NOTHING for n in checks.EXERCISES[stem]]


def test_every_check_gates_on_its_job():
    for name in checks.REGISTRY:
        assert checks.get(name).gates >= 2, f"{name}: only the validity of the result gates the points"
