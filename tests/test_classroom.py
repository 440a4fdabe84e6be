"""Notebook helpers: demo cells that survive Run All, and the setup check (issue 14, items 1 and 5)."""

import io

import pytest

from coursekit import classroom


def decode(symbols):
    """An unwritten exercise function, as the generated exercise has it."""
    # YOUR CODE HERE
    raise NotImplementedError()


def test_an_unwritten_function_ends_the_demo_with_one_line_naming_it(capsys):
    ran_after = []
    with classroom.demo("section 1"):
        decode(["x"])
        ran_after.append(True)  # never reached: the demo stops at the missing function
    out = capsys.readouterr().out
    assert ran_after == [] and out.count("\n") == 1
    assert "`decode` still raises NotImplementedError" in out and "(section 1)" in out and "goes on below" in out


def test_a_result_an_earlier_demo_could_not_make_is_named(capsys):
    with classroom.demo():
        print(yours)  # noqa: F821  (made by an earlier demo that did not run)
    assert "needs `yours`" in capsys.readouterr().out


def test_a_bug_in_a_written_function_still_raises():
    def written(x):
        return x[3]

    with pytest.raises(IndexError):
        with classroom.demo():
            written([1, 2])


def test_a_working_demo_prints_nothing_extra(capsys):
    with classroom.demo():
        print("done")
    assert capsys.readouterr().out == "done\n"


def test_the_setup_check_gives_one_line_per_item_and_the_fix_when_one_fails(monkeypatch):
    def broken():
        raise ImportError("No module named 'torch'")

    monkeypatch.setitem(classroom.CHECKS, "torch", broken)
    monkeypatch.setitem(classroom.CHECKS, "3D rendering", lambda: "pyvista x")
    monkeypatch.setitem(classroom.CHECKS, "widgets", lambda: "ipywidgets y")
    monkeypatch.setitem(classroom.CHECKS, "swimmers' physics", lambda: "numba w")
    out = io.StringIO()
    results = classroom.setup_check(file=out)
    lines = out.getvalue().splitlines()
    assert list(results) == ["3D rendering", "widgets", "torch", "swimmers' physics"] and len(lines) == 4
    assert results["torch"][0] is False and "No module named 'torch'" in results["torch"][1]
    assert lines[2].startswith("✘ torch: does not work") and "pip install torch" in lines[2]
    assert lines[0] == "✔ 3D rendering: works (pyvista x)"


def test_the_real_setup_check_passes_where_the_test_suite_runs():
    """CI installs everything the course needs, so every item works there (and a regression shows)."""
    out = io.StringIO()
    results = classroom.setup_check(file=out)
    assert all(ok for ok, _ in results.values()), out.getvalue()


def test_the_setup_check_bar_ends_full_even_when_a_check_fails(monkeypatch, capsys):
    """Lesson 00 runs it with a bar: saved with the notebook, the bar must read 4/4, not stop short."""
    def broken():
        raise RuntimeError("no EGL")

    monkeypatch.setitem(classroom.CHECKS, "3D rendering", broken)
    monkeypatch.setitem(classroom.CHECKS, "widgets", lambda: "ipywidgets y")
    monkeypatch.setitem(classroom.CHECKS, "torch", lambda: "torch z")
    monkeypatch.setitem(classroom.CHECKS, "swimmers' physics", lambda: "numba w")
    results = classroom.setup_check(file=io.StringIO(), progress=True)
    bar = capsys.readouterr().err.replace("\r", "\n").splitlines()
    assert results["3D rendering"][0] is False
    assert any("4/4" in line and "done" in line for line in bar), bar
