"""Exercise generation from solutions: stubs keep signature and docstring, sync is enforced."""

from pathlib import Path

import nbformat
import pytest

from coursekit.cli import main as cli
from coursekit.grading import authoring

ROOT = Path(__file__).resolve().parent.parent

SOLUTION = '''def f(x):
    """Docstring stays."""
    # BEGIN SOLUTION
    y = x + 1
    return y
    # END SOLUTION

def g():
    # BEGIN SOLUTION
    return 2
    # END SOLUTION'''


def test_strip_solutions_keeps_signature_and_docstring():
    out = authoring.strip_solutions(SOLUTION)
    assert out == '''def f(x):
    """Docstring stays."""
    # YOUR CODE HERE
    raise NotImplementedError()

def g():
    # YOUR CODE HERE
    raise NotImplementedError()'''
    ns = {}
    exec(out, ns)
    with pytest.raises(NotImplementedError):
        ns["f"](1)
    assert ns["f"].__doc__ == "Docstring stays."


@pytest.mark.parametrize("src,msg", [
    ("# BEGIN SOLUTION\nx = 1", "never closed"),
    ("x = 1\n# END SOLUTION", "line 2: '# END SOLUTION' without"),
    ("# BEGIN SOLUTION\n# BEGIN SOLUTION\n# END SOLUTION", "line 2: nested"),
])
def test_unbalanced_markers_are_refused(src, msg):
    with pytest.raises(ValueError, match=msg):
        authoring.strip_solutions(src, "nb.ipynb, cell 3")


def _solution_dir(tmp_path):
    sol = tmp_path / "solutions"
    sol.mkdir()
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_markdown_cell("# T"), nbformat.v4.new_code_cell(SOLUTION)])
    nb.cells[1].outputs = [nbformat.v4.new_output("stream", text="hi")]
    nb.cells[1].execution_count = 3
    nbformat.write(nb, sol / "01_x.ipynb")
    return sol, tmp_path / "exercises"


def test_build_then_check_detects_stale_missing_and_extra(tmp_path):
    sol, ex = _solution_dir(tmp_path)
    assert authoring.check(sol, ex) == [f"{ex / '01_x.ipynb'}: missing (run `coursekit exercises build`)"]
    assert authoring.build(sol, ex) == [ex / "01_x.ipynb"]
    assert authoring.check(sol, ex) == [] and authoring.build(sol, ex) == []  # idempotent, byte-stable
    built = nbformat.read(ex / "01_x.ipynb", as_version=4)
    assert built.cells[1].outputs == [] and built.cells[1].execution_count is None
    assert "raise NotImplementedError()" in built.cells[1].source and "x + 1" not in built.cells[1].source
    (ex / "01_x.ipynb").write_text((ex / "01_x.ipynb").read_text().replace("YOUR CODE HERE", "edited"))
    (ex / "02_orphan.ipynb").write_text("{}")
    problems = authoring.check(sol, ex)
    assert len(problems) == 2 and "out of date" in problems[0] and "has no solution notebook" in problems[1]


def test_cli_exercises_check_passes_on_the_repository_and_fails_when_stale(tmp_path, capsys):
    assert cli(["exercises", "check"]) == 0
    sol, ex = _solution_dir(tmp_path)
    assert cli(["exercises", "check", "--solutions", str(sol), "--exercises", str(ex)]) == 1
    assert cli(["exercises", "build", "--solutions", str(sol), "--exercises", str(ex)]) == 0
    assert cli(["exercises", "check", "--solutions", str(sol), "--exercises", str(ex)]) == 0
    assert cli(["exercises", "check", "--solutions", str(tmp_path / "none"), "--exercises", str(ex)]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_repository_exercise_keeps_every_signature_and_docstring_but_no_solution():
    sol = nbformat.read(ROOT / "solutions" / "01_selection.ipynb", as_version=4)
    ex = nbformat.read(ROOT / "exercises" / "01_selection.ipynb", as_version=4)
    assert len(sol.cells) == len(ex.cells)
    graded = 0
    for s, e in zip(sol.cells, ex.cells):
        if "# BEGIN SOLUTION" not in s.source:
            assert s.source == e.source
            continue
        graded += 1
        head, rest = s.source.split("# BEGIN SOLUTION")
        assert e.source.startswith(head.rstrip(" ")) and "raise NotImplementedError()" in e.source
        answer = rest.split("# END SOLUTION")[0]
        assert not any(line.strip() and line.strip() in e.source for line in answer.splitlines())
    assert graded == 5
