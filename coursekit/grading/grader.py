"""Summative grading: ``coursekit grade NOTEBOOK... --json OUT`` (seed paper section 4, exercises graded).

Integrity model. This process -- the *supervisor* -- draws the cases, computes and writes the
scores, and never imports or runs student code:

- **Cases are drawn per run** (a fresh seed unless ``--seed`` repeats one; the results name it).
  Every call gets a random id and the calls of a check are shuffled. The plan goes to the
  grading child (:mod:`coursekit.grading.executor`) in a file that child reads and deletes
  before the notebook runs, so no case is ever on disk or in the kernel while the notebook's own
  cells run. The child makes itself undumpable (no process of its user can read its memory or
  open its descriptors) and hands the kernel **one call at a time**: the next call leaves only
  after the previous one's record came back.
- **Only the supervisor writes results.** Records come back on a pipe that only the child holds
  (the kernel never inherits it), each answering one call id the kernel could not know in
  advance: records written ahead of time, into a file or anywhere, count for nothing. Then the
  supervisor itself judges, with its own copy of the checks and cases: it compares the outputs
  of separate calls with one seed (determinism) and each call's arguments after the call with
  what it sent ("inputs unchanged", on every call of every case). Points come from the registry.
- The child starts in a new session and as an unprivileged user (``nobody``) when running as
  root, as autograders such as Gradescope do, in a bubblewrap sandbox (:mod:`.sandbox`): the
  file system read-only, ``solutions/``, the other submissions and the results file hidden, a
  private ``/tmp``, no network, its own PID namespace (the grader and its environment are not
  visible). Where the sandbox cannot be set up, grading is refused unless the instructor passes
  ``--unsafe``.
- **Limits** come from outside (:mod:`.supervisor`): resident memory (never address space: a
  CUDA build of torch reserves ~3 GB of it on import), the number of processes, the bytes
  written in the notebook's folder, the wall time of the whole notebook; ``RLIMIT_FSIZE`` bounds
  any one file and ``RLIMIT_NPROC`` the processes of a dedicated user.
- A graded function must be written in the notebook (:mod:`.runner` refuses one whose code comes
  from coursekit or any other file), and coursekit's own versions of it raise while it runs.
- A notebook part of which could not run -- a cell skipped for time, memory or a crash, a
  harvest that did not finish, no execution report -- is reported **not graded**, with the
  reasons, and ``coursekit grade`` exits with status 3: an instructor never gets a silent 0.
  The ``--json`` path is checked before grading starts; every message is stripped of terminal
  escapes and control characters (:func:`clean`).
- It is a child subreaper (Linux): processes the notebook forked, even double-forked daemons,
  become its children when their parents die, and are killed before any result is written.
  Results are written atomically after that, so nothing the notebook started can overwrite them.
  (``COURSEKIT_GRADE_KEEP=1`` keeps the private directory, with the child's log, for debugging;
  otherwise it is removed, after ``SIGTERM`` too, and by the next run after a ``SIGKILL``.)

What is still trusted: the calls run in the notebook's own interpreter (that is where its
function lives), so the code that observes a call -- converting the result, reading the
arguments after it -- runs there too, from source shipped fresh, but next to whatever the
notebook patched before (numpy, ``json``). A notebook that rewrites those to lie about its own
side effects, or hijacks the harvest's connection from a thread, still only answers the calls
the supervisor sends, one at a time; what it can choose is the raw outputs and what it reports
about its arguments -- the first is what any function does, the second needs deliberate forgery.
Inside the sandbox it runs as ``nobody`` where that user can run this Python, else as the
grader's user with every capability dropped: it can then read files that user can read outside
the hidden ones.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import ctypes
import json
import os
import pwd
import re
import resource
import secrets
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import psutil

import coursekit

from coursekit.grading import checks as registry
from coursekit.grading import sandbox, supervisor
from coursekit.grading.checks import STATUSES, Judgement, Verdict
from coursekit.grading.runner import assemble

RESULTS_FORMAT = "coursekit.grade/1"
MAX_CHANNEL_BYTES = 64 * 2**20
MAX_FILE_BYTES = 2**30  # the largest file a graded notebook's processes may write
_PKG_ROOT = Path(os.path.abspath(coursekit.__file__)).parent.parent  # the coursekit this grader runs (not symlink-resolved)


@dataclass
class NotebookResult:
    """The judgements of one notebook, plus notes on how its execution went."""

    path: str
    judgements: list
    notes: list
    not_graded: list = field(default_factory=list)  # why the score does not stand (cells skipped...)
    seed: int | None = None  # the seed of the grading cases (``--seed`` repeats them)

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


def _valid_output(out, check, max_len) -> bool:
    """Is ``out`` one call's converted result of the kind ``check.output`` (plain data within ``max_len``)?"""
    if check.output == "json":
        return type(out) is str and len(out) <= max_len
    if check.output == "json_pair":
        return type(out) is list and len(out) == 2 and all(type(t) is str and len(t) <= max_len for t in out)
    if check.output == "array_pair":
        return _plain_list(out, max_len, 2) and len(out) == 2
    if not _plain_list(out, max_len, 1):
        return False
    return check.output != "indices" or all(type(x) is int for x in out)


