"""Calling student functions on plain-data cases, each call bounded, results turned into plain data.

Part of the exercise machinery behind the seed paper's section 4 (students' own GA operators
drive the real systems, and are checked first). This module is the only grading code that runs
next to student code: in the student's kernel for formative checks, and -- shipped as *source
text* and executed in a fresh namespace, never imported from the kernel's possibly patched
``coursekit`` -- inside the grading kernel for the summative grader. It is therefore
self-contained (standard library and numpy only) and produces only raw observations, never
verdicts.

Isolation: each batch of calls runs in a ``fork()`` of the current process (copy-on-write: it
sees every name the notebook defined), with a cap on the address space it may *add* (``RLIMIT_AS``
set to its size at the fork plus ``memory_mb``, so reservations made before, such as a CUDA
torch's, do not count; the summative grader bounds resident memory from outside), its ``print``
captured, and a watchdog in the calling process that ``SIGKILL``s it when a call does not finish
within ``timeout`` seconds. An infinite loop, ``sys.exit``, ``os._exit``, a segfault or a huge
allocation therefore costs one case, never the kernel, and the next case runs in a fresh fork.
Trade-off: a fork is a real kill (threads cannot be killed) and contains crashes, but forking a
multi-threaded process (the kernel) only keeps the calling thread, so the worker must not touch
the kernel's I/O threads -- it writes to a private pipe and never to the kernel's stdout. Where
``fork`` does not exist (Windows) calls run in a daemon thread: a timeout is reported but the
runaway thread cannot be stopped, and a crash takes the kernel with it. Setting
``COURSEKIT_CHECK_ISOLATION=thread`` chooses threads everywhere (for platforms where forking a
kernel is fragile, e.g. macOS with GUI frameworks loaded).

Case format (plain JSON)::

    {"id": "rate", "args": [{"ndarray": [0, 1, 1], "dtype": "int64"}, {"rng": true}],
     "kwargs": {"rate": 0.25}, "seeds": [11, 12, 13], "check_inputs": true, "max_len": 100}

The function is called once per seed, with ``{"rng": true}`` replaced by
``numpy.random.default_rng(seed)``. A record (one JSON object per case) carries ``status``
(``ok``/``not_implemented``/``error``/``timeout``/``died``/``missing``/``bad_output``),
``outputs`` (one converted result per seed, when ok), the failing ``call`` index and ``error``
text otherwise, ``inputs_after`` (the array arguments after the first call, when asked) and
``printed`` (what the function printed, truncated).
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


def _array(out, what, max_len):
    if type(out) is not np.ndarray:
        raise BadOutput(f"{what} has type {type(out).__name__}; expected a numpy array (np.ndarray)")
    if out.ndim != 1:
        raise BadOutput(f"{what} has shape {out.shape}; expected a 1-D array")
    if out.dtype.kind not in "biuf":
        raise BadOutput(f"{what} has dtype {out.dtype}; expected numbers (bool, int or float)")
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
            array of numbers), ``"array_pair"`` (a tuple or list of two such arrays), ``"json"``
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


def run_case(fn, case, kind, tick=None, capture=True, refuse=()):
    """Call ``fn`` once per seed of ``case`` in this process and return the plain record.

    With ``capture``, what the function prints is recorded instead of shown (only safe where
    nothing else runs meanwhile: in a forked worker). ``refuse`` lists library functions
    (``"module:attr"``) that raise while ``fn`` runs (see :class:`_Refusing`).
    """
    guard = _Refusing(refuse, getattr(fn, "__name__", "function")) if refuse else None
    record = {"case": case["id"]}
    outputs = []
    captured = io.StringIO()
    old = sys.stdout, sys.stderr
    if capture:
        sys.stdout = sys.stderr = captured
    try:
        for i, seed in enumerate(case["seeds"]):
            args = [decode(a, seed) for a in case["args"]]
            kwargs = {k: decode(v, seed) for k, v in case.get("kwargs", {}).items()}
            record["call"] = i
            try:
                if guard is None:
                    out = fn(*args, **kwargs)
                else:
                    with guard:
                        out = fn(*args, **kwargs)
                outputs.append(convert(kind, out, case["max_len"]))
            except NotImplementedError as exc:
                record.update(status="not_implemented", error=_describe_error(exc))
                return record
            except BadOutput as exc:
                record.update(status="bad_output", error=str(exc))
                return record
            except BaseException as exc:  # SystemExit, KeyboardInterrupt and friends included
                record.update(status="error", error=_describe_error(exc))
                return record
            if i == 0 and case.get("check_inputs"):
                record["inputs_after"] = [_after(a, v, case["max_len"]) for a, v in zip(args, case["args"])]
            if tick is not None:
                tick()
        record.pop("call", None)
        record.update(status="ok", outputs=outputs)
        return record
    finally:
        if capture:
            sys.stdout, sys.stderr = old
        printed = captured.getvalue()
        if printed:
            record["printed"] = printed[:MAX_PRINTED]


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


def _worker(fn, cases, kind, wfd, memory_mb, refuse=()):
    """Body of the forked child: run cases, write 'T' ticks and 'R json' records, never return."""
    try:
        sys.stdin = io.StringIO()
        _limit_memory(memory_mb)

        def write(line):
            data = line.encode() + b"\n"
            while data:
                data = data[os.write(wfd, data):]

        for case in cases:
            record = run_case(fn, case, kind, tick=lambda: write("T"), refuse=refuse)
            try:
                text = json.dumps(record, allow_nan=False)
            except (TypeError, ValueError) as exc:
                text = json.dumps({"case": case["id"], "status": "bad_output", "error": f"result is not plain data: {exc}"})
            write("R " + text)
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


def _run_forked(fn, cases, kind, timeout, memory_mb, budget, refuse=()):
    # A notebook that ignores SIGCHLD makes the kernel reap its children itself, and waitpid()
    # on a worker would fail: the default disposition is restored for the calls, then put back.
    old_chld = signal.signal(signal.SIGCHLD, signal.SIG_DFL) if threading.current_thread() is threading.main_thread() else None
    try:
        return _run_forked_calls(fn, cases, kind, timeout, memory_mb, budget, refuse)
    finally:
        if old_chld is not None:
            signal.signal(signal.SIGCHLD, old_chld)


def _run_forked_calls(fn, cases, kind, timeout, memory_mb, budget, refuse):
    records = {}
    todo = list(cases)
    end = time.monotonic() + budget
    while todo and time.monotonic() < end:
        rfd, wfd = os.pipe()
        pid = os.fork()
        if pid == 0:  # child
            os.close(rfd)
            _worker(fn, todo, kind, wfd, memory_mb, refuse)
        os.close(wfd)
        buf = b""
        deadline = time.monotonic() + timeout
        timed_out = False
        with os.fdopen(rfd, "rb", buffering=0) as r:
            while True:
                left = min(deadline, end) - time.monotonic()
                if left <= 0:
                    timed_out = True
                    break
                ready, _, _ = select.select([r], [], [], left)
                if not ready:
                    continue
                chunk = r.read(65536)
                if not chunk:
                    break
                buf += chunk
                *lines, buf = buf.split(b"\n")
                for line in lines:
                    deadline = time.monotonic() + timeout
                    if line.startswith(b"R "):
                        try:
                            rec = json.loads(line[2:])
                        except ValueError:
                            continue
                        if isinstance(rec, dict) and isinstance(rec.get("case"), str) and rec["case"] in {c["id"] for c in todo}:
                            records.setdefault(rec["case"], rec)
        if timed_out:
            os.kill(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        remaining = [c for c in todo if c["id"] not in records]
        if remaining:
            current = remaining[0]
            if timed_out:
                why = (f"the time budget of {budget:g} s for all calls ran out" if time.monotonic() >= end
                       else f"a call did not return within {timeout:g} s")
                records[current["id"]] = {"case": current["id"], "status": "timeout", "error": why}
            else:
                records[current["id"]] = {"case": current["id"], "status": "died", "error": _died_message(status)}
            remaining = remaining[1:]
        todo = remaining
    for c in todo:
        records[c["id"]] = {"case": c["id"], "status": "timeout", "error": f"the time budget of {budget:g} s for all calls ran out"}
    return [records[c["id"]] for c in cases]


def _run_threaded(fn, cases, kind, timeout, refuse=()):
    out = []
    for case in cases:
        box = []
        t = threading.Thread(target=lambda: box.append(run_case(fn, case, kind, capture=False, refuse=refuse)), daemon=True)
        t.start()
        t.join(timeout * max(1, len(case["seeds"])))
        out.append(box[0] if box else {"case": case["id"], "status": "timeout",
                                        "error": f"the calls did not return within {timeout:g} s each"})
    return out


def run_cases(fn, cases, kind, *, timeout=10.0, memory_mb=2048, budget=None, refuse=()):
    """Run ``fn`` on every case, isolated and bounded; return one plain record per case.

    Args:
        fn: the student's function.
        cases: list of case dicts (see module docstring).
        kind: output conversion kind (see :func:`convert`).
        timeout: seconds allowed per call.
        memory_mb: extra address space the worker may allocate.
        budget: seconds for all cases together (default ``4 * timeout + 30``); cases not reached
            in time are reported as timeouts.
        refuse: ``"module:attr"`` names of coursekit's own versions of the function, which raise
            while it runs (summative grading; see :class:`_Refusing`).
    Returns:
        list of record dicts, in case order.
    """
    if hasattr(os, "fork") and os.environ.get("COURSEKIT_CHECK_ISOLATION", "fork") != "thread":
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # "multi-threaded, fork() may deadlock"
            return _run_forked(fn, cases, kind, timeout, memory_mb, 4 * timeout + 30 if budget is None else budget, refuse)
    return _run_threaded(fn, cases, kind, timeout, refuse)


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


def harvest(namespace, spec, channel, cells=None):
    """Summative side: run every check of ``spec`` on the function the notebook defined.

    Appends one JSON line per case record, tagged with its check name, to the file ``channel``.
    ``spec`` is ``{"timeout": s, "memory_mb": m, "checks": [{"name", "function", "output", "cases",
    "refuse"}]}``. With ``cells`` (the file names the kernel compiled the notebook's cells under),
    a function whose code comes from anywhere else -- ``from coursekit.ga import tournament``, a
    module on disk -- is refused as not attempted; ``refuse`` lists coursekit's own versions of
    the function, which raise while it is graded (:class:`_Refusing`).
    """
    for check in spec["checks"]:
        fn = namespace.get(check["function"])
        why = None
        if not callable(fn):
            why = "is not defined" if fn is None else f"is a {type(fn).__name__}, not a function"
        elif cells is not None:
            why = _foreign(fn, cells)
        if why:
            records = [{"case": c["id"], "status": "missing", "error": f"{check['function']} {why}"} for c in check["cases"]]
        else:
            records = run_cases(fn, check["cases"], check["output"], timeout=spec["timeout"], memory_mb=spec["memory_mb"],
                                refuse=tuple(check.get("refuse", ())))
        with open(channel, "a", encoding="utf-8") as f:
            for rec in records:
                rec.pop("printed", None)
                f.write(json.dumps({"check": check["name"], **rec}, allow_nan=False) + "\n")
