"""Summative grading: ``coursekit grade NOTEBOOK... --json OUT`` (seed paper section 4, exercises graded).

Integrity model. This process computes and writes scores and never imports or runs student code:

- It makes the test cases itself (seeded), writes them into a private box directory and starts
  :mod:`coursekit.grading.executor` as a child -- in a new session and as an unprivileged user
  (``nobody``) when running as root, as autograders such as Gradescope do. The child executes
  the notebook in a fresh kernel and harvests *raw outputs* of the student's functions into one
  channel file. Memory is bounded by what the notebook's processes hold, never by address space
  (a CUDA build of torch reserves ~3 GB of it on import): :mod:`.supervisor` polls them and
  kills the largest when they pass ``--memory-mb``.
- The child runs in a bubblewrap sandbox (:mod:`.sandbox`): the file system read-only,
  ``solutions/``, the other submissions and the results file hidden, a private ``/tmp``, no
  network, its own PID namespace (the grader and its environment are not visible). Where the
  sandbox cannot be set up, grading is refused unless the instructor passes ``--unsafe``.
- A graded function must be written in the notebook (:mod:`.runner` refuses one whose code comes
  from coursekit or any other file), and coursekit's own versions of it raise while it runs.
- A notebook part of which could not run -- a cell skipped for time, memory or a crash, a
  harvest that did not finish, no execution report -- is reported **not graded**, with the
  reasons, and ``coursekit grade`` exits with status 3: an instructor never gets a silent 0.
  The ``--json`` path is checked before grading starts; every message is stripped of terminal
  escapes and control characters (:func:`clean`).
- It reads only that channel (and a small execution report), refusing anything that is not a
  regular file below a size cap, and validates every record strictly (schema, types, lengths).
  It then judges with its own copy of the checks and cases; points come from the registry.
- It is a child subreaper (Linux): processes the notebook forked, even double-forked daemons,
  become its children when their parents die, and are killed before any result is written.
  Results are written atomically after that, so nothing the notebook started can overwrite them.
  (``COURSEKIT_GRADE_KEEP=1`` keeps the private directory, with the child's log, for debugging;
  otherwise it is removed, after ``SIGTERM`` too, and by the next run after a ``SIGKILL``.)

What the kernel can still do is choose the raw outputs its functions return -- exactly what a
student's function can do anyway -- and forge what the harvest reports about itself (its cell
file names, its own inputs), since the harvest runs in the kernel. Inside the sandbox it runs as
``nobody`` where that user can run this Python, else as the grader's user with every capability
dropped: it can then read files that user can read outside the hidden ones.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import ctypes
import json
import os
import pwd
import re
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

import coursekit

from coursekit.grading import checks as registry
from coursekit.grading import sandbox, supervisor
from coursekit.grading.checks import STATUSES, Judgement, Verdict

RESULTS_FORMAT = "coursekit.grade/1"
GRADING_SEED = 7_919
MAX_CHANNEL_BYTES = 64 * 2**20
MAX_REPORT_BYTES = 2**20
MAX_FILE_BYTES = 2**30  # the largest file a graded notebook's processes may write
_PKG_ROOT = Path(os.path.abspath(coursekit.__file__)).parent.parent  # the coursekit this grader runs (not symlink-resolved)


@dataclass
class NotebookResult:
    """The judgements of one notebook, plus notes on how its execution went."""

    path: str
    judgements: list
    notes: list
    not_graded: list = field(default_factory=list)  # why the score does not stand (cells skipped...)

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


# -- reading what the child produced -------------------------------------------------------------


def _read_untrusted(path: Path, limit: int) -> bytes | None:
    """Bytes of a regular file (no symlinks, FIFOs or devices), or None; ValueError when too big."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
    except OSError:
        return None
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            return None
        data = f.read(limit + 1)
    if len(data) > limit:
        raise ValueError(f"{path.name} exceeds {limit} bytes")
    return data


def _reject_constant(name):
    raise ValueError(f"non-finite number {name}")