def _valid_after(a, encoded, max_len) -> bool:
    if a is None:
        return True
    if type(a) is not dict:
        return False
    if set(a) == {"ndarray", "dtype"}:
        return type(a["dtype"]) is str and _plain_list(a["ndarray"], max_len, 1)
    return set(a) == {"json"} and type(a["json"]) is str and len(a["json"]) <= max_len


def validate_call(rec, check, call) -> dict | None:
    """A call record from the grading child as a clean dict, or None when it is malformed in any way.

    ``call`` is the call the grader sent under that record's id (None when the id is unknown).
    """
    if type(rec) is not dict or rec.get("check") != check.name or call is None or rec.get("id") != call["id"]:
        return None
    status = rec.get("status")
    if status not in STATUSES:
        return None
    clean = {"id": call["id"], "status": status}
    if "error" in rec:
        if type(rec["error"]) is not str:
            return None
        clean["error"] = rec["error"][:600]
    if status == "ok":
        if "output" not in rec or not _valid_output(rec["output"], check, call["max_len"]):
            return None
        after = rec.get("inputs_after")
        if type(after) is not list or len(after) != len(call["args"]) or \
                not all(_valid_after(a, e, call["max_len"]) for a, e in zip(after, call["args"])):
            return None
        clean.update(output=rec["output"], inputs_after=after)
    return clean


def read_results(data: bytes, checks: list, plan: dict) -> tuple[dict, dict | None, int]:
    """Parse what the grading child sent on its pipe.

    Args:
        data: the JSON lines received.
        checks: the notebook's checks.
        plan: ``{check name: {call id: (case id, call index, call)}}``, what the grader sent.
    Returns:
        ``({check name: {(case id, index): clean call record}}, the execution report or None,
        number of rejected lines)``. The first record of a call counts.
    """
    by_name = {c.name: c for c in checks}
    results: dict = {c.name: {} for c in checks}
    report, rejected = None, 0
    for line in data.splitlines():
        try:
            rec = json.loads(line, parse_constant=_reject_constant)
        except (ValueError, RecursionError):
            rejected += 1
            continue
        if type(rec) is dict and set(rec) == {"report"}:
            report = rec["report"]
            continue
        check = by_name.get(rec.get("check")) if type(rec) is dict and type(rec.get("check")) is str else None
        sent = plan.get(check.name, {}).get(rec.get("id")) if check and type(rec.get("id")) is str else None
        try:
            clean = validate_call(rec, check, sent[2]) if sent else None
        except (TypeError, ValueError):
            clean = None
        if clean is None:
            rejected += 1
        else:
            results[check.name].setdefault(sent[:2], clean)
    return results, report, rejected


def read_report(rep) -> tuple[list, list]:
    """``(notes, problems)`` from the execution report: which cells failed, and which were skipped.

    A *problem* means part of the notebook never ran (a cell skipped for time, memory or a crash,
    or no report at all), so its score cannot stand; an error raised by a cell is only a note.
    """
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


