"""Calling student functions on plain-data calls, one at a time, each bounded, results as plain data.

Part of the exercise machinery behind the seed paper's section 4 (students' own GA operators
drive the real systems, and are checked first). This module is the only grading code that runs
next to student code: in the student's kernel for formative checks, and -- shipped as *source
text* and executed in a fresh namespace, never imported from the kernel's possibly patched
``coursekit`` -- inside the grading kernel for the summative grader, where :func:`harvest`
fetches the grader's calls one at a time over a socket. It is therefore self-contained
(standard library and numpy; :mod:`.values` and :mod:`.lockdown` are shipped with it) and
produces only raw observations, never verdicts: each call's converted result and every argument
as it was after the call. In summative grading a call's array arguments come as shared memory
(file descriptors passed with its line, :class:`_Lines`), which the grading child reads back
itself, and the worker that runs the calls refuses coursekit's own versions of the function for
good and is locked down (:meth:`.lockdown.Refusing.forever`).

Isolation: calls run in a ``fork()`` of the current process (copy-on-write: it sees every name
the notebook defined) that serves them one at a time (:class:`Calls`), with a cap on the address
space it may *add* (``RLIMIT_AS`` set to its size at the fork plus ``memory_mb``, so reservations
made before, such as a CUDA torch's, do not count; the summative grader bounds resident memory
from outside), its ``print`` captured, and a watchdog in the calling process that ``SIGKILL``s it
when a call does not finish within ``timeout`` seconds. An infinite loop, ``sys.exit``,
``os._exit``, a segfault or a huge allocation therefore costs one call, never the kernel, and
the next call runs in a fresh fork. Trade-off: a fork is a real kill (threads cannot be killed)
and contains crashes, but forking a multi-threaded process (the kernel) only keeps the calling
thread, so the worker must not touch the kernel's I/O threads -- it writes to a private pipe and
never to the kernel's stdout. Where ``fork`` does not exist (Windows) calls run in a daemon
thread: a timeout is reported but the runaway thread cannot be stopped, and a crash takes the
kernel with it. Setting ``COURSEKIT_CHECK_ISOLATION=thread`` chooses threads everywhere (for
platforms where forking a kernel is fragile, e.g. macOS with GUI frameworks loaded).

Case format (plain JSON; a check makes its cases, :func:`calls_of` turns them into calls)::

    {"id": "rate", "args": [{"ndarray": [0, 1, 1], "dtype": "int64"}, {"rng": true}],
     "kwargs": {"rate": 0.25}, "seeds": [11, 12, 13], "max_len": 100}

The function is called once per seed, with ``{"rng": true}`` replaced by
``numpy.random.default_rng(seed)``. A call's record carries ``status``
(``ok``/``not_implemented``/``error``/``timeout``/``died``/``missing``/``bad_output``),
``output`` (the converted result, when ok), ``error`` text otherwise, ``inputs_after`` (every
argument after the call) and ``printed`` (what the function printed, truncated);
:func:`assemble` groups them into one record per case for the judges.
"""

from __future__ import annotations

import io
import json
import os
import select
import signal
import socket
import sys
import threading
import time

if __name__ != "coursekit_harvest":  # imported; the harvest cell ships the texts of values.py and lockdown.py first
    from coursekit.grading.lockdown import Refusing
    from coursekit.grading.values import BadOutput, _after, changed, convert, decode, map_shared

MAX_PRINTED = 1500
MAX_ERROR = 600
MAX_MESSAGE = 64 * 2**20  # the longest call line read (a call with two large creatures)


def _describe_error(exc):
    text = f"{type(exc).__name__}: {exc}"
    return text if len(text) <= MAX_ERROR else text[: MAX_ERROR - 3] + "..."


