"""Which exercise a notebook answers (issue 13, part 7): its metadata, so renamed files still grade.

``coursekit grade`` reads the notebook metadata field ``coursekit.exercise``; ``--exercise``
overrides it; a notebook without it is known by its file stem, and one whose file name names another
exercise is graded as its metadata says but not graded silently. Exercises generated from the
solutions carry the field. (A renamed solution graded end to end: tests/test_grading_integrity.py.)
"""

import json
import subprocess
import sys
from pathlib import Path

import nbformat
import pytest

from coursekit.grading.authoring import exercise_notebook
from coursekit.grading.grader import exercise_of

ROOT = Path(__file__).resolve().parent.parent
STEMS = sorted(p.stem for p in (ROOT / "solutions").glob("*.ipynb"))


def with_metadata(path, meta):
    nb = json.loads((ROOT / "solutions" / "01_selection.ipynb").read_text())
    nb["metadata"].pop("coursekit", None)
    if meta is not None:
        nb["metadata"]["coursekit"] = meta
    path.write_text(json.dumps(nb))
    return path


def test_metadata_names_the_exercise_whatever_the_file_name(tmp_path):
    assert exercise_of(with_metadata(tmp_path / "homework.ipynb", {"exercise": "01_selection"})) == "01_selection"
    assert exercise_of(with_metadata(tmp_path / "02_picture_mutations.ipynb", {"exercise": "01_selection"})) == "01_selection"


def test_exercise_option_overrides_the_metadata(tmp_path):
    nb = with_metadata(tmp_path / "homework.ipynb", {"exercise": "01_selection"})
    assert exercise_of(nb, "07_swimming_physics") == "07_swimming_physics"


def test_without_metadata_the_file_stem_names_it(tmp_path):
    assert exercise_of(with_metadata(tmp_path / "03_picture_recombination.ipynb", None)) == "03_picture_recombination"
    truncated = tmp_path / "05_creature_operators.ipynb"
    truncated.write_text('{"cells": [')
    assert exercise_of(truncated) == "05_creature_operators"
    with pytest.raises(ValueError, match="no exercise is registered for notebook 'homework'"):
        exercise_of(with_metadata(tmp_path / "homework.ipynb", None))


@pytest.mark.parametrize("value", [42, "99_unknown", None, ["01_selection"]])
def test_bad_metadata_is_refused_naming_the_field(tmp_path, value):
    nb = with_metadata(tmp_path / "01_selection.ipynb", {"exercise": value})
    with pytest.raises(ValueError, match=r"metadata field coursekit\.exercise is .*names no exercise; known: 01_selection"):
        exercise_of(nb)
    proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(nb), "--json", "r.json"], capture_output=True,
                          text=True, cwd=tmp_path, env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT)})
    assert proc.returncode == 3 and f"{nb}: NOT GRADED: {nb}: metadata field coursekit.exercise is " in proc.stdout
    [result] = json.loads((tmp_path / "r.json").read_text())["extra_data"]["notebooks"]
    assert not result["graded"] and result["max_score"] == 0


def test_one_notebook_of_unknown_exercise_does_not_stop_the_batch(tmp_path):
    # red team, round 7: a notebook whose metadata names no exercise (or a file with neither metadata nor an
    # exercise's name) stopped the whole batch with status 2 and no results file
    honest = tmp_path / "alice" / "01_selection.ipynb"
    honest.parent.mkdir()
    honest.write_bytes((ROOT / "solutions" / "01_selection.ipynb").read_bytes())
    odd = with_metadata(tmp_path / "my homework.ipynb", None)
    proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(honest), str(odd), "--json", "r.json",
                           "--seed", "7"], cwd=tmp_path, capture_output=True, text=True, timeout=900,
                          env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "COURSEKIT_PROFILE": "ci"})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    first, second = json.loads((tmp_path / "r.json").read_text())["extra_data"]["notebooks"]
    assert first["graded"] and first["score"] == 10 and not second["graded"]
    assert "no exercise is registered for notebook 'my homework'" in second["not_graded"][0]


@pytest.mark.parametrize("stem", STEMS)
def test_solutions_and_generated_exercises_carry_their_identity(stem):
    for folder in ("solutions", "exercises"):
        nb = nbformat.read(ROOT / folder / f"{stem}.ipynb", as_version=4)
        assert nb.metadata["coursekit"]["exercise"] == stem
        assert exercise_of(ROOT / folder / f"{stem}.ipynb") == stem


def test_a_generated_exercise_is_named_after_its_solution_file():
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("x = 1")])
    assert exercise_notebook(nb, "04_new_topic.ipynb").metadata["coursekit"] == {"exercise": "04_new_topic"}
    nb.metadata["coursekit"] = {"exercise": "01_selection"}  # a solution that sets it keeps it
    assert exercise_notebook(nb, "renamed.ipynb").metadata["coursekit"] == {"exercise": "01_selection"}


def test_metadata_is_read_in_a_fresh_process_before_anything_else_loaded_the_checks(tmp_path):
    nb = with_metadata(tmp_path / "homework.ipynb", {"exercise": "01_selection"})
    code = f"from coursekit.grading.grader import exercise_of; print(exercise_of({str(nb)!r}))"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={"PYTHONPATH": str(ROOT)})
    assert proc.returncode == 0 and proc.stdout.strip() == "01_selection", proc.stderr


def test_a_file_named_for_one_exercise_that_answers_another_is_not_graded_silently(tmp_path):
    # red team, round 6: exercise 01's solution handed in as 03_picture_recombination.ipynb scored 10 / 10, more
    # than the 6 points exercise 03 is worth, and nothing said which exercise had been graded
    nb = tmp_path / "Alice_03_Picture_Recombination (1).ipynb"  # as a browser and a course site may name it (round 7)
    nb.write_bytes((ROOT / "solutions" / "01_selection.ipynb").read_bytes())
    proc = subprocess.run([sys.executable, "-m", "coursekit", "grade", str(nb), "--json", "r.json", "--seed", "7"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=900,
                          env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(ROOT), "COURSEKIT_PROFILE": "ci"})
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert f"{nb}: NOT GRADED: its file name names exercise 03_picture_recombination, but its metadata field " \
           "coursekit.exercise says 01_selection" in proc.stdout and "(graded as exercise 01_selection)" in proc.stdout
    [result] = json.loads((tmp_path / "r.json").read_text())["extra_data"]["notebooks"]
    assert result["exercise"] == "01_selection" and not result["graded"]