def _limits(max_processes: int, uid: int | None = None):
    """The child's rlimits: no core dumps, no file over MAX_FILE_BYTES and, for a dedicated user
    ``uid``, at most ``max_processes`` more processes than that user runs now (``RLIMIT_NPROC``
    counts every process of the user, so it is only set for an account of its own, never for the
    instructor's; root is exempt from it, and then :class:`supervisor.Watch` bounds the count)."""
    nproc = None
    if uid is not None:
        running = sum(1 for p in psutil.process_iter(["uids"]) if p.info["uids"] and p.info["uids"].real == uid)
        nproc = running + max_processes

    def apply():
        # No address-space limit: a CUDA build of torch reserves ~3 GB of it on import. Memory is
        # bounded by what the processes hold (supervisor.Watch).
        resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        resource.setrlimit(resource.RLIMIT_FSIZE, (MAX_FILE_BYTES, MAX_FILE_BYTES))
        if nproc is not None:
            resource.setrlimit(resource.RLIMIT_NPROC, (nproc, nproc))

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


def new_seed() -> int:
    """A fresh grading seed: the cases of every run are new (``--seed`` repeats a run's cases)."""
    return secrets.randbits(63)


def make_plan(checks, cases: dict, rng) -> tuple[list, dict]:
    """The calls sent to the grading child, and how to read their records.

    Every call gets a random id (it tells the kernel nothing about its case) and the calls of each
    check are sent in a random order, so a notebook cannot tell which call repeats which seed or
    which case is checked for what: every call is checked for everything. Returns ``(checks'
    plans, {check name: {call id: (case id, call index, call)}})``; a call's ``group`` (its case's
    position) stays with the grading child, which sends no more calls of a case after one failed.
    """
    from coursekit.grading.runner import calls_of

    plans, lookup = [], {}
    for c in checks:
        calls, ids = [], {}
        for g, case in enumerate(cases[c.name]):
            for i, call in enumerate(calls_of([case])):
                call = {**call, "id": secrets.token_hex(8), "group": g}
                ids[call["id"]] = (case["id"], i, call)
                calls.append(call)
        calls = [calls[k] for k in rng.permutation(len(calls))]
        plans.append({"name": c.name, "function": c.function, "output": c.output, "refuse": list(c.reference), "calls": calls})
        lookup[c.name] = ids
    return plans, lookup


class _Collector(threading.Thread):
    """Read the grading child's pipe into memory, up to MAX_CHANNEL_BYTES (the rest is drained and dropped)."""

    def __init__(self, fd):
        super().__init__(daemon=True)
        self.fd, self.data, self.overflow = fd, bytearray(), False

    def run(self):
        with os.fdopen(self.fd, "rb", buffering=0) as f:
            while True:
                chunk = f.read(1 << 16)
                if not chunk:
                    return
                if len(self.data) + len(chunk) > MAX_CHANNEL_BYTES:
                    self.overflow = True
                else:
                    self.data += chunk


