"""The course outside the checkout: the working copy `coursekit lab` makes, and the wheel."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

from coursekit import course

ROOT = Path(__file__).resolve().parent.parent


def make_course(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root


def test_the_working_copy_holds_the_student_folders_and_no_solutions(tmp_path):
    report = course.copy_course(tmp_path / "class")
    copied = sorted(p.relative_to(tmp_path / "class").as_posix() for p in (tmp_path / "class").rglob("*.ipynb"))
    expected = sorted(p.relative_to(ROOT).as_posix() for folder in course.STUDENT_FOLDERS
                      for p in (ROOT / folder).glob("*.ipynb"))
    assert copied == expected == sorted(report.added)
    assert not (tmp_path / "class" / "solutions").exists()
    for rel in copied:
        assert (tmp_path / "class" / rel).read_bytes() == (ROOT / rel).read_bytes()


def test_a_second_copy_never_overwrites_a_students_work(tmp_path):
    src = make_course(tmp_path / "v1", {"lessons/a.ipynb": "A1", "lessons/b.ipynb": "B1", "exercises/e.ipynb": "E1"})
    work = tmp_path / "work"
    assert sorted(course.copy_course(work, src=src).added) == ["exercises/e.ipynb", "lessons/a.ipynb", "lessons/b.ipynb"]
    (work / "lessons" / "a.ipynb").write_text("my notes")  # the student's run / edit
    again = course.copy_course(work, src=src)
    assert again.kept == ["lessons/a.ipynb"] and again.added == [] and again.updated == []
    assert (work / "lessons" / "a.ipynb").read_text() == "my notes"

    # A new course version: untouched files follow it, edited ones stay the student's, new ones arrive.
    src2 = make_course(tmp_path / "v2", {"lessons/a.ipynb": "A2", "lessons/b.ipynb": "B2", "exercises/e.ipynb": "E1",
                                         "lessons/c.ipynb": "C2"})
    upgrade = course.copy_course(work, src=src2)
    assert upgrade.kept == ["lessons/a.ipynb"]
    assert upgrade.updated == ["lessons/b.ipynb"]
    assert upgrade.added == ["lessons/c.ipynb"]
    assert upgrade.unchanged == ["exercises/e.ipynb"]
    assert [(work / f).read_text() for f in ("lessons/a.ipynb", "lessons/b.ipynb", "lessons/c.ipynb")] == ["my notes", "B2", "C2"]
    assert "kept your changes to 1 (lessons/a.ipynb)" in str(upgrade)


def test_a_file_the_student_made_is_kept_even_without_a_record(tmp_path):
    """A working folder whose record was lost: every differing file counts as the student's."""
    src = make_course(tmp_path / "src", {"lessons/a.ipynb": "A"})
    work = make_course(tmp_path / "work", {"lessons/a.ipynb": "mine"})
    assert course.copy_course(work, src=src).kept == ["lessons/a.ipynb"]
    assert (work / "lessons" / "a.ipynb").read_text() == "mine"
    assert json.loads((work / course.MANIFEST).read_text())["format"] == "coursekit.course-copy/1"


def test_a_file_in_the_way_is_refused(tmp_path):
    (tmp_path / "course").write_text("")
    with pytest.raises(NotADirectoryError, match="course folder"):
        course.copy_course(tmp_path / "course")


def test_the_build_hook_packages_what_the_course_module_reads():
    """setup.py cannot import coursekit (no dependencies in the build environment): one table, twice."""
    import ast

    tree = ast.parse((ROOT / "setup.py").read_text())
    (table,) = [node.value for node in tree.body if isinstance(node, ast.Assign) and node.targets[0].id == "PACKAGED"]
    assert ast.literal_eval(table) == course.PACKAGED


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(out), str(ROOT)], check=True,
                   capture_output=True)
    (found,) = out.glob("coursekit-*.whl")
    return found


def test_the_wheel_carries_the_course_data_license_and_types(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for folder, pattern in course.PACKAGED.items():
        for p in (ROOT / folder).glob(pattern):
            assert f"coursekit/_course/{folder}/{p.name}" in names
    assert not any("solutions" in n for n in names)
    assert {"coursekit/py.typed", "coursekit/data/limit_exploit_creature.json"} <= names
    assert any(n.endswith(".dist-info/licenses/LICENSE") for n in names)


def test_the_installed_wheel_copies_the_course_and_runs_a_lesson_outside_the_checkout(wheel, tmp_path):
    """The wheel in a fresh venv (its dependencies borrowed from this one, none of the checkout):
    `coursekit lab` copies the course from the package, and lesson 08 -- which reads its data
    through the package -- runs top to bottom there."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = Path(subprocess.run([py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                               capture_output=True, text=True, check=True).stdout.strip())
    # This environment's packages (not its editable coursekit: a path in a .pth file runs no finder).
    (site / "deps.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    subprocess.run([sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-compile", "--target", str(site),
                    str(wheel)], check=True, capture_output=True)
    work = tmp_path / "class"
    work.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env.update(COURSEKIT_PROFILE="ci")
    where = subprocess.run([py, "-c", "import coursekit.course as c; print(c.__file__); print(c.source())"],
                           cwd=work, env=env, capture_output=True, text=True, check=True).stdout.split()
    assert where == [str(site / "coursekit" / "course.py"), str(site / "coursekit" / "_course")]
    script = (
        "import sys, nbformat\n"
        "from nbclient import NotebookClient\n"
        "from coursekit.course import copy_course\n"
        "print(copy_course('my-course'))\n"
        "probe = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell('import coursekit; print(coursekit.__file__)')])\n"
        "NotebookClient(probe, kernel_name='python3').execute()\n"
        "print('kernel coursekit:', probe.cells[0].outputs[0]['text'].strip())\n"
        "nb = nbformat.read('my-course/lessons/08_evolving_swimmers.ipynb', as_version=4)\n"
        "NotebookClient(nb, timeout=600, kernel_name='python3', resources={'metadata': {'path': 'my-course/lessons'}}).execute()\n"
        "print('ran', sum(c.cell_type == 'code' for c in nb.cells), 'cells')\n"
    )
    run = subprocess.run([py, "-c", script], cwd=work, env=env, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "course in" in run.stdout and "ran" in run.stdout
    assert f"kernel coursekit: {site / 'coursekit' / '__init__.py'}" in run.stdout  # the wheel's, not the checkout's


def test_ci_runs_the_readmes_commands_as_written():
    """`.ci/run` runs the README's test command verbatim (no torch installed first)."""
    import re

    readme = (ROOT / "README.md").read_text()
    blocks = re.findall(r"```bash\n(.*?)\n```", readme, re.S)
    install, test = blocks[0], blocks[1]
    assert install == "python3 -m venv .venv && .venv/bin/pip install -e . && .venv/bin/coursekit lab"
    ci = (ROOT / ".ci" / "run").read_text()
    assert any(line == test or line.startswith(test + " || exit") for line in ci.splitlines())
    assert "torch" not in "".join(line for line in ci.splitlines() if "pip install" in line)