def calls_of(cases):
    """The calls of ``cases`` in order: one self-contained plain dict per seed.

    A call is ``{"id", "args", "kwargs", "seed", "max_len"}``; its id is ``"<case id>#<index>"``
    here (the summative grader replaces it by a random token, so a call says nothing about its case).
    """
    return [{"id": f"{c['id']}#{i}", "args": c["args"], "kwargs": c.get("kwargs", {}), "seed": s, "max_len": c["max_len"]}
            for c in cases for i, s in enumerate(c["seeds"])]


def run_call(fn, call, kind, guard=None, capture=True, shared=()):
    """Call ``fn`` once on ``call`` in this process; return the plain record of that call.

    The record carries ``id``, ``status``, ``output`` (when ok), ``error`` otherwise, and
    ``inputs_after``: every argument as it is after the call (None for those that are not arrays
    or library objects), so whoever judges can see whether the call modified its inputs. With
    ``capture``, what the function prints is recorded (``printed``) instead of shown (only safe
    where nothing else runs meanwhile: in a forked worker). ``guard`` is a :class:`Refusing`;
    ``shared`` the mappings of the call's shared-memory arguments (see :func:`.values.decode`).
    """
    record = {"id": call["id"]}
    captured = io.StringIO()
    old = sys.stdout, sys.stderr
    if capture:
        sys.stdout = sys.stderr = captured
    try:
        args = [decode(a, call["seed"], shared) for a in call["args"]]
        kwargs = {k: decode(v, call["seed"], shared) for k, v in call.get("kwargs", {}).items()}
        try:
            if guard is None:
                out = fn(*args, **kwargs)
                record["output"] = convert(kind, out, call["max_len"])
            else:  # converting runs the result's to_json: the library stays refused for it too
                with guard:
                    out = fn(*args, **kwargs)
                    record["output"] = convert(kind, out, call["max_len"])
        except NotImplementedError as exc:
            record.update(status="not_implemented", error=_describe_error(exc))
            return record
        except BadOutput as exc:
            record.update(status="bad_output", error=str(exc))
            return record
        except BaseException as exc:  # SystemExit, KeyboardInterrupt and friends included
            record.update(status="error", error=_describe_error(exc))
            return record
        try:
            record["inputs_after"] = [_after(a, v, call["max_len"]) for a, v in zip(args, call["args"])]
        except BadOutput as exc:  # an argument the function turned into something that no longer serialises
            record.pop("output", None)
            record.update(status="bad_output", error=f"after the call, {exc}")
            return record
        record["status"] = "ok"
        return record
    finally:
        if capture:
            sys.stdout, sys.stderr = old
        printed = captured.getvalue()
        if printed:
            record["printed"] = printed[:MAX_PRINTED]


def assemble(cases, results):
    """Per-case records, the format :func:`coursekit.grading.checks.judge` reads, from per-call ones.

    Args:
        cases: the case dicts.
        results: ``{(case id, call index): call record}``; a missing call counts as not returned.
    Returns:
        one record per case: ``status`` (``ok`` only when every call was), ``outputs`` (one per
        seed), ``inputs_after`` (of the first call that modified its inputs, else of the first
        call), or the first failure's ``status``, ``error`` and ``call`` index.
    """
    out = []
    for c in cases:
        recs = [results.get((c["id"], i)) for i in range(len(c["seeds"]))]
        rec = {"case": c["id"]}
        failed = [(i, r) for i, r in enumerate(recs) if r is not None and r["status"] != "ok"]
        missing = [i for i, r in enumerate(recs) if r is None]
        if failed:
            i, r = failed[0]
            rec.update(status=r["status"], error=r.get("error", "?"), call=i)
        elif missing:
            rec.update(status="timeout", error="no result came back for this call", call=missing[0])
        else:
            afters = [r.get("inputs_after") for r in recs]
            changed_inputs = next((a for a in afters if any(changed(x, e) for x, e in zip(a or (), c["args"]))), None)
            rec.update(status="ok", outputs=[r["output"] for r in recs], inputs_after=changed_inputs or afters[0])
        printed = next((r["printed"] for r in recs if r is not None and r.get("printed")), None)
        if printed:
            rec["printed"] = printed
        out.append(rec)
    return out


