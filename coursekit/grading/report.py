"""The grader's results as people and Gradescope read them, stripped of terminal escapes.

Part of the summative grader (seed paper section 4, exercises graded; see
:mod:`coursekit.grading.grader`): a :class:`NotebookResult` per notebook, the summary
``coursekit grade`` prints (:func:`summary`), the Gradescope ``results.json``
(:func:`gradescope`, written atomically after :func:`check_results_path` said, before any
grading, that it can be). Every message passes through :func:`clean`: it may quote a student's
exception text. Notes on the grader itself (it ran as root, without a sandbox, how long it took,
the seed) go to the instructor -- the printed summary, which Gradescope keeps from students, and
``extra_data`` -- and never into the ``output`` students read.
"""

from __future__ import annotations

import json
import os
import re
import tempfile
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path

from coursekit.atomic import atomic_write
from coursekit.grading.checks import Judgement

RESULTS_FORMAT = "coursekit.grade/1"


@dataclass
class NotebookResult:
    """The judgements of one notebook, plus notes on how its execution went."""

    path: str
    judgements: list
    notes: list
    not_graded: list = field(default_factory=list)  # why the score does not stand (cells skipped...)
    seed: int | None = None  # the seed of the grading cases (``--seed`` repeats them)
    seconds: float | None = None  # wall time of its grading, kernel start and sandbox included
    exercise: str | None = None  # the exercise it was graded as
    #: notes on how the grader ran (privileges, sandbox, timing, seed): for the instructor, in the printed
    #: summary (Gradescope keeps stdout from students) and ``extra_data``, never in the output students read
    grader_notes: list = field(default_factory=list)

    @property
    def graded(self) -> bool:
        """False when part of the notebook could not run (time, memory, crash): see ``not_graded``."""
        return not self.not_graded

    @property
    def score(self) -> float:
        return round(sum(j.score for j in self.judgements), 4)

    @property
    def max_score(self) -> float:
        return float(sum(j.check.points for j in self.judgements))



_ESCAPES = re.compile(r"(?:\x1b\[|\x9b)[0-?]*[ -/]*[@-~]"  # CSI (7- and 8-bit): colours, cursor moves, screen clears
                      r"|\x9d[^\x07\x9c]*[\x07\x9c]?"  # 8-bit OSC
                      r"|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?"  # OSC: titles, hyperlinks, clipboard (OSC 52)
                      r"|\x1b[P^_X][^\x1b]*(?:\x1b\\)?"  # DCS, PM, APC, SOS strings
                      r"|\x1b.?")  # any other escape
_LINE_BREAKS = re.compile(r"\s*[\n\u2028\u2029]\s*")
_SPACES = re.compile(r"[ \t]{8,}")  # long enough to wrap a terminal's line; a file name's double space stays


def clean(text) -> str:
    """``text`` as one line, without terminal escapes, without control, format, private-use,
    unassigned or lone surrogate characters (Unicode categories C*; a single tab stays), a line
    break as " ⏎ " and a run of eight spaces or more as one.

    Everything the grader prints or writes passes through here: a message may quote a student's
    exception text, and an ANSI or OSC escape in it could clear the instructor's screen or set the
    clipboard, a line break or a long run of spaces (wrapped by the terminal) could fake a line of
    the summary, bidirectional and invisible characters could make it read other than it is, and
    a lone surrogate could stop the summary from being printed at all.
    """
    text = _ESCAPES.sub("", str(text))
    text = "".join(ch for ch in text if ch in "\t\n" or unicodedata.category(ch)[0] != "C")
    return _SPACES.sub(" ", _LINE_BREAKS.sub(" ⏎ ", text))


def _said(j: Judgement, v) -> str:
    """One verdict as a line: its property and message; an unattempted function's message alone
    ("not attempted yet: ..."), which needs no property before it."""
    return clean(v.message) if not j.attempted else f"{v.label}: {clean(v.message)}"


def _messages(j: Judgement) -> str:
    return "\n".join(f"{'PASS' if v.passed else 'FAIL'} {_said(j, v)}" for v in j.verdicts)