def grade_notebook(path, *, timeout=60.0, cell_timeout=300.0, memory_mb=4096, seed=None,
                   exercise=None, user="nobody", sandboxed=True, hide_files=(), notebook_timeout=3600.0,
                   max_processes=supervisor.MAX_PROCESSES, disk_mb=supervisor.DISK_MB) -> NotebookResult:
    """Grade one notebook in an isolated child; see the module docstring.

    Args:
        path: the submitted notebook.
        timeout: seconds per call of a student function.
        cell_timeout: seconds per notebook cell.
        memory_mb: memory (proportional set size, not address space) the notebook's processes
            may hold together; over it the largest is killed and the notebook is not graded.
        seed: seed of the grading cases (default: a fresh one, :func:`new_seed`).
        exercise: exercise stem (default: :func:`exercise_of`: the notebook's metadata field
            ``coursekit.exercise``, else its file stem, e.g. ``01_selection``).
        user: account the child runs as when grading as root ("" keeps root).
        sandboxed: run the child in the bubblewrap sandbox (:mod:`.sandbox`; it must be
            available); False grades unsandboxed (``--unsafe``).
        hide_files: files the sandbox masks (the batch's other submissions, the results file).
        notebook_timeout: seconds for the whole notebook (its cells and the calls); past them it
            is stopped and reported not graded.
        max_processes: processes the notebook may run at once; past them all are stopped.
        disk_mb: MiB the notebook may write in its folder; past them all are stopped.
    Returns:
        a :class:`NotebookResult`; ``not_graded`` lists why its score does not stand, if it does not.
    """
    path = Path(path)
    checks = registry.for_notebook(exercise_of(path, exercise))
    seed = new_seed() if seed is None else int(seed)
    rng = np.random.default_rng(seed)
    cases = {c.name: c.cases(rng) for c in checks}
    plans, lookup = make_plan(checks, cases, rng)
    plan = {"timeout": float(timeout), "memory_mb": int(memory_mb), "checks": plans}
    ids = grading_user(user)
    if sandboxed and ids and sandbox.available(ids) is not None:
        ids = None  # the sandbox works for this user only: run it as this user, capabilities dropped
    private = supervisor.private_dir()
    child = None
    rfd = wfd = None
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
        calls_file = box / "calls.json"  # read and deleted by the child before the notebook runs
        fd = os.open(calls_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(plan, f)
        if ids:
            os.chown(calls_file, *ids)
        env = {k: v for k, v in os.environ.items() if k in ("PATH", "LANG", "LC_ALL", "TZ", "COURSEKIT_PROFILE")}
        env.update(PYTHONPATH=str(_PKG_ROOT), HOME=str(box / "home"), JUPYTER_RUNTIME_DIR=str(box / "runtime"),
                   IPYTHONDIR=str(box / "home" / ".ipython"), MPLCONFIGDIR=str(box / "home" / ".mpl"),
                   TMPDIR=str(box / "tmp"), MPLBACKEND="Agg", PYTHONNOUSERSITE="1",
                   COURSEKIT_PROFILE=env.get("COURSEKIT_PROFILE", "ci"))
        rfd, wfd = os.pipe()
        cmd = [sys.executable, "-m", "coursekit.grading.executor", "--notebook", str(box / "submission.ipynb"),
               "--calls", str(calls_file), "--results-fd", str(wfd),
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
        watch = supervisor.Watch(memory_mb, max_processes=max_processes, folder=box, disk_mb=disk_mb)
        with open(private / "child.log", "wb") as log:
            child = subprocess.Popen(cmd, cwd=box / "work", env=env, stdin=subprocess.DEVNULL, stdout=log,
                                     stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=_limits(max_processes, ids[0] if ids else None),
                                     user=ids[0] if ids else None, group=ids[1] if ids else None,
                                     extra_groups=[] if ids else None, pass_fds=(wfd,))
            os.close(wfd)
            wfd = None
            collector = _Collector(rfd)
            rfd = None
            collector.start()
            if not watch.wait(child, wall):
                problems.append(f"grading stopped after {wall:.0f} s (--notebook-timeout {notebook_timeout:g} s)"
                                if wall == notebook_timeout else f"grading stopped after {wall:.0f} s")
            _stop(child)
            child = None
            collector.join(10)
        problems += watch.events
        results, report, rejected = read_results(bytes(collector.data), checks, lookup)
        if collector.overflow:
            notes.append(f"the results passed {MAX_CHANNEL_BYTES} bytes; the rest was ignored")
        more_notes, more_problems = read_report(report)
        notes += more_notes
        problems += more_problems
        if rejected:
            notes.append(f"{rejected} malformed result line(s) were ignored")
        unreadable = any(n.startswith("could not read the notebook") for n in more_notes)
        if not unreadable and not more_problems and any(not results[c.name] for c in checks):
            problems.append("no results came back for " + ", ".join(c.function for c in checks if not results[c.name]))
        judgements = [registry.judge(c, cases[c.name], {r["case"]: r for r in assemble(cases[c.name], results[c.name])})
                      if results[c.name] else
                      _zero([c], f"no results: {c.function} could not be called (the notebook stopped before grading; see the notes)")[0]
                      for c in checks]
        return NotebookResult(str(path), judgements, notes, problems, seed=seed)
    finally:
        for fd in (rfd, wfd):
            if fd is not None:
                os.close(fd)
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
                                      "not_graded": [clean(n) for n in r.not_graded], "seed": r.seed} for r in results]},
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
    for name in ("timeout", "cell_timeout", "memory_mb", "notebook_timeout", "max_processes", "disk_mb"):
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
                                          notebook_timeout=getattr(args, "notebook_timeout", 3600.0),
                                          seed=getattr(args, "seed", None),
                                          max_processes=getattr(args, "max_processes", supervisor.MAX_PROCESSES),
                                          disk_mb=getattr(args, "disk_mb", supervisor.DISK_MB)))
            results[-1].notes.append(f"graded in {time.monotonic() - t0:.1f} s (cases drawn with --seed {results[-1].seed})")
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