def _plain_list(v, max_len, depth):
    """Is v a list of ints/finite floats (depth 1) or of such lists (depth 2), within max_len?"""
    if type(v) is not list or len(v) > max_len:
        return False
    if depth == 1:
        return all(type(x) in (int, float) for x in v)
    return all(_plain_list(x, max_len, depth - 1) for x in v)


def validate_record(rec, check, cases_by_id) -> dict | None:
    """A record from the channel as a clean dict, or None when it is malformed in any way."""
    if type(rec) is not dict or rec.get("check") != check.name or type(rec.get("case")) is not str:
        return None
    case = cases_by_id.get(rec["case"])
    status = rec.get("status")
    if case is None or status not in STATUSES:
        return None
    clean = {"case": case["id"], "status": status}
    if "error" in rec:
        if type(rec["error"]) is not str:
            return None
        clean["error"] = rec["error"][:600]
    if "call" in rec:
        if type(rec["call"]) is not int or not 0 <= rec["call"] < len(case["seeds"]):
            return None
        clean["call"] = rec["call"]
    if status == "ok":
        outs = rec.get("outputs")
        if type(outs) is not list or len(outs) != len(case["seeds"]):
            return None
        if check.output in ("json", "json_pair"):
            if check.output == "json":
                texts = outs
            elif all(type(o) is list and len(o) == 2 for o in outs):
                texts = [t for o in outs for t in o]
            else:
                return None
            if not all(type(t) is str and len(t) <= case["max_len"] for t in texts):
                return None
        else:
            depth = 2 if check.output == "array_pair" else 1
            if not all(_plain_list(o, case["max_len"], depth) and (depth == 1 or len(o) == 2) for o in outs):
                return None
            if check.output == "indices" and not all(type(x) is int for o in outs for x in o):
                return None
        clean["outputs"] = outs
        if case.get("check_inputs"):
            after = rec.get("inputs_after")
            if type(after) is not list or len(after) != len(case["args"]):
                return None
            for a, arg in zip(after, case["args"]):
                if a is None:
                    continue
                is_array = type(a) is dict and set(a) == {"ndarray", "dtype"} and type(a["dtype"]) is str and _plain_list(a["ndarray"], case["max_len"], 1)
                is_json = type(a) is dict and set(a) == {"json"} and type(a["json"]) is str and len(a["json"]) <= case["max_len"]
                if not (is_array or is_json):
                    return None
            clean["inputs_after"] = after
    return clean


def read_channel(path: Path, checks: list, cases: dict) -> tuple[dict, int]:
    """Parse the JSON-lines channel: ``({check_name: {case_id: record}}, number of rejected lines)``."""
    by_name = {c.name: c for c in checks}
    records: dict = {c.name: {} for c in checks}
    try:
        data = _read_untrusted(path, MAX_CHANNEL_BYTES)
    except ValueError:
        return records, 1
    rejected = 0
    for line in (data or b"").splitlines():
        try:
            rec = json.loads(line, parse_constant=_reject_constant)
        except (ValueError, RecursionError):
            rejected += 1
            continue
        check = by_name.get(rec.get("check")) if type(rec) is dict and type(rec.get("check")) is str else None
        try:
            clean = validate_record(rec, check, {c["id"]: c for c in cases[check.name]}) if check else None
        except (TypeError, ValueError):
            clean = None
        if clean is None:
            rejected += 1
        else:
            records[check.name].setdefault(clean["case"], clean)  # the first record of a case counts
    return records, rejected


