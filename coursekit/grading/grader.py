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
  what it sent ("inputs unchanged", on every call of every case). Array arguments travel in
  shared memory that the grading child wrote and reads back after each call, so a change to
  them is seen from outside the kernel, whatever the kernel reports. Points come from the registry.
- The child starts in a new session and as an unprivileged user (``nobody``) when running as
  root, as autograders such as Gradescope do, in a bubblewrap sandbox (:mod:`.sandbox`): the
  file system read-only, ``solutions/``, the other submissions and the results file hidden, a
  private ``/tmp``, no network, its own PID namespace (the grader and its environment are not
  visible). Where the sandbox cannot be set up, grading is refused unless the instructor passes
  ``--unsafe``.
- **Limits** come from outside (:mod:`.supervisor`): resident memory (never address space: a
  CUDA build of torch reserves ~3 GB of it on import), the number of processes, the bytes
  written in the notebook's folder, the wall time of the whole notebook; ``RLIMIT_FSIZE`` bounds
  any one file, and ``RLIMIT_NPROC`` the processes: inside the sandbox's own user namespace for a
  grader who is not root (:func:`.sandbox.limit_processes`), for the user ``nobody`` when root.
- The simulator's compiled kernels are compiled once per grader, outside the sandbox, from the
  library's own code, and each notebook gets a copy of its own (:mod:`.warm`): a notebook that
  simulates does not spend 10-20 s compiling them.
