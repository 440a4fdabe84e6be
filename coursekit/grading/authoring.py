"""Exercises generated from solutions: ``coursekit exercises build|check`` (seed paper section 4).

``solutions/NN_topic.ipynb`` is the single source. In its code cells, the lines between
``# BEGIN SOLUTION`` and ``# END SOLUTION`` are the answer; the generated
``exercises/NN_topic.ipynb`` keeps everything else (signature, docstring, narrative, check
cells) and replaces each block with ``raise NotImplementedError`` at the marker's indentation.
Outputs and execution counts are dropped; the notebook metadata field ``coursekit.exercise``
(the solution's file stem unless the solution sets it) names the exercise, so that ``coursekit
grade`` still knows a renamed submission. ``check`` rebuilds in memory and fails when any
exercise file differs byte for byte, is missing, or has no solution.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import copy
import re
import sys
from pathlib import Path

import nbformat

BEGIN = re.compile(r"^(?P<indent>[ \t]*)# BEGIN SOLUTION[ \t]*$")
END = re.compile(r"^[ \t]*# END SOLUTION[ \t]*$")
STUB = "{indent}# YOUR CODE HERE\n{indent}raise NotImplementedError()"


def strip_solutions(source: str, where: str = "cell") -> str:
    """Replace every ``# BEGIN SOLUTION`` ... ``# END SOLUTION`` block by a NotImplementedError stub.

    Raises:
        ValueError: on an unmatched or nested marker (naming ``where`` and the line).
    """
    out, indent = [], None
    for n, line in enumerate(source.split("\n"), 1):
        m = BEGIN.match(line)
        if m:
            if indent is not None:
                raise ValueError(f"{where}, line {n}: nested '# BEGIN SOLUTION' (the previous block is not closed)")
            indent = m.group("indent")
            out.append(STUB.format(indent=indent))
        elif END.match(line):
            if indent is None:
                raise ValueError(f"{where}, line {n}: '# END SOLUTION' without a matching '# BEGIN SOLUTION'")
            indent = None
        elif indent is None:
            out.append(line)
    if indent is not None:
        raise ValueError(f"{where}: '# BEGIN SOLUTION' is never closed by '# END SOLUTION'")
    return "\n".join(out)


def exercise_notebook(nb, name: str = "notebook"):
    """The exercise version of a solution notebook (a new object; ``nb`` is not modified)."""
    ex = copy.deepcopy(nb)
    if name.endswith(".ipynb"):  # the exercise's identity travels with the file: a renamed submission still grades
        ex.metadata.setdefault("coursekit", {}).setdefault("exercise", name[:-len(".ipynb")])
    for i, cell in enumerate(ex.cells):
        if cell.cell_type == "code":
            cell.source = strip_solutions(cell.source, f"{name}, cell {i + 1}")
            cell.outputs = []
            cell.execution_count = None
        cell.metadata.pop("execution", None)
    nbformat.validate(ex)
    return ex


def render(nb) -> str:
    """Canonical text of a notebook (stable across runs)."""
    text = nbformat.writes(nb)
    return text if text.endswith("\n") else text + "\n"


def expected(solutions: Path) -> dict:
    """``{file name: exercise text}`` for every solution notebook in the folder."""
    if not solutions.is_dir():
        raise ValueError(f"solutions folder {str(solutions)!r} does not exist")
    out = {}
    for path in sorted(solutions.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        out[path.name] = render(exercise_notebook(nb, path.name))
    if not out:
        raise ValueError(f"no solution notebooks (*.ipynb) in {str(solutions)!r}")
    return out


def build(solutions, exercises) -> list[Path]:
    """Write ``exercises/*.ipynb`` from ``solutions/*.ipynb``; return the files that changed."""
    solutions, exercises = Path(solutions), Path(exercises)
    exercises.mkdir(parents=True, exist_ok=True)
    changed = []
    for name, text in expected(solutions).items():
        target = exercises / name
        if not target.exists() or target.read_text(encoding="utf-8") != text:
            atomic_write(target, text)
            changed.append(target)
    return changed


def check(solutions, exercises) -> list[str]:
    """Problems that make ``exercises/`` stale (empty when in sync)."""
    solutions, exercises = Path(solutions), Path(exercises)
    want = expected(solutions)
    problems = []
    for name, text in want.items():
        target = exercises / name
        if not target.exists():
            problems.append(f"{target}: missing (run `coursekit exercises build`)")
        elif target.read_text(encoding="utf-8") != text:
            problems.append(f"{target}: out of date with {solutions / name} (run `coursekit exercises build`)")
    for extra in sorted(exercises.glob("*.ipynb")) if exercises.is_dir() else []:
        if extra.name not in want:
            problems.append(f"{extra}: has no solution notebook {solutions / extra.name}")
    return problems


def main(args) -> int:
    """``coursekit exercises build|check``."""
    try:
        if args.action == "build":
            for path in build(args.solutions, args.exercises):
                print(f"wrote {path}")
            return 0
        problems = check(args.solutions, args.exercises)
    except (ValueError, nbformat.ValidationError) as exc:
        print(f"coursekit exercises: {exc}", file=sys.stderr)
        return 2
    for p in problems:
        print(p, file=sys.stderr)
    if not problems:
        print(f"exercises in {args.exercises} are in sync with {args.solutions}")
    return 1 if problems else 0