def read_report(path: Path) -> tuple[list, list]:
    """``(notes, problems)`` from the execution report: which cells failed, and which were skipped.

    A *problem* means part of the notebook never ran (a cell skipped for time, memory or a crash,
    or no report at all), so its score cannot stand; an error raised by a cell is only a note.
    """
    try:
        data = _read_untrusted(path, MAX_REPORT_BYTES)
        rep = json.loads(data) if data else None
    except (ValueError, RecursionError):
        return [], ["the execution report was unreadable"]
    if type(rep) is not dict or rep.get("format") != "coursekit.execution/1":
        return [], ["no execution report (the notebook run was stopped)"]
    notes, problems = [], []
    if type(rep.get("error")) is str:
        notes.append(rep["error"][:400])
    elif rep.get("harvested") is not True and type(rep.get("harvest_problem")) is not str:
        problems.append("the graded functions were never called (the kernel did not get that far)")
    if type(rep.get("harvest_problem")) is str:
        problems.append(rep["harvest_problem"][:300])
    cells = rep.get("cells") if type(rep.get("cells")) is list else []
    for c in cells[:200]:
        if type(c) is dict and type(c.get("status")) is str and type(c.get("index")) is int and c["status"] != "ok":
            line = f"cell {c['index'] + 1}: {c['status'][:200]}"
            (problems if c["status"].startswith(("skipped", "not run")) else notes).append(line)
    return notes, problems


# -- which exercise a notebook is --------------------------------------------------------------

MAX_NOTEBOOK_BYTES = 64 * 2**20


def exercise_of(path, override=None) -> str:
    """The exercise a notebook answers: ``override`` (``--exercise``), else the notebook's metadata
    field ``coursekit.exercise`` (so a renamed file still grades), else the file stem.

    Raises ``ValueError`` naming the field when the metadata names no registered exercise. A file
    that cannot be read or parsed falls back to its stem (grading then reports it).
    """
    if override:
        registry.for_notebook(override)
        return override
    path = Path(path)
    try:
        data = _read_untrusted(path, MAX_NOTEBOOK_BYTES)
        meta = json.loads(data)["metadata"]["coursekit"] if data else None
    except (ValueError, RecursionError, KeyError, TypeError):
        meta = None
    if type(meta) is not dict or "exercise" not in meta:
        registry.for_notebook(path.stem)
        return path.stem
    name = meta["exercise"]
    if type(name) is str:
        try:
            registry.for_notebook(name)  # loads the registry
            return name
        except ValueError:
            pass
    registry._load()
    raise ValueError(f"{path}: metadata field coursekit.exercise is {clean(repr(name))[:80]}, which names no exercise; "
                     f"known: {', '.join(sorted(registry.EXERCISES))} (or pass --exercise)")


# -- running the child and cleaning up after it --------------------------------------------------


_SUBREAPER = False


