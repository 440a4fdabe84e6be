"""Calling student functions on plain-data calls, one at a time, each bounded, results as plain data.

Part of the exercise machinery behind the seed paper's section 4 (students' own GA operators
drive the real systems, and are checked first). This module is the only grading code that runs
next to student code: in the student's kernel for formative checks, and -- shipped as *source
text* and executed in a fresh namespace, never imported from the kernel's possibly patched
``coursekit`` -- inside the grading kernel for the summative grader, where :func:`harvest`
fetches the grader's calls one at a time over a socket. It is therefore self-contained
(standard library and numpy only) and produces only raw observations, never verdicts: each
call's converted result and every argument as it was after the call.

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

import copy
import io
import json
import math
import os
import select
import signal
import sys
import threading
import time

import numpy as np

MAX_PRINTED = 1500
MAX_ERROR = 600
_INT_TYPES = tuple({np.dtype(c).type for c in "bBhHiIlLqQ"})


class BadOutput(Exception):
    """The function returned something that is not the plain data the check asks for."""


def _library_attr(path):
    """``"coursekit.pictures.genome:Genome"`` -> that attribute; only coursekit's own modules."""
    import importlib

    module, _, attr = path.partition(":")
    if not (module == "coursekit" or module.startswith("coursekit.")) or not attr:
        raise ValueError(f"cases may only name coursekit attributes, got {path!r}")
    obj = importlib.import_module(module)
    for part in attr.split("."):
        obj = getattr(obj, part)
    return obj


def decode(value, seed):
    """Turn one encoded argument into the Python object passed to the student function.

    Encodings: ``{"rng": true}`` (a generator seeded with ``seed``), ``{"ndarray": ..., "dtype":
    ...}``, ``{"object": "module:Class", "json": text}`` (``Class.from_json(text)``, for genomes
    and creatures), ``{"function": "module:name"}`` (a library function, e.g. an ODE right-hand
    side), or a plain JSON value.
    """
    if isinstance(value, dict):
        if value.get("rng") is True:
            return np.random.default_rng(seed)
        if "ndarray" in value:
            return np.array(value["ndarray"], dtype=np.dtype(value["dtype"]))
        if "object" in value:
            return _library_attr(value["object"]).from_json(value["json"])
        if "function" in value:
            return _library_attr(value["function"])
        raise ValueError(f"unknown encoded argument {sorted(value)}")
    return copy.deepcopy(value)  # a function that edits its list argument must not edit the case


def encode_array(a):
    """Encode a numpy array as plain data (the inverse of :func:`decode`)."""
    return {"ndarray": a.tolist(), "dtype": str(a.dtype)}


_REAL_TYPES = (int, float, bool) + _INT_TYPES + tuple({np.dtype(c).type for c in "efdg?"})


def _array(out, what, max_len):
    if type(out) in (list, tuple):
        # a list or tuple of plain numbers is what an array holds: accepted as one (exact types only,
        # so an object with a rigged __eq__ or __float__ is not read as a number)
        if len(out) > max_len:
            raise BadOutput(f"{what} has {len(out)} values, far more than the {max_len} allowed")
        if not all(type(v) in _REAL_TYPES for v in out):
            bad = next(v for v in out if type(v) not in _REAL_TYPES)
            raise BadOutput(f"{what} is a {type(out).__name__} holding a {type(bad).__name__}; expected numbers: "
                            "return np.array([...]) of floats")
        out = np.array(out, dtype=np.float64 if any(type(v) not in (int, bool) + _INT_TYPES for v in out) else np.int64)
    elif type(out) is not np.ndarray:
        how = "result.detach().cpu().numpy()" if type(out).__module__.startswith("torch") else "np.asarray(result, dtype=float)"
        raise BadOutput(f"{what} has type {type(out).__name__}; expected a numpy array (np.ndarray): convert it with {how}")
    if out.ndim != 1:
        fix = " (flatten it with result.ravel())" if out.size <= max_len and out.ndim > 1 else ""
        raise BadOutput(f"{what} has shape {out.shape}; expected a 1-D array{fix}")
    if out.dtype.kind not in "biuf":
        raise BadOutput(f"{what} has dtype {out.dtype}; expected numbers (bool, int or float): convert it with "
                        "result.astype(float)")
    if out.size > max_len:
        raise BadOutput(f"{what} has {out.size} values, far more than the {max_len} allowed")
    if out.dtype.kind == "b":
        out = out.astype(np.int64)
    values = out.tolist()
    if out.dtype.kind == "f" and not all(math.isfinite(v) for v in values):
        raise BadOutput(f"{what} contains NaN or infinity")
    return values