def _limit_memory(memory_mb):
    try:
        import resource

        with open("/proc/self/statm") as f:
            vsz = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        want = vsz + memory_mb * 2**20
        if soft != resource.RLIM_INFINITY:
            want = min(want, soft)
        if hard != resource.RLIM_INFINITY:
            want = min(want, hard)
        resource.setrlimit(resource.RLIMIT_AS, (want, hard))
    except (ImportError, OSError, ValueError, OverflowError):
        pass  # no /proc or no RLIMIT_AS (macOS), or a limit past what rlim_t holds: the outer limits still apply


def _write_all(fd, data):
    while data:
        data = data[os.write(fd, data):]


class _Lines:
    """Lines from a Unix stream socket, and the file descriptors passed along (``SCM_RIGHTS``).

    Descriptors arrive with the bytes they were sent with, but one read may also hold the line
    before them, so they wait here until the line that needs them takes them (:meth:`take`).
    """

    def __init__(self, sock, limit):
        self.sock, self.limit, self.buf, self.fds = sock, limit, b"", []

    def readline(self):
        """The next line without its newline, or None at the end (or past the limit)."""
        while b"\n" not in self.buf:
            if len(self.buf) > self.limit:
                return None
            data, fds, _, _ = socket.recv_fds(self.sock, 1 << 16, 16)
            self.fds += fds
            if not data:
                return None
            self.buf += data
        line, self.buf = self.buf.split(b"\n", 1)
        return line

    def take(self, n):
        """The next ``n`` descriptors received (fewer if fewer came: the call then fails to decode)."""
        fds, self.fds = self.fds[:n], self.fds[n:]
        return fds


def send_line(sock, data, fds=()):
    """Send ``data`` (one line) on a Unix stream socket, with ``fds`` attached to its first bytes."""
    sent = socket.send_fds(sock, [data], list(fds)) if fds else 0
    sock.sendall(data[sent:])


def _sizes(call):
    """Bytes of each shared-memory argument of ``call``, by index."""
    sizes = {}
    for v in list(call["args"]) + list(call.get("kwargs", {}).values()):
        if isinstance(v, dict) and "shared" in v:
            sizes[v["shared"]] = v["nbytes"]
    return [sizes[k] for k in range(len(sizes))]


def _serve_calls(fn, kind, sock, wfd, memory_mb, refuse, native):
    """Body of a forked worker: read call lines (with their shared memory) from ``sock``, write
    ``R <record>`` lines to ``wfd``; never return. With ``refuse``, the process is locked down first
    (:meth:`Refusing.forever`); where that fails, every call is refused."""
    try:
        sys.stdin = io.StringIO()
        _limit_memory(memory_mb)
        broken = None
        if refuse:
            try:
                Refusing(refuse, getattr(fn, "__name__", "function"), native).forever()
            except BaseException as exc:
                broken = f"the grader could not lock the graded function's process down ({_describe_error(exc)})"
        lines = _Lines(sock, MAX_MESSAGE)
        while True:
            line = lines.readline()
            if line is None:
                break
            call = json.loads(line)
            fds = lines.take(len(_sizes(call)))
            if broken:
                for fd in fds:
                    os.close(fd)
                record = {"id": call["id"], "status": "error", "error": broken}
            else:
                shared = map_shared(fds, _sizes(call))
                record = run_call(fn, call, kind, shared=shared)
                for m in shared:
                    try:
                        m.close()
                    except BufferError:  # the function kept a view of it
                        pass
            try:
                text = json.dumps(record, allow_nan=False)
            except (TypeError, ValueError) as exc:
                text = json.dumps({"id": call["id"], "status": "bad_output", "error": f"result is not plain data: {exc}"})
            _write_all(wfd, b"R " + text.encode() + b"\n")
    finally:
        os._exit(0)