- A graded function must be written in the notebook (:mod:`.runner` refuses one whose code comes
  from coursekit or any other file), and coursekit's own versions of it raise in the process
  that runs it, which is locked down against fetching them afresh (:mod:`.lockdown`). Beyond
  that, the sandbox does not hold them at all: it binds copies of their modules with those
  functions (and the checks' own oracles) withheld, masks their compiled files, and shows
  nothing of the checkout but the package (:mod:`.withheld`, :mod:`.sandbox`). The harvest
  runs in the student's kernel, so a notebook can take it over (an input transformer sees the
  harvest cell's socket address and token) and answer the calls from code of its own choosing;
  withholding is what makes that worth nothing: no process in the sandbox can run the
  library's version of a graded function, and array arguments are read back outside. A function
  the library needs while some checks are graded (``Check.library_uses``) but that answers
  another check is withheld for that one in a second run of the notebook (:func:`.withheld.runs`).
- A notebook part of which could not run -- a cell skipped for time, memory or a crash, a
  harvest that did not finish, no execution report -- is reported **not graded**, with the
  reasons, and ``coursekit grade`` exits with status 3: an instructor never gets a silent 0.
  The ``--json`` path is checked before grading starts; every message is stripped of terminal
  escapes and control characters (:func:`.report.clean`; the records themselves are validated in :mod:`.channel`).
- It is a child subreaper (Linux): processes the notebook forked, even double-forked daemons,
  become its children when their parents die, and are killed before any result is written.
  Results are written atomically after that, so nothing the notebook started can overwrite them.
  (``COURSEKIT_GRADE_KEEP=1`` keeps the private directory, with the child's log, for debugging;
  otherwise it is removed, after ``SIGTERM`` too, and by the next run after a ``SIGKILL``.)

What is still trusted: the calls run in the notebook's own interpreter (that is where its
function lives), so the code that converts a result runs there too, from source shipped fresh,
next to whatever the notebook patched before; what a notebook can choose is the raw outputs,
which is what any function does. What it reports about its *arguments* counts only where the
grading child cannot look itself: array arguments are read back from shared memory, but a
genome's or creature's state after the call is serialised in the kernel (a notebook that patches
``to_json`` or swaps the argument through the caller's frame can hide a change to one), and a
function that undoes its change from a thread of its own before the record comes back is not
seen either (a caller looking then would not see it).
Inside the sandbox it runs as ``nobody`` where that user can run this Python, else as the
grader's user with every capability dropped: it can then read files that user can read outside
the hidden ones.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import secrets
import shutil
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from coursekit.grading import checks as registry
from coursekit.grading import sandbox, supervisor, warm, withheld
from coursekit.grading.channel import MAX_CHANNEL_BYTES, Collector, read_report, read_results, read_untrusted
from coursekit.grading.checks import Judgement, Verdict
from coursekit.grading.report import (NotebookResult, check_results_path, clean, gradescope, summary,
                                      write_json_atomic)
from coursekit.grading.runner import assemble
from coursekit.grading.supervisor import PKG_ROOT

# -- which exercise a notebook is --------------------------------------------------------------

MAX_NOTEBOOK_BYTES = 64 * 2**20


def exercise_of(path: str | os.PathLike[str], override: str | None = None) -> str:
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
        data = read_untrusted(path, MAX_NOTEBOOK_BYTES)
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



def named_exercises(path: str | os.PathLike[str]) -> list[str]:
    """The registered exercises whose names a notebook's file name holds, whatever the case, the
    separators and what a browser or a course site adds around it (``03_Picture_Recombination (1)``,
    ``alice_03_picture_recombination``)."""
    registry._load()
    stem = "_" + re.sub(r"[^a-z0-9]+", "_", Path(path).name.lower().removesuffix(".ipynb")) + "_"
    return [name for name in sorted(registry.EXERCISES) if f"_{name}_" in stem]


# -- the grading plan and one notebook's run ------------------------------------------------------


def new_seed() -> int:
    """A fresh grading seed: the cases of every run are new (``--seed`` repeats a run's cases)."""
    return secrets.randbits(63)


def make_plan(checks: Sequence, cases: dict, rng: np.random.Generator, held: Sequence[str] = (),
              native: bool = False) -> tuple[list, dict]:
    """The calls sent to the grading child, and how to read their records (``held``: what its
    sandbox withholds, refused by name while each function runs; ``native``: the sandbox withholds
    them, so the student's code may make C calls, as numba does when it compiles).

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
        plans.append({"name": c.name, "function": c.function, "output": c.output, "refuse": withheld.refused(c, held),
                      "native": native, "calls": calls})
        lookup[c.name] = ids
    return plans, lookup



def grade_notebook(path: str | os.PathLike[str], *, timeout: float = 60.0, cell_timeout: float = 300.0,
                   memory_mb: int = 4096, seed: int | None = None, exercise: str | None = None, user: str = "nobody",
                   sandboxed: bool = True, hide_files: Sequence[str | os.PathLike[str]] = (),
                   notebook_timeout: float = 3600.0, max_processes: int = supervisor.MAX_PROCESSES,
                   disk_mb: int = supervisor.DISK_MB) -> NotebookResult:
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
    try:
        nb_bytes = path.read_bytes()
    except OSError as exc:
        return NotebookResult(str(path), _zero(checks, f"could not read {path}: {exc.strerror}"), [],
                              [f"could not read {path}: {exc.strerror}"])
    ids = supervisor.grading_user(user)
    if sandboxed and ids and sandbox.available(ids, show=[PKG_ROOT / "coursekit"]) is not None:
        ids = None  # the sandbox works for this user only: run it as this user, capabilities dropped
    notes = []
    grader_notes = [] if ids or os.geteuid() != 0 else [f"ran as root: user {user!r} could not run this Python, so privileges were not dropped"
                                                         + (" (inside the sandbox, every capability dropped)" if sandboxed else "")]
    if not sandboxed:
        grader_notes.append("graded without a sandbox (--unsafe): the notebook could read solutions/ and other submissions")
    problems, judgements, start = [], {}, time.monotonic()
    groups = withheld.runs(checks) if sandboxed else [(checks, withheld.of(checks))]  # --unsafe: refused by name only
    for k, (group, held) in enumerate(groups):
        plans, lookup = make_plan(group, cases, rng, held, native=sandboxed)
        left = notebook_timeout - (time.monotonic() - start)
        if left < 1:  # the first run took it all
            stopped = f"grading stopped after {notebook_timeout:.0f} s (--notebook-timeout {notebook_timeout:g} s)"
            problems += [] if stopped in problems else [stopped]
            break
        results, run_notes, run_problems = _run(nb_bytes, {"timeout": float(timeout), "memory_mb": int(memory_mb), "checks": plans},
                                                group, lookup, held if sandboxed else None, ids, timeout=timeout,
                                                cell_timeout=cell_timeout, memory_mb=memory_mb, hide_files=hide_files,
                                                left=left, notebook_timeout=notebook_timeout, max_processes=max_processes, disk_mb=disk_mb)
        if k:  # the second run: its own cells' notes only where they differ from the first's
            what = ", ".join(c.function for c in group)
            run_notes = [f"while {what} was graded (a second run of the notebook): {n}" for n in run_notes if n not in notes]
            run_problems = [f"{what} (second run): {p}" for p in run_problems]
        notes += run_notes
        problems += run_problems
        for c in group:
            judgements[c.name] = _judge(c, cases[c.name], results[c.name], problems)
    return NotebookResult(str(path), [judgements.get(c.name) or _zero([c], f"not run: {c.function} was to be graded in a second run")[0]
                                      for c in checks], notes, problems, seed=seed, grader_notes=grader_notes)


def _judge(check, cases, records, problems) -> Judgement:
    """``check``'s judgement of its ``records``; a record the grader cannot read (a bug the
    notebook's data reached) zeroes the check and adds to ``problems``: the notebook is then not
    graded, and the other notebooks of the run are."""
    if not records:
        return _zero([check], f"no results: {check.function} could not be called (the notebook stopped before grading; see the notes)")[0]
    try:
        return registry.judge(check, cases, {r["case"]: r for r in assemble(cases, records)})
    except Exception as exc:  # noqa: BLE001 -- whatever it is, this notebook alone pays for it
        why = clean(f"the grader failed to judge {check.function}: {type(exc).__name__}: {exc}")[:300]
        problems.append(why)
        return _zero([check], why)[0]


def _run(nb_bytes: bytes, plan: dict, checks: Sequence, lookup: dict, held: Sequence[str] | None, ids, *, timeout: float,
         cell_timeout: float, memory_mb: int, hide_files: Sequence, left: float, notebook_timeout: float, max_processes: int,
         disk_mb: int) -> tuple[dict, list, list]:
    """Run the notebook once in a grading child (in the sandbox, withholding ``held``; None: no
    sandbox) with ``plan``'s calls, within the ``left`` seconds of the notebook's ``notebook_timeout``;
    ``(records by check, notes, problems)``."""
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
        (box / "submission.ipynb").write_bytes(nb_bytes)
        calls_file = box / "calls.json"  # read and deleted by the child before the notebook runs
        fd = os.open(calls_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            json.dump(plan, f)
        if ids:
            os.chown(calls_file, *ids)
        env = {k: v for k, v in os.environ.items() if k in ("PATH", "LANG", "LC_ALL", "TZ", "COURSEKIT_PROFILE")}
        env.update(PYTHONPATH=str(PKG_ROOT), HOME=str(box / "home"), JUPYTER_RUNTIME_DIR=str(box / "runtime"),
                   IPYTHONDIR=str(box / "home" / ".ipython"), MPLCONFIGDIR=str(box / "home" / ".mpl"),
                   TMPDIR=str(box / "tmp"), MPLBACKEND="Agg", PYTHONNOUSERSITE="1",
                   COURSEKIT_PROFILE=env.get("COURSEKIT_PROFILE", "ci"))
        rfd, wfd = os.pipe()
        cmd = [sys.executable, "-m", "coursekit.grading.executor", "--notebook", str(box / "submission.ipynb"),
               "--calls", str(calls_file), "--results-fd", str(wfd),
               "--cwd", str(box / "work"), "--cell-timeout", str(cell_timeout)]
        if held is not None:
            cmd += ["--max-processes", str(max_processes)]  # RLIMIT_NPROC inside, where it holds (sandbox.limit_processes)
            replace, compiled = withheld.withhold(held, private / "withheld")
            kernels = warm.copy_into(box / "numba", [module for _, module in replace])  # the simulator compiled once, not per notebook
            if kernels is not None:
                env["NUMBA_CACHE_DIR"] = str(kernels)
                if ids:
                    for f in [kernels, *kernels.rglob("*")]:
                        os.chown(f, *ids)
            cmd = sandbox.command(box, show=[PKG_ROOT / "coursekit"], hide_dirs=[PKG_ROOT / "solutions", PKG_ROOT / ".git"],
                                  hide_files=[*hide_files, *compiled], replace=replace) + cmd
        # The child bounds every cell and call itself; this bounds the notebook as a whole.
        wall = min(float(left), 2 * cell_timeout * (min(nb_bytes.count(b'"cell_type"'), 500) + 2) + (4 * timeout + 60) * len(checks))
        notes, problems = [], []
        watch = supervisor.Watch(memory_mb, max_processes=max_processes, folder=box, disk_mb=disk_mb)
        with open(private / "child.log", "wb") as log:
            child = subprocess.Popen(cmd, cwd=box / "work", env=env, stdin=subprocess.DEVNULL, stdout=log,
                                     stderr=subprocess.STDOUT, start_new_session=True, preexec_fn=supervisor.limits(max_processes, ids[0] if ids else None),
                                     user=ids[0] if ids else None, group=ids[1] if ids else None,
                                     extra_groups=[] if ids else None, pass_fds=(wfd,))
            os.close(wfd)
            wfd = None
            collector = Collector(rfd)
            rfd = None
            collector.start()
            if not watch.wait(child, wall):
                problems.append(f"grading stopped after {notebook_timeout:.0f} s (--notebook-timeout {notebook_timeout:g} s)"
                                if wall == left else f"grading stopped after {wall:.0f} s")
            supervisor.stop(child)
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
        return results, notes, problems
    finally:
        for fd in (rfd, wfd):
            if fd is not None:
                os.close(fd)
        if child is not None:  # interrupted (Terminated, KeyboardInterrupt): nothing of the notebook survives
            supervisor.stop(child)
        if not os.environ.get("COURSEKIT_GRADE_KEEP"):
            shutil.rmtree(private, ignore_errors=True)


def _zero(checks, why):
    return [Judgement(c, False, [Verdict("graded", False, why)], 0.0) for c in checks]



#: Exit status of ``coursekit grade`` when a notebook could not be graded (2 is a usage error).
EXIT_NOT_GRADED = 3


def main(args: argparse.Namespace) -> int:
    """``coursekit grade``: grade each notebook in isolation, print a summary, write Gradescope JSON.

    Exits 0 when every notebook was graded, 2 on a usage error (nothing graded, nothing written),
    3 when a notebook was not graded (its cells were skipped for time, memory or a crash) and
    1 when the results file could not be written.
    """
    for stream in (sys.stdout, sys.stderr):  # a terminal that cannot show a character gets "?", not a traceback
        if hasattr(stream, "reconfigure"):
            stream.reconfigure(errors="replace")
    for name in ("timeout", "cell_timeout", "memory_mb", "notebook_timeout", "max_processes", "disk_mb"):
        v = getattr(args, name, None)
        if v is not None and not (v > 0 and (isinstance(v, int) or math.isfinite(v))):
            print(f"coursekit grade: --{name.replace('_', '-')} must be a positive finite number, got {v}", file=sys.stderr)
            return 2
    missing = [nb for nb in args.notebooks if not os.path.isfile(nb)]
    if missing:  # a mistyped path, before any notebook is graded
        print(f"coursekit grade: no such notebook file: {', '.join(map(repr, missing))}", file=sys.stderr)
        return 2
    override = getattr(args, "exercise", None)
    if override:
        try:
            registry.for_notebook(override)
        except ValueError as exc:
            print(f"coursekit grade: --exercise: {exc}", file=sys.stderr)
            return 2
    exercises = []
    for nb in args.notebooks:  # a notebook whose exercise is unknown is not graded; the others are
        try:
            exercises.append(exercise_of(nb, override))
        except ValueError as exc:
            exercises.append(exc)
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
    if not supervisor.become_subreaper():
        print("coursekit grade: warning: cannot adopt orphaned processes (no PR_SET_CHILD_SUBREAPER); "
              "processes a notebook daemonises may outlive grading", file=sys.stderr)
    if not unsafe and any(type(e) is str for e in exercises):  # before the first notebook, so that its time is its own
        if not warm.cached():
            print("coursekit grade: compiling the simulator once, for every notebook to load (10-20 s, the first "
                  "time on this machine)", file=sys.stderr, flush=True)
        warm.cache()
    results = []
    try:
        for nb, exercise in zip(args.notebooks, exercises):
            t0 = time.monotonic()
            if isinstance(exercise, ValueError):
                results.append(NotebookResult(nb, [], [], [clean(exercise)]))
                continue
            try:
                results.append(grade_notebook(nb, timeout=args.timeout, cell_timeout=getattr(args, "cell_timeout", 300.0),
                                              memory_mb=getattr(args, "memory_mb", 4096), exercise=exercise,
                                              sandboxed=not unsafe, hide_files=hide,
                                              notebook_timeout=getattr(args, "notebook_timeout", 3600.0),
                                              seed=getattr(args, "seed", None),
                                              max_processes=getattr(args, "max_processes", supervisor.MAX_PROCESSES),
                                              disk_mb=getattr(args, "disk_mb", supervisor.DISK_MB)))
            except supervisor.Terminated:
                raise
            except Exception as exc:  # noqa: BLE001 -- a grader bug costs this notebook its grade, not the batch its results
                why = clean(f"the grader failed on this notebook: {type(exc).__name__}: {exc}")[:300]
                results.append(NotebookResult(nb, _zero(registry.for_notebook(exercise), why), [], [why]))
            results[-1].seconds, results[-1].exercise = round(time.monotonic() - t0, 2), exercise
            named = named_exercises(nb)
            if named and exercise not in named and not override:  # a file handed in as one exercise that answers another
                results[-1].not_graded.append(
                    f"its file name names exercise {named[0]}, but its metadata field coursekit.exercise says {exercise}: "
                    f"graded as {exercise}; pass --exercise to say which exercise it answers")
            if results[-1].seed is not None:
                results[-1].grader_notes.append(f"graded in {results[-1].seconds:.1f} s (cases drawn with --seed {results[-1].seed})")
    except supervisor.Terminated as exc:  # the notebook's processes and private folder are gone already
        print(f"coursekit grade: {exc}; no results written", file=sys.stderr)
        return 128 + exc.signum
    finally:
        if supervisor.ADOPTING:
            supervisor.sweep()
    if args.json_out:  # the results first: nothing printed can cost them
        try:
            write_json_atomic(args.json_out, gradescope(results))
        except OSError as exc:
            print(f"coursekit grade: could not write the results to {args.json_out}: {exc.strerror}", file=sys.stderr)
            return 1
    print(summary(results))
    return 0 if all(r.graded for r in results) else EXIT_NOT_GRADED
