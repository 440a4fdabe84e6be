"""Formative feedback that teaches (issue 13, part 6), and the checks' code (part 8).

A convertible wrong type is accepted or told how to convert; messages and hints guide without
printing the answer; ``hint(...)`` climbs a ladder after ``check(...)``; every call of every case
is looked at for side effects; check modules are found on disk, one per exercise.
"""

import math
import re
from pathlib import Path

import nbformat
import numpy as np
import pytest

from coursekit.grading import checks, evaluate, formative, runner
from coursekit.grading.checks.ex07_swimming_physics import face_integral_drag

ROOT = Path(__file__).resolve().parent.parent


def solution(stem):
    nb = nbformat.read(ROOT / "solutions" / f"{stem}.ipynb", as_version=4)
    ns = {}
    for cell in nb.cells:
        if cell.cell_type == "code" and ("import" in cell.source.split("\n", 1)[0] or "# BEGIN SOLUTION" in cell.source):
            exec(cell.source.replace("check(", "(lambda *a, **k: None)("), ns)
    return ns


DRAG = solution("07_swimming_physics")["box_drag"]
SELECTION = solution("01_selection")


def test_a_correct_box_drag_returning_a_list_or_tuple_scores_in_full():
    array = evaluate("physics.box_drag", DRAG)
    assert array.passed
    for kind in (list, tuple):
        j = evaluate("physics.box_drag", lambda h, k, kind=kind: kind(float(x) for x in DRAG(h, k)))
        assert j.passed and j.score == array.score == j.check.points, [v.message for v in j.verdicts if not v.passed]


@pytest.mark.parametrize("result, advice", [
    (lambda h, k: np.asarray(DRAG(h, k)).reshape(6, 1), "result.ravel()"),
    (lambda h, k: np.asarray(DRAG(h, k)).astype(str), "result.astype(float)"),
    (lambda h, k: [str(x) for x in DRAG(h, k)], "np.array([...]) of floats"),
    (lambda h, k: {"D": list(DRAG(h, k))}, "np.asarray(result, dtype=float)"),
])
def test_an_unconvertible_result_is_told_how_to_convert(result, advice):
    j = evaluate("physics.box_drag", result)
    assert j.score == 0 and advice in j.verdicts[0].message, j.verdicts[0].message


def _numbers(text):
    return [float(x) for x in re.findall(r"-?\d+\.\d+(?:e-?\d+)?", text)]


@pytest.mark.parametrize("factor", [2.0, 0.5, 1.3])
def test_drag_messages_never_show_the_target_value(factor):
    j = evaluate("physics.box_drag", lambda h, k: factor * np.asarray(DRAG(h, k)))
    failed = [v for v in j.verdicts if not v.passed]
    assert failed and j.score < j.check.points
    # every number a message shows is the student's own value or the box's size, never the face integral's
    targets = {round(float(d), 4) for cid in range(6) for d in np.diag(face_integral_drag(np.ones(3), 1.0))}
    for v in failed:
        for x in _numbers(v.message):
            assert not any(math.isclose(x, t, rel_tol=1e-3) for t in targets if t), (x, v.message)
        if factor != 1.3 and "face integral" in v.prop:
            assert "power of two" in v.message
    assert "times that" not in " ".join(v.message for v in failed)


def test_hint_ladder_after_check(capsys):
    formative._LAST.pop("ga.point_mutation", None)
    formative._RUNG.clear()
    assert formative.next_hint("ga.point_mutation").startswith("Run check('ga.point_mutation', point_mutation) first")

    def nothing(genome, rng, rate=None):
        return genome.copy()

    formative.check("ga.point_mutation", nothing)
    ladder = checks.get("ga.point_mutation").ladder("changes the genome")
    assert len(ladder) == 3
    seen = [formative.next_hint("ga.point_mutation") for _ in range(4)]
    assert [s.split(":")[0] for s in seen[:3]] == [f"Hint {i} of 3 for 'changes the genome'" for i in (1, 2, 3)]
    assert all(h in s for h, s in zip(ladder, seen))
    assert seen[3].startswith("That was the last hint")
    formative.hint("ga.point_mutation")
    assert "last hint" in capsys.readouterr().out
    formative.check("ga.point_mutation", SELECTION["point_mutation"])
    assert formative.next_hint("ga.point_mutation") == "All properties of ga.point_mutation hold: no hint needed."


def test_a_shared_property_has_a_shared_ladder_and_no_hint_gives_a_solution():
    def global_random(fitness, k, rng, size=3):  # right, but ignores its rng
        return SELECTION["tournament"](fitness, k, np.random.default_rng(), size)

    formative._RUNG.clear()
    evaluate("ga.tournament", global_random)
    assert formative.next_hint("ga.tournament").startswith("Hint 1 of 3 for 'deterministic for a seed'")
    answers = set()  # every line of every solution block
    for path in (ROOT / "solutions").glob("*.ipynb"):
        for cell in nbformat.read(path, as_version=4).cells:
            inside = False
            for line in cell.source.split("\n") if cell.cell_type == "code" else ():
                inside = (inside or "# BEGIN SOLUTION" in line) and "# END SOLUTION" not in line
                if inside and len(line.strip()) > 12 and not line.strip().startswith("#"):
                    answers.add(line.strip())
    assert len(answers) > 50
    for name in checks.REGISTRY:
        for prop, ladder in checks.get(name).hints:
            assert ladder and all(isinstance(h, str) for h in ladder)
            assert not [a for h in ladder for a in answers if a in h], (name, prop)


def test_side_effects_are_looked_at_on_every_case():
    def zeroes_unless_20(fitness, k, rng, survival=0.2):
        picks = SELECTION["truncation"](fitness, k, rng, survival)
        if k != 20:
            fitness[:] = 0
        return picks

    j = evaluate("ga.truncation", zeroes_unless_20)
    verdict = {v.prop: v for v in j.verdicts}["inputs unchanged"]
    assert not verdict.passed and "fitness argument was modified" in verdict.message
    assert 0 < j.score < j.check.points


def test_check_modules_are_found_on_disk_one_per_exercise():
    modules = checks.check_modules()
    stems = sorted(p.stem for p in (ROOT / "exercises").glob("*.ipynb"))
    assert modules == [f"ex{s}" for s in stems]
    for module in modules:
        exercise = module[2:]
        names = [c.name for c in checks.for_notebook(exercise)]  # loads the registry
        # an exercise's cases come from its own module or a helper module (creature_expansion...), never another exercise's
        homes = {checks.REGISTRY[n].cases.__module__.rpartition(".")[2] for n in names}
        assert names and all(h == module or not checks.CHECK_MODULE.match(h) for h in homes), (module, homes)
    assert set(checks.REGISTRY) == {n for names in checks.EXERCISES.values() for n in names}


def test_calls_record_every_argument_after_the_call():
    case = {"id": "c", "args": [{"ndarray": [3, 1, 2], "dtype": "int64"}, {"rng": True}], "seeds": [1, 2], "max_len": 10}

    def sorts_in_place(xs, rng):
        xs.sort()
        return xs.copy()

    [rec] = runner.run_cases(sorts_in_place, [case], "indices", timeout=20)
    assert rec["status"] == "ok" and rec["inputs_after"][0] == {"ndarray": [1, 2, 3], "dtype": "int64"}