def _died_message(status):
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            name = signal.Signals(sig).name
        except ValueError:
            name = str(sig)
        return f"the process running it was killed by signal {name} (a crash, or it ran out of memory)"
    return f"the process running it exited with status {os.WEXITSTATUS(status)} (os._exit?)"


class _Worker:
    """A forked copy of this process (it sees every name the notebook defined) that runs calls one at a time."""

    def __init__(self, fn, kind, memory_mb, refuse, native):
        mine, theirs = socket.socketpair()  # calls, with their shared memory: parent -> worker
        rrfd, rwfd = os.pipe()  # records: worker -> parent
        self.pid = os.fork()
        if self.pid == 0:
            mine.close()
            os.close(rrfd)
            _serve_calls(fn, kind, theirs, rwfd, memory_mb, refuse, native)
        theirs.close()
        os.close(rwfd)
        self.calls, self.records, self.buf = mine, rrfd, b""

    def call(self, call, timeout, fds=()):
        """The worker's record of ``call`` (``fds``: its shared memory); ``None`` after ``timeout`` s
        (the worker is then killed), or ``("died", status)`` when it stopped."""
        try:
            send_line(self.calls, json.dumps(call).encode() + b"\n", fds)
        except OSError:  # the worker is gone
            return ("died", self.close(kill=True))
        deadline = time.monotonic() + timeout
        while b"\n" not in self.buf:
            left = deadline - time.monotonic()
            if left <= 0 or not select.select([self.records], [], [], left)[0]:
                if time.monotonic() >= deadline:
                    self.close(kill=True)
                    return None
                continue
            chunk = os.read(self.records, 65536)
            if not chunk:
                return ("died", self.close(kill=False))
            self.buf += chunk
        line, self.buf = self.buf.split(b"\n", 1)
        try:
            rec = json.loads(line[2:]) if line.startswith(b"R ") else None
        except ValueError:
            rec = None
        if not isinstance(rec, dict) or rec.get("id") != call["id"]:
            return ("died", self.close(kill=True))
        return rec

    def close(self, kill=False):
        """Stop the worker and reap it; returns its wait status."""
        self.calls.close()
        try:
            os.close(self.records)
        except OSError:
            pass
        if kill:
            try:
                os.kill(self.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        _, status = os.waitpid(self.pid, 0)
        return status


class Calls:
    """Run calls of one function one at a time, each bounded; a context manager.

    In a forked :class:`_Worker` (re-forked after a crash or a timeout, so the next call starts
    fresh), or in daemon threads where there is no ``fork`` (see the module docstring).

    Args:
        fn: the student's function.
        kind: output conversion kind (see :func:`convert`).
        timeout: seconds allowed per call.
        memory_mb: extra address space a worker may allocate.
        budget: seconds for all calls together; calls after it are reported as timeouts unrun.
        refuse: ``"module:attr"`` names of coursekit's own versions of the function (see :class:`Refusing`).
        native: the worker may make C calls through ctypes (numba compiling), where the sandbox withholds the library.
    """

    def __init__(self, fn, kind, *, timeout=10.0, memory_mb=2048, budget=None, refuse=(), native=False):
        self.fn, self.kind, self.timeout, self.memory_mb, self.refuse = fn, kind, float(timeout), memory_mb, tuple(refuse)
        self.native = native
        self.budget = 4 * self.timeout + 30 if budget is None else float(budget)
        self.fork = hasattr(os, "fork") and os.environ.get("COURSEKIT_CHECK_ISOLATION", "fork") != "thread"
        self.worker = None
        self.old_chld = None

    def __enter__(self):
        self.end = time.monotonic() + self.budget
        # A notebook that ignores SIGCHLD makes the kernel reap its children itself, and waitpid()
        # on a worker would fail: the default disposition is restored for the calls, then put back.
        if self.fork and threading.current_thread() is threading.main_thread():
            self.old_chld = signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        return self

    def __exit__(self, *exc):
        if self.worker is not None:
            self.worker.close(kill=True)
            self.worker = None
        if self.old_chld is not None:
            signal.signal(signal.SIGCHLD, self.old_chld)
        return False

    def call(self, call, fds=()):
        """The plain record of one call (see :func:`run_call`); ``fds``: its shared memory, closed here."""
        try:
            return self._call(call, fds)
        finally:
            for fd in fds:
                try:
                    os.close(fd)
                except OSError:
                    pass

    def _call(self, call, fds):
        left = self.end - time.monotonic()
        over = {"id": call["id"], "status": "timeout", "error": f"the time budget of {self.budget:g} s for all calls ran out"}
        if left <= 0:
            return over
        if not self.fork:
            box = []
            shared = map_shared([os.dup(fd) for fd in fds], _sizes(call))
            t = threading.Thread(target=lambda: box.append(run_call(self.fn, call, self.kind, self._guard(), capture=False,
                                                                    shared=shared)), daemon=True)
            t.start()
            t.join(min(self.timeout, left))
            return box[0] if box else (over if time.monotonic() >= self.end else
                                       {"id": call["id"], "status": "timeout", "error": f"a call did not return within {self.timeout:g} s"})
        if self.worker is None:
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)  # "multi-threaded, fork() may deadlock"
                self.worker = _Worker(self.fn, self.kind, self.memory_mb, self.refuse, self.native)
        rec = self.worker.call(call, min(self.timeout, left), fds)
        if rec is None:
            self.worker = None
            return over if time.monotonic() >= self.end else \
                {"id": call["id"], "status": "timeout", "error": f"a call did not return within {self.timeout:g} s"}
        if type(rec) is tuple:
            self.worker = None
            return {"id": call["id"], "status": "died", "error": _died_message(rec[1])}
        return rec

    def _guard(self):
        return Refusing(self.refuse, getattr(self.fn, "__name__", "function")) if self.refuse else None