def _json_text(out, what, max_len):
    """An object with ``to_json()`` (a genome, a creature) or a plain JSON value, as JSON text."""
    if hasattr(type(out), "to_json"):
        text = out.to_json()
        if type(text) is not str:
            raise BadOutput(f"{what}.to_json() returned {type(text).__name__}; expected str")
    else:
        try:
            text = json.dumps(out, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise BadOutput(f"{what} has type {type(out).__name__}, which is not plain data ({exc})") from None
    if len(text) > max_len:
        raise BadOutput(f"{what} is {len(text)} characters of JSON, far more than the {max_len} allowed")
    try:
        json.loads(text)
    except ValueError:
        raise BadOutput(f"{what} did not serialise to valid JSON") from None
    return text


def convert(kind, out, max_len):
    """Convert one call's result to plain data with strict type checks, or raise :class:`BadOutput`.

    Args:
        kind: ``"indices"`` (1-D integer array or list/tuple of ints), ``"array"`` (1-D numpy
            array of numbers, or a list/tuple of plain numbers), ``"array_pair"`` (a tuple or list of two such arrays), ``"json"``
            (an object with ``to_json()`` or plain JSON data) or ``"json_pair"`` (two of those).
        out: the function's return value.
        max_len: largest number of values accepted (characters of JSON text for the json kinds).
    Returns:
        a list of ints / floats, or a list of two such lists; JSON text, or a list of two.
    """
    if kind == "indices":
        if type(out) is np.ndarray:
            if out.ndim != 1 or out.dtype.kind not in "iu":
                raise BadOutput(f"returned an array of shape {out.shape} and dtype {out.dtype}; expected a 1-D array of integer indices")
            if out.size > max_len:
                raise BadOutput(f"returned {out.size} indices, far more than the {max_len} allowed")
            return [int(v) for v in out.tolist()]
        if type(out) in (list, tuple):
            if len(out) > max_len:
                raise BadOutput(f"returned {len(out)} indices, far more than the {max_len} allowed")
            values = []
            for i, v in enumerate(out):
                if type(v) is not int and type(v) not in _INT_TYPES:
                    raise BadOutput(f"element {i} of the result has type {type(v).__name__}; indices must be plain integers")
                values.append(int(v))
            return values
        raise BadOutput(f"returned a value of type {type(out).__name__}; expected a sequence of integer indices (list or numpy array)")
    if kind == "array":
        return _array(out, "the result", max_len)
    if kind == "json":
        return _json_text(out, "the result", max_len)
    if kind in ("array_pair", "json_pair"):
        if type(out) not in (tuple, list) or len(out) != 2:
            n = f" of length {len(out)}" if type(out) in (tuple, list) else ""
            raise BadOutput(f"returned a {type(out).__name__}{n}; expected a pair (child1, child2)")
        one = _array if kind == "array_pair" else _json_text
        return [one(out[0], "child 1", max_len), one(out[1], "child 2", max_len)]
    raise ValueError(f"unknown output kind {kind!r}")


def _describe_error(exc):
    text = f"{type(exc).__name__}: {exc}"
    return text if len(text) <= MAX_ERROR else text[: MAX_ERROR - 3] + "..."


def _after(arg, encoded, max_len):
    """An argument as it is after the call, to show whether the function modified it."""
    if type(arg) is np.ndarray:
        return encode_array(arg)
    if isinstance(encoded, dict) and "object" in encoded:
        return {"json": _json_text(arg, "the argument", max_len)}
    return None


class _Refusing:
    """While active, coursekit's own versions of a graded function raise instead of running.

    Each ``"module:attr"`` of ``paths`` (a library function or method) gets the code of a stub
    that raises ``RuntimeError``, so every reference to it -- an import under another name, a
    wrapper that calls it, the library calling it internally -- refuses while the student's
    function runs; the code is put back on exit. Arguments are decoded and results converted
    outside, so the library itself stays usable there.
    """

    def __init__(self, paths, function):
        self.saved = []
        for path in paths:
            try:
                obj = _library_attr(path)
            except (ImportError, AttributeError, ValueError):
                continue
            obj = getattr(obj, "__func__", obj)
            if not hasattr(obj, "__code__") or obj.__code__.co_freevars:
                continue
            name = path.partition(":")[2]
            msg = (f"coursekit's own {name} is not available while your {function} is graded: "
                   f"{function} must do the work itself (the rest of the library may be used)")
            ns = {}
            exec(compile(f"def stub(*args, **kwargs):\n    raise RuntimeError({msg!r})", "<coursekit-refused>", "exec"), ns)
            self.saved.append((obj, obj.__code__, ns["stub"].__code__))

    def __enter__(self):
        for obj, _, stub in self.saved:
            obj.__code__ = stub
        return self

    def __exit__(self, *exc):
        for obj, code, _ in self.saved:
            obj.__code__ = code
        return False


def calls_of(cases):
    """The calls of ``cases`` in order: one self-contained plain dict per seed.

    A call is ``{"id", "args", "kwargs", "seed", "max_len"}``; its id is ``"<case id>#<index>"``
    here (the summative grader replaces it by a random token, so a call says nothing about its case).
    """
    return [{"id": f"{c['id']}#{i}", "args": c["args"], "kwargs": c.get("kwargs", {}), "seed": s, "max_len": c["max_len"]}
            for c in cases for i, s in enumerate(c["seeds"])]


def run_call(fn, call, kind, guard=None, capture=True):
    """Call ``fn`` once on ``call`` in this process; return the plain record of that call.

    The record carries ``id``, ``status``, ``output`` (when ok), ``error`` otherwise, and
    ``inputs_after``: every argument as it is after the call (None for those that are not arrays
    or library objects), so whoever judges can see whether the call modified its inputs. With
    ``capture``, what the function prints is recorded (``printed``) instead of shown (only safe
    where nothing else runs meanwhile: in a forked worker). ``guard`` is a :class:`_Refusing`.
    """
    record = {"id": call["id"]}
    captured = io.StringIO()
    old = sys.stdout, sys.stderr
    if capture:
        sys.stdout = sys.stderr = captured
    try:
        args = [decode(a, call["seed"]) for a in call["args"]]
        kwargs = {k: decode(v, call["seed"]) for k, v in call.get("kwargs", {}).items()}
        try:
            if guard is None:
                out = fn(*args, **kwargs)
            else:
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


def changed(after, encoded) -> bool:
    """Did a call change one argument? ``encoded``: the argument as sent; ``after``: its entry of ``inputs_after``."""
    if after is None:
        return False
    if "json" in after:
        return not (isinstance(encoded, dict) and "json" in encoded) or json.loads(after["json"]) != json.loads(encoded["json"])
    return after != encoded


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
    except (ImportError, OSError, ValueError):
        pass  # no /proc or no RLIMIT_AS (macOS): the outer limits still apply


def _write_all(fd, data):
    while data:
        data = data[os.write(fd, data):]


def _serve_calls(fn, kind, rfd, wfd, memory_mb, refuse):
    """Body of a forked worker: read call lines from ``rfd``, write ``R <record>`` lines to ``wfd``; never return."""
    try:
        sys.stdin = io.StringIO()
        _limit_memory(memory_mb)
        guard = _Refusing(refuse, getattr(fn, "__name__", "function")) if refuse else None
        with os.fdopen(rfd, "rb") as calls:
            for line in calls:
                call = json.loads(line)
                record = run_call(fn, call, kind, guard)
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

    def __init__(self, fn, kind, memory_mb, refuse):
        crfd, cwfd = os.pipe()  # calls: parent -> worker
        rrfd, rwfd = os.pipe()  # records: worker -> parent
        self.pid = os.fork()
        if self.pid == 0:
            os.close(cwfd)
            os.close(rrfd)
            _serve_calls(fn, kind, crfd, rwfd, memory_mb, refuse)
        os.close(crfd)
        os.close(rwfd)
        self.calls, self.records, self.buf = cwfd, rrfd, b""

    def call(self, call, timeout):
        """The worker's record of ``call``; ``None`` after ``timeout`` s (the worker is then killed), or
        ``("died", status)`` when it stopped."""
        try:
            _write_all(self.calls, json.dumps(call).encode() + b"\n")
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
        for fd in (self.calls, self.records):
            try:
                os.close(fd)
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
        refuse: ``"module:attr"`` names of coursekit's own versions of the function (see :class:`_Refusing`).
    """

    def __init__(self, fn, kind, *, timeout=10.0, memory_mb=2048, budget=None, refuse=()):
        self.fn, self.kind, self.timeout, self.memory_mb, self.refuse = fn, kind, float(timeout), memory_mb, tuple(refuse)
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

    def call(self, call):
        """The plain record of one call (see :func:`run_call`)."""
        left = self.end - time.monotonic()
        over = {"id": call["id"], "status": "timeout", "error": f"the time budget of {self.budget:g} s for all calls ran out"}
        if left <= 0:
            return over
        if not self.fork:
            box = []
            t = threading.Thread(target=lambda: box.append(run_call(self.fn, call, self.kind, self._guard(), capture=False)),
                                 daemon=True)
            t.start()
            t.join(min(self.timeout, left))
            return box[0] if box else (over if time.monotonic() >= self.end else
                                       {"id": call["id"], "status": "timeout", "error": f"a call did not return within {self.timeout:g} s"})
        if self.worker is None:
            import warnings

            with warnings.catch_warnings():
                warnings.simplefilter("ignore", DeprecationWarning)  # "multi-threaded, fork() may deadlock"
                self.worker = _Worker(self.fn, self.kind, self.memory_mb, self.refuse)
        rec = self.worker.call(call, min(self.timeout, left))
        if rec is None:
            self.worker = None
            return over if time.monotonic() >= self.end else \
                {"id": call["id"], "status": "timeout", "error": f"a call did not return within {self.timeout:g} s"}
        if type(rec) is tuple:
            self.worker = None
            return {"id": call["id"], "status": "died", "error": _died_message(rec[1])}
        return rec

    def _guard(self):
        return _Refusing(self.refuse, getattr(self.fn, "__name__", "function")) if self.refuse else None


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
            while it runs (see :class:`_Refusing`).
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


MAX_MESSAGE = 64 * 2**20  # the longest line the harvest reads (a call with two large creatures)


def harvest(namespace, address, token, cells=None):
    """Summative side: answer the grader's calls of one check, one call at a time.

    Connects to the grading child's socket ``address``, proves itself with ``token`` (which only
    this harvest cell knows), and receives the check's header ``{"name", "function", "output",
    "timeout", "memory_mb", "budget", "refuse"}``; then, until ``{"end": true}``, one call at a
    time: ``{"call": {...}}`` answered by its plain record (:func:`run_call`). The cases are never
    all in the kernel: each call arrives only after the previous one's record went back. With
    ``cells`` (the file names the kernel compiled the notebook's cells under), a function whose
    code comes from anywhere else -- ``from coursekit.ga import tournament``, a module on disk --
    is refused as not attempted; ``refuse`` lists coursekit's own versions of the function, which
    raise while it is graded (:class:`_Refusing`).
    """
    import socket

    sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    sock.connect(address)
    stream = sock.makefile("rwb")

    def send(obj):
        stream.write(json.dumps(obj, allow_nan=False).encode() + b"\n")
        stream.flush()

    def receive():
        line = stream.readline(MAX_MESSAGE)
        return json.loads(line) if line.endswith(b"\n") else None

    try:
        send({"token": token})
        check = receive()
        fn = namespace.get(check["function"])
        why = None
        if not callable(fn):
            why = "is not defined" if fn is None else f"is a {type(fn).__name__}, not a function"
        elif cells is not None:
            why = _foreign(fn, cells)
        with Calls(fn, check["output"], timeout=check["timeout"], memory_mb=check["memory_mb"], budget=check["budget"],
                   refuse=tuple(check.get("refuse", ()))) as calls:
            while True:
                msg = receive()
                if type(msg) is not dict or "call" not in msg:
                    break
                call = msg["call"]
                rec = {"id": call["id"], "status": "missing", "error": f"{check['function']} {why}"} if why else calls.call(call)
                rec.pop("printed", None)
                send(rec)
    finally:
        stream.close()
        sock.close()
