"""The lessons' per-section time estimates: written by ``benchmarks/notebooks.py --estimates write``
from a measured run, checked by ``--estimates check``. Here: the bookkeeping (no notebook is run,
no time is measured) and that every committed lesson carries an estimate for every section."""

import importlib.util
from pathlib import Path

import nbformat
import pytest
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

ROOT = Path(__file__).resolve().parent.parent
spec = importlib.util.spec_from_file_location("notebooks_benchmark", ROOT / "benchmarks" / "notebooks.py")
bench = importlib.util.module_from_spec(spec)
spec.loader.exec_module(bench)


def lesson():
    return new_notebook(cells=[
        new_markdown_cell("# Title\n\n*Time: about 40 minutes to read, run and try; Run All takes about 99 s on a 2-core "
                          "machine.*"),
        new_code_cell("import numpy as np"),                                  # 1: preamble, no section
        new_markdown_cell("## 1. First\n\n" + "word " * 300),                 # 2
        new_code_cell("x = 1\ny = 2"),                                        # 3
        new_markdown_cell("### A subsection\n\nmore words here"),             # 4: still section 1
        new_code_cell("z = 3"),                                               # 5
        new_markdown_cell("## 2. Second\n\nshort\n\n## Try this\n\n1. change x"),  # 6: two sections
        new_code_cell("w = 4"),                                               # 7: belongs to "Try this"
    ])


SECONDS = {1: 4.0, 3: 30.0, 5: 12.4, 7: 0.3}


def test_sections_split_cells_and_collect_the_code_below_their_heading():
    found = bench.sections(lesson(), SECONDS)
    assert [s["heading"] for s in found] == ["1. First", "2. Second", "Try this"]
    assert [s["seconds"] for s in found] == [pytest.approx(42.4), 0.0, pytest.approx(0.3)]
    assert found[0]["words"] == 300 + 6 and found[0]["code_lines"] == 3
    assert (found[1]["cell"], found[2]["cell"]) == (6, 6) and found[1]["words"] == 1


def test_the_estimate_adds_computing_reading_and_trying():
    first, second, tries = bench.sections(lesson(), SECONDS)
    # 42.4 s + 306 words at 150/min (122.4 s) + 3 code lines at 15/min (12 s) = 176.8 s -> 3 min
    assert bench.estimate_minutes(first) == 3
    assert bench.note(first) == "*About 3 min: 42 s of computing, plus reading.*"
    assert bench.note(second) == "*About 1 min: under 1 s of computing, plus reading.*"
    assert bench.note(tries) == f"*About {bench.TRY_MINUTES + 1} min: under 1 s of computing, plus reading and trying.*"


def test_writing_puts_one_note_under_each_heading_and_is_idempotent():
    nb = lesson()
    before = [s["words"] for s in bench.sections(nb, SECONDS)]
    assert bench.write_estimates(nb, SECONDS, run_all=61.6) == 3
    assert bench.noted(nb) == [bench.note(s) for s in bench.sections(nb, SECONDS)]
    assert [s["words"] for s in bench.sections(nb, SECONDS)] == before  # notes are not read as prose
    # the lesson's total: its sections (3 + 1 + 4 min) and a minute for the title and imports (4 s, 25 words)
    assert "about 9 minutes to read, run and try; Run All takes about 62 s" in nb.cells[0].source
    assert nb.cells[6].source.startswith("## 2. Second\n\n*About 1 min")
    ends = nbformat.v4.new_markdown_cell("## Last\n\ntext\n")
    nb.cells.append(ends)
    bench.write_estimates(nb, SECONDS)
    assert ends.source.endswith("text\n")  # a cell's other lines stay as they were
    nb.cells.pop()
    text = nbformat.writes(nb)
    assert bench.write_estimates(nb, SECONDS, run_all=61.6) == 0 and nbformat.writes(nb) == text
    slower = {**SECONDS, 3: 200.0}
    assert bench.write_estimates(nb, slower) == 1  # replaced in place, not added
    assert nb.cells[2].source.count("*About") == 1 and "212 s of computing" in nb.cells[2].source


def test_a_note_is_stale_when_its_minutes_or_its_computing_time_no_longer_hold():
    note = "*About 3 min: 20 s of computing, plus reading.*"
    assert not bench.stale(note, "*About 3 min: 24 s of computing, plus reading.*")
    assert bench.stale(note, "*About 3 min: 40 s of computing, plus reading.*")
    assert bench.stale(note, "*About 4 min: 20 s of computing, plus reading.*")
    assert bench.stale(None, note)


@pytest.mark.parametrize("path", sorted((ROOT / "lessons").glob("*.ipynb")), ids=lambda p: p.name)
def test_every_section_of_every_lesson_has_a_measured_estimate(path):
    nb = nbformat.read(path, as_version=4)
    found, notes = bench.sections(nb, {}), bench.noted(nb)
    assert found, f"{path.name}: no '## ' sections"
    missing = [s["heading"] for s, n in zip(found, notes) if n is None]
    assert not missing, f"{path.name}: no time estimate under {missing} (benchmarks/notebooks.py --estimates write)"
    head = nb.cells[0].source
    assert bench.RUN_ALL.search(head) and bench.TOTAL.search(head), \
        f"{path.name}: no 'Run All takes about N s' line under the title (benchmarks/notebooks.py --estimates write)"


def test_writing_gives_a_lesson_without_the_time_line_one_under_its_title():
    nb = lesson()
    nb.cells[0].source = "# Title\n\n**Goals.** read"
    bench.write_estimates(nb, SECONDS, run_all=61.6)
    assert nb.cells[0].source == ("# Title\n\n*Time: about 9 minutes to read, run and try; Run All takes about 62 s on a "
                                  "2-core machine (classroom profile, `coursekit bench notebooks`).*\n\n**Goals.** read")
    text = nb.cells[0].source
    bench.write_estimates(nb, SECONDS, run_all=61.6)
    assert nb.cells[0].source == text

