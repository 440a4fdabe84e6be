"""Every notebook in the repository is stored without outputs or execution counts."""

from pathlib import Path

import nbformat
import pytest

ROOT = Path(__file__).resolve().parent.parent
NOTEBOOKS = sorted(p for folder in ("lessons", "solutions", "exercises", "demos", "tests")
                   for p in (ROOT / folder).rglob("*.ipynb") if ".ipynb_checkpoints" not in p.parts)


def test_the_notebook_list_is_not_empty():
    names = {p.relative_to(ROOT).as_posix() for p in NOTEBOOKS}
    assert {"solutions/01_selection.ipynb", "exercises/01_selection.ipynb"} <= names


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.relative_to(ROOT).as_posix() for p in NOTEBOOKS])
def test_notebook_is_valid_and_output_free(path):
    nb = nbformat.read(path, as_version=4)
    nbformat.validate(nb)
    for i, cell in enumerate(nb.cells):
        if cell.cell_type == "code":
            assert cell.outputs == [], f"{path.name} cell {i + 1} has stored outputs"
            assert cell.execution_count is None, f"{path.name} cell {i + 1} has an execution count"