def _headline(r: NotebookResult) -> str:
    if r.exercise and r.exercise != Path(r.path).stem:
        return f"{_score_line(r)} (graded as exercise {r.exercise})"
    return _score_line(r)


def _score_line(r: NotebookResult) -> str:
    if r.graded:
        return f"{r.score:g} / {r.max_score:g} points"
    return (f"NOT GRADED: {clean(r.not_graded[0])}"
            + (f" (+{len(r.not_graded) - 1} more, below)" if len(r.not_graded) > 1 else "")
            + f"; the parts that ran scored {r.score:g} / {r.max_score:g}")


def gradescope(results: list) -> dict:
    """Results in Gradescope's results.json format (plus ``extra_data`` with our format tag).

    A notebook that was not graded keeps the points its parts that ran earned, and says so in
    ``output`` and in ``extra_data.notebooks[*].graded`` / ``not_graded`` (the reasons).
    """
    tests = []
    for r in results:
        stem = clean(Path(r.path).name)
        for j in r.judgements:
            tests.append({"name": f"{stem}: {j.check.name} ({j.check.title})", "score": j.score,
                          "max_score": j.check.points, "output": _messages(j)})
    return {
        "score": round(sum(r.score for r in results), 4),
        "output": "\n".join(f"{clean(Path(r.path).name)}: {_headline(r)}"
                            + "".join(f"\n  {clean(n)}" for n in r.not_graded + r.notes) for r in results),
        "visibility": "visible",
        "stdout_visibility": "hidden",
        "tests": tests,
        "extra_data": {"format": RESULTS_FORMAT,
                       "notebooks": [{"path": clean(r.path), "score": r.score, "max_score": r.max_score, "graded": r.graded,
                                      "exercise": r.exercise, "not_graded": [clean(n) for n in r.not_graded], "seed": r.seed,
                                      "seconds": r.seconds, "grader_notes": [clean(n) for n in r.grader_notes]}
                                     for r in results]},
    }


def summary(results: list) -> str:
    """The readable summary printed by ``coursekit grade``: one line per check, its name, score and
    first failing property in columns as wide as the longest name and score need."""
    lines = []
    judgements = [j for r in results for j in r.judgements]
    name_w = max([24] + [len(j.check.name) for j in judgements])
    points_w = max([1] + [len(f"{j.check.points:g}") for j in judgements])
    for r in results:
        lines.append(f"{clean(r.path)}: {_headline(r)}")
        for j in r.judgements:
            first = next((v for v in j.verdicts if not v.passed), None)
            lines.append(f"  {j.check.name:<{name_w}} {j.score:>6.2f} / {j.check.points:<{points_w}g}   "
                         + ("all properties hold" if first is None else _said(j, first)))
        lines += [f"  not graded: {clean(n)}" for n in r.not_graded]
        lines += [f"  note: {clean(n)}" for n in r.notes]
        lines += [f"  grader: {clean(n)}" for n in r.grader_notes]
    bad = [r for r in results if not r.graded]
    if bad:
        lines.append(f"{len(bad)} of {len(results)} notebook(s) NOT GRADED: their scores do not stand; see the reasons above")
    return "\n".join(lines)


def write_json_atomic(path, obj) -> None:
    """Write JSON to ``path`` via a temporary file in the same folder and ``os.replace``."""
    atomic_write(path, json.dumps(obj, indent=1))


def check_results_path(path) -> str | None:
    """Why ``--json path`` cannot be written (checked before any grading starts), or None."""
    p = Path(path)
    if p.is_dir():
        return f"--json {path}: is a directory; give a file name, e.g. {p / 'results.json'}"
    parent = p.parent
    if not parent.is_dir():
        return f"--json {path}: the folder {parent} does not exist"
    if p.exists() and not p.is_file():
        return f"--json {path}: is not a regular file"
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{p.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        return f"--json {path}: cannot write in the folder {parent} ({exc.strerror})"
    return None