def become_subreaper() -> bool:
    """Adopt orphaned descendants (Linux ``PR_SET_CHILD_SUBREAPER``); False where unsupported.

    Only a dedicated grading process should do this: afterwards :func:`grade_notebook` kills
    *every* child of the process once each notebook is done.
    """
    global _SUBREAPER
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        _SUBREAPER = libc.prctl(36, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        _SUBREAPER = False
    return _SUBREAPER


def _own_children() -> list[int]:
    me, kids = os.getpid(), []
    for entry in os.listdir("/proc") if os.path.isdir("/proc") else []:
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat", "rb") as f:
                    fields = f.read().rsplit(b")", 1)[1].split()
                if int(fields[1]) == me:
                    kids.append(int(entry))
            except (OSError, IndexError, ValueError):
                pass
    return kids


def sweep(spare=()) -> int:
    """SIGKILL and reap every child of this process (adopted orphans included); return how many."""
    killed = 0
    for _ in range(1000):
        kids = [k for k in _own_children() if k not in spare]
        if not kids:
            break
        for k in kids:
            try:
                os.kill(k, signal.SIGKILL)
                killed += 1
            except ProcessLookupError:
                pass
        for k in kids:
            try:
                os.waitpid(k, 0)
            except ChildProcessError:
                pass
    return killed


_USABLE: dict = {}


def grading_user(user: str):
    """(uid, gid) of ``user`` when running as root and that user can run this Python; else None."""
    if os.geteuid() != 0 or not user:
        return None
    if user not in _USABLE:
        try:
            pw = pwd.getpwnam(user)
            probe = subprocess.run([sys.executable, "-c", "import nbclient, numpy"], user=pw.pw_uid, group=pw.pw_gid,
                                   extra_groups=[], env={"PYTHONPATH": str(_PKG_ROOT)}, cwd="/", capture_output=True, timeout=60)
            _USABLE[user] = (pw.pw_uid, pw.pw_gid) if probe.returncode == 0 else None
        except (KeyError, OSError, subprocess.SubprocessError):
            _USABLE[user] = None
    return _USABLE[user]


def _limits():
    def apply():
        # No address-space limit: a CUDA build of torch reserves ~3 GB of it on import. Memory is
        # bounded by what the processes hold (supervisor.MemoryWatch); core dumps are off and no
        # file the notebook writes may pass MAX_FILE_BYTES.
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        resource.setrlimit(resource.RLIMIT_FSIZE, (MAX_FILE_BYTES, MAX_FILE_BYTES))

    return apply


def _stop(child) -> None:
    """Kill the child's process group and every process this one adopted; reap them."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    child.wait()
    if _SUBREAPER:  # orphans of this notebook (kernel, daemons) are our children now: none survives
        sweep()


def grade_notebook(path, *, timeout=60.0, cell_timeout=300.0, memory_mb=4096, seed=GRADING_SEED,
                   exercise=None, user="nobody", sandboxed=True, hide_files=(), notebook_timeout=3600.0) -> NotebookResult:
    """Grade one notebook in an isolated child; see the module docstring.

    Args:
        path: the submitted notebook.
        timeout: seconds per call of a student function.
        cell_timeout: seconds per notebook cell.
        memory_mb: memory (proportional set size, not address space) the notebook's processes
            may hold together; over it the largest is killed and the notebook is not graded.
        seed: seed of the grading cases.
        exercise: exercise stem (default: :func:`exercise_of`: the notebook's metadata field
            ``coursekit.exercise``, else its file stem, e.g. ``01_selection``).
        user: account the child runs as when grading as root ("" keeps root).
        sandboxed: run the child in the bubblewrap sandbox (:mod:`.sandbox`; it must be
            available); False grades unsandboxed (``--unsafe``).
        hide_files: files the sandbox masks (the batch's other submissions, the results file).
        notebook_timeout: seconds for the whole notebook (its cells and the calls); past them it
            is stopped and reported not graded.
    Returns:
        a :class:`NotebookResult`; ``not_graded`` lists why its score does not stand, if it does not.
    """
    path = Path(path)
    checks = registry.for_notebook(exercise_of(path, exercise))
    rng = np.random.default_rng(seed)
    cases = {c.name: c.cases(rng) for c in checks}
    spec = {"timeout": float(timeout), "memory_mb": int(memory_mb),
            "checks": [{"name": c.name, "function": c.function, "output": c.output, "cases": cases[c.name],
                        "refuse": list(c.reference)} for c in checks]}
    ids = grading_user(user)
    if sandboxed and ids and sandbox.available(ids) is not None:
        ids = None  # the sandbox works for this user only: run it as this user, capabilities dropped
    private = supervisor.private_dir()
    child = None
    try:
        box = private / "box"
        for d in ("", "work", "home", "runtime", "tmp"):
            (box / d).mkdir(exist_ok=True)
            if ids:
                os.chown(box / d, *ids)
        if ids:
            os.chmod(private, 0o711)
        try:
            nb_bytes = path.read_bytes()
        except OSError as exc:
            return NotebookResult(str(path), _zero(checks, f"could not read {path}: {exc.strerror}"), [],
                                  [f"could not read {path}: {exc.strerror}"])
        (box / "submission.ipynb").write_bytes(nb_bytes)
        (box / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
        channel, report = box / "channel.jsonl", box / "report.json"
        env = {k: v for k, v in os.environ.items() if k in ("PATH", "LANG", "LC_ALL", "TZ", "COURSEKIT_PROFILE")}
        env.update(PYTHONPATH=str(_PKG_ROOT), HOME=str(box / "home"), JUPYTER_RUNTIME_DIR=str(box / "runtime"),
                   IPYTHONDIR=str(box / "home" / ".ipython"), MPLCONFIGDIR=str(box / "home" / ".mpl"),
                   TMPDIR=str(box / "tmp"), MPLBACKEND="Agg", PYTHONNOUSERSITE="1",
                   COURSEKIT_PROFILE=env.get("COURSEKIT_PROFILE", "ci"))
        cmd = [sys.executable, "-m", "coursekit.grading.executor", "--notebook", str(box / "submission.ipynb"),
               "--spec", str(box / "spec.json"), "--channel", str(channel), "--report", str(report),
               "--cwd", str(box / "work"), "--cell-timeout", str(cell_timeout)]
        if sandboxed:
            cmd = sandbox.command(box, hide_dirs=[_PKG_ROOT / "solutions"], hide_files=hide_files) + cmd
        # The child bounds every cell and call itself; this bounds the notebook as a whole.
        wall = min(float(notebook_timeout),
                   2 * cell_timeout * (min(nb_bytes.count(b'"cell_type"'), 500) + 2) + (4 * timeout + 60) * len(checks))
        notes = [] if ids or os.geteuid() != 0 else [f"ran as root: user {user!r} could not run this Python, so privileges were not dropped"
                                                      + (" (inside the sandbox, every capability dropped)" if sandboxed else "")]
        if not sandboxed:
            notes.append("graded without a sandbox (--unsafe): the notebook could read solutions/ and other submissions")
        problems = []
        watch = supervisor.MemoryWatch(memory_mb)
        with open(private / "child.log", "wb") as log:
            child = subprocess.Popen(cmd, cwd=box / "work", env=env, stdin=subprocess.DEVNULL, stdout=log,
                                     stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_limits(),
                                     user=ids[0] if ids else None, group=ids[1] if ids else None,
                                     extra_groups=[] if ids else None)
            if not watch.wait(child, wall):
                problems.append(f"grading stopped after {wall:.0f} s (--notebook-timeout {notebook_timeout:g} s)"
                                if wall == notebook_timeout else f"grading stopped after {wall:.0f} s")
            _stop(child)
            child = None
        problems += watch.events
        records, rejected = read_channel(channel, checks, cases)
        more_notes, more_problems = read_report(report)
        notes += more_notes
        problems += more_problems
        if rejected:
            notes.append(f"{rejected} malformed result line(s) were ignored")
        unreadable = any(n.startswith("could not read the notebook") for n in more_notes)
        if not unreadable and not more_problems and any(not records[c.name] for c in checks):
            problems.append("no results came back for " + ", ".join(c.function for c in checks if not records[c.name]))
        judgements = [registry.judge(c, cases[c.name], records[c.name]) if records[c.name] else
                      _zero([c], f"no results: {c.function} could not be called (the notebook stopped before grading; see the notes)")[0]
                      for c in checks]
        return NotebookResult(str(path), judgements, notes, problems)
    finally:
        if child is not None:  # interrupted (Terminated, KeyboardInterrupt): nothing of the notebook survives
            _stop(child)
        if not os.environ.get("COURSEKIT_GRADE_KEEP"):
            shutil.rmtree(private, ignore_errors=True)


def _zero(checks, why):
    return [Judgement(c, False, [Verdict("graded", False, why)], 0.0) for c in checks]


# -- reporting -----------------------------------------------------------------------------------


_ESCAPES = re.compile(r"(?:\x1b\[|\x9b)[0-?]*[ -/]*[@-~]"  # CSI (7- and 8-bit): colours, cursor moves, screen clears
                      r"|\x9d[^\x07\x9c]*[\x07\x9c]?"  # 8-bit OSC
                      r"|\x1b\][^\x07\x1b]*(?:\x07|\x1b\\)?"  # OSC: titles, hyperlinks, clipboard (OSC 52)
                      r"|\x1b[P^_X][^\x1b]*(?:\x1b\\)?"  # DCS, PM, APC, SOS strings
                      r"|\x1b.?")  # any other escape
_CONTROLS = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069]")


def clean(text) -> str:
    """``text`` without terminal escapes and control characters (newlines and tabs stay).

    Everything the grader prints or writes passes through here: a message may quote a student's
    exception text, and an ANSI or OSC escape in it could clear the instructor's screen, fake a
    line of the summary or set the clipboard.
    """
    return _CONTROLS.sub("", _ESCAPES.sub("", str(text))).replace("\r", "")


def _messages(j: Judgement) -> str:
    return "\n".join(f"{'PASS' if v.passed else 'FAIL'} {v.prop}: {clean(v.message)}" for v in j.verdicts)


def _headline(r: NotebookResult) -> str:
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
                                      "not_graded": [clean(n) for n in r.not_graded]} for r in results]},
    }


def summary(results: list) -> str:
    """The readable summary printed by ``coursekit grade``."""
    lines = []
    for r in results:
        lines.append(f"{clean(r.path)}: {_headline(r)}")
        for j in r.judgements:
            first = next((v for v in j.verdicts if not v.passed), None)
            lines.append(f"  {j.check.name:<24} {j.score:>6.2f} / {j.check.points:g}   "
                         + ("all properties hold" if first is None else f"{first.prop}: {clean(first.message)}"))
        lines += [f"  not graded: {clean(n)}" for n in r.not_graded]
        lines += [f"  note: {clean(n)}" for n in r.notes]
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


#: Exit status of ``coursekit grade`` when a notebook could not be graded (2 is a usage error).
EXIT_NOT_GRADED = 3


def main(args) -> int:
    """``coursekit grade``: grade each notebook in isolation, print a summary, write Gradescope JSON.

    Exits 0 when every notebook was graded, 2 on a usage error (nothing graded, nothing written),
    3 when a notebook was not graded (its cells were skipped for time, memory or a crash) and
    1 when the results file could not be written.
    """
    for name in ("timeout", "cell_timeout", "memory_mb", "notebook_timeout"):
        v = getattr(args, name, None)
        if v is not None and not v > 0:
            print(f"coursekit grade: --{name.replace('_', '-')} must be positive, got {v}", file=sys.stderr)
            return 2
    try:
        exercises = [exercise_of(nb, getattr(args, "exercise", None)) for nb in args.notebooks]
    except ValueError as exc:
        print(f"coursekit grade: {exc}", file=sys.stderr)
        return 2
    if args.json_out:
        why = check_results_path(args.json_out)
        if why:
            print(f"coursekit grade: {why}", file=sys.stderr)
            return 2
    unsafe = bool(getattr(args, "unsafe", False))
    why = None if unsafe else sandbox.available()
    if why:
        print(f"coursekit grade: cannot sandbox the notebooks: {why}. Refusing to grade; --unsafe grades without a "
              "sandbox (a notebook can then read solutions/ and the other submissions, and write what this user can)",
              file=sys.stderr)
        return 2
    hide = [os.path.abspath(nb) for nb in args.notebooks] + ([os.path.abspath(args.json_out)] if args.json_out else [])
    supervisor.remove_stale()
    supervisor.handle_termination()
    if not become_subreaper():
        print("coursekit grade: warning: cannot adopt orphaned processes (no PR_SET_CHILD_SUBREAPER); "
              "processes a notebook daemonises may outlive grading", file=sys.stderr)
    results = []
    try:
        for nb, exercise in zip(args.notebooks, exercises):
            t0 = time.monotonic()
            results.append(grade_notebook(nb, timeout=args.timeout, cell_timeout=getattr(args, "cell_timeout", 300.0),
                                          memory_mb=getattr(args, "memory_mb", 4096), exercise=exercise,
                                          sandboxed=not unsafe, hide_files=hide,
                                          notebook_timeout=getattr(args, "notebook_timeout", 3600.0)))
            results[-1].notes.append(f"graded in {time.monotonic() - t0:.1f} s")
    except supervisor.Terminated as exc:  # the notebook's processes and private folder are gone already
        print(f"coursekit grade: {exc}; no results written", file=sys.stderr)
        return 128 + exc.signum
    finally:
        if _SUBREAPER:
            sweep()
    print(summary(results))
    if args.json_out:
        try:
            write_json_atomic(args.json_out, gradescope(results))
        except OSError as exc:
            print(f"coursekit grade: could not write the results to {args.json_out}: {exc.strerror}", file=sys.stderr)
            return 1
    return 0 if all(r.graded for r in results) else EXIT_NOT_GRADED