def run_cases(fn, cases, kind, *, timeout=10.0, memory_mb=2048, budget=None, refuse=()):
    """Run ``fn`` on every call of every case, isolated and bounded; return one plain record per case.

    Args:
        fn: the student's function.
        cases: list of case dicts (see module docstring).
        kind: output conversion kind (see :func:`convert`).
        timeout: seconds allowed per call.
        memory_mb: extra address space the worker may allocate.
        budget: seconds for all cases together (default ``4 * timeout + 30``); cases not reached
            in time are reported as timeouts.
        refuse: ``"module:attr"`` names of coursekit's own versions of the function, which raise
            while it runs (see :class:`Refusing`).
    Returns:
        list of record dicts, in case order (see :func:`assemble`). After a case's first failing
        call its other calls are not made.
    """
    results = {}
    with Calls(fn, kind, timeout=timeout, memory_mb=memory_mb, budget=budget, refuse=refuse) as calls:
        for c in cases:
            for i, call in enumerate(calls_of([c])):
                rec = calls.call(call)
                results[(c["id"], i)] = rec
                if rec["status"] != "ok":
                    break
    return assemble(cases, results)


def _foreign(fn, cells):
    """Why ``fn`` is not the notebook's own function, or None (``cells``: the kernel's cell file names)."""
    code = getattr(fn, "__code__", None)
    if code is None:
        return f"is a {type(fn).__name__}, not a function written with def in this notebook"
    if code.co_filename in cells:
        return None
    module = getattr(fn, "__module__", None) or ""
    if module == "coursekit" or module.startswith("coursekit."):
        where = f"coursekit's own, from {module}"
    elif "coursekit" in code.co_filename.replace("\\", "/").split("/"):
        where = f"coursekit's own code, from {os.path.basename(code.co_filename)}"
    else:
        where = f"not defined in this notebook (its code comes from {os.path.basename(code.co_filename)})"
    return f"is {where}; write your own with def in a cell of this notebook (the rest of the library may be used)"


