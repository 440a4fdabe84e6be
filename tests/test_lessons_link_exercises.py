"""Every lesson links to the exercise of its number, so a student who finished reading knows where to write code."""

import re
from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parent.parent
EXERCISES = {p.name[:2]: p.name for p in (ROOT / "exercises").glob("[0-9][0-9]_*.ipynb")}
LESSONS = sorted(p for p in (ROOT / "lessons").glob("[0-9][0-9]_*.ipynb") if p.name[:2] in EXERCISES)


def links(path):
    text = "\n".join(c.source for c in nbformat.read(path, as_version=4).cells if c.cell_type == "markdown")
    return set(re.findall(r"\]\(\.\./exercises/([^)#]+\.ipynb)\)", text))


def test_the_numbered_lessons_with_exercises_include_the_pictures_and_swimmers():
    assert {"02", "03", "05", "07", "08"} <= {p.name[:2] for p in LESSONS}


@pytest.mark.parametrize("lesson", LESSONS, ids=[p.stem for p in LESSONS])
def test_lesson_links_to_its_exercise(lesson):
    found = links(lesson)
    assert EXERCISES[lesson.name[:2]] in found, f"{lesson.name} links to {sorted(found)}, not to ../exercises/{EXERCISES[lesson.name[:2]]}"
    assert all((ROOT / "exercises" / name).is_file() for name in found), found
