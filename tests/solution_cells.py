"""The reference answers of a solution notebook, for the grading tests: its function cells (those
marked ``# BEGIN SOLUTION``) executed into one namespace."""

from __future__ import annotations

from pathlib import Path

import nbformat

SOLUTIONS = Path(__file__).resolve().parents[1] / "solutions"


def solution_functions(notebook: str, namespace: dict | None = None, *, imports: bool = False) -> dict:
    """Execute ``solutions/<notebook>``'s solution cells into ``namespace`` (what they need that
    the notebook imports elsewhere goes in it) and return it; ``imports``: its import cells too."""
    ns = {} if namespace is None else namespace
    for cell in nbformat.read(SOLUTIONS / notebook, as_version=4).cells:
        if cell.cell_type == "code" and ("# BEGIN SOLUTION" in cell.source or imports and cell.source.startswith("import")):
            exec(cell.source, ns)
    return ns