def harvest(namespace, address, token, cells=None):
    """Summative side: answer the grader's calls of one check, one call at a time, from a fork of the kernel.

    The fork (:func:`_harvest`) is locked down against coursekit's own versions of the function
    (:meth:`Refusing.forever`) before it connects, so that nothing of the kernel's -- a patched
    ``json`` that would rewrite each record with the library's answer on its way back -- can
    compute that answer; threads a cell left running in the kernel are not in the fork. Where
    ``fork`` does not exist, it runs here, unlocked. Raises ``RuntimeError`` when the fork failed.
    """
    if not hasattr(os, "fork") or os.environ.get("COURSEKIT_CHECK_ISOLATION", "fork") == "thread":
        return _harvest(namespace, address, token, cells, lock=False)
    main = threading.current_thread() is threading.main_thread()
    old = signal.signal(signal.SIGCHLD, signal.SIG_DFL) if main else None  # a notebook may ignore SIGCHLD
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # "multi-threaded, fork() may deadlock"
            pid = os.fork()
        if pid == 0:
            code = 1
            try:
                _harvest(namespace, address, token, cells, lock=True)
                code = 0
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
    finally:
        if old is not None:
            signal.signal(signal.SIGCHLD, old)
    if status != 0:
        raise RuntimeError(f"the harvest's process stopped: {_died_message(status)}")


def _harvest(namespace, address, token, cells, lock):
    """The body of :func:`harvest`.

    Connects to the grading child's socket ``address``, proves itself with ``token`` (which only
    this harvest cell knows), and receives the check's header ``{"name", "function", "output",
    "timeout", "memory_mb", "budget", "refuse", "native"}``; then, until ``{"end": true}``, one call at a
    time: ``{"call": {...}}`` answered by its plain record (:func:`run_call`). The cases are never
    all in the kernel: each call arrives only after the previous one's record went back. With
    ``cells`` (the file names the kernel compiled the notebook's cells under), a function whose
    code comes from anywhere else -- ``from coursekit.ga import tournament``, a module on disk --
    is refused as not attempted; ``refuse`` lists coursekit's own versions of the function, which
    raise in this process (with ``lock``) and in the one that runs it (:meth:`Refusing.forever`).
    A call's array arguments come
    as shared memory (file descriptors with its line), which the worker maps and this cell closes.
    """
    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.connect(address)
    lines = _Lines(sock, MAX_MESSAGE)

    def send(obj):
        sock.sendall(json.dumps(obj, allow_nan=False).encode() + b"\n")

    def receive():
        line = lines.readline()
        return json.loads(line) if line is not None else None

    try:
        send({"token": token})
        check = receive()
        fn = namespace.get(check["function"])
        why = None
        if not callable(fn):
            why = "is not defined" if fn is None else f"is a {type(fn).__name__}, not a function"
        elif cells is not None:
            why = _foreign(fn, cells)
        try:
            if lock and check.get("refuse"):
                Refusing(check["refuse"], check["function"], check.get("native") is True).forever()
        except BaseException as exc:
            why = why or f"could not be graded: the grader could not lock the harvest down ({_describe_error(exc)})"
        with Calls(fn, check["output"], timeout=check["timeout"], memory_mb=check["memory_mb"], budget=check["budget"],
                   refuse=tuple(check.get("refuse", ())), native=check.get("native") is True) as calls:
            while True:
                msg = receive()
                if type(msg) is not dict or "call" not in msg:
                    break
                call = msg["call"]
                fds = lines.take(len(_sizes(call)))
                if why:
                    for fd in fds:
                        os.close(fd)
                    rec = {"id": call["id"], "status": "missing", "error": f"{check['function']} {why}"}
                else:
                    rec = calls.call(call, fds)
                rec.pop("printed", None)
                send(rec)
    finally:
        sock.close()
