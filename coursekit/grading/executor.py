"""The grading child: execute a student notebook in a fresh kernel, then serve it the grader's calls.

Seed paper section 4 (students' operators, graded). Started by :mod:`coursekit.grading.grader`
as ``python -m coursekit.grading.executor`` in its own session, in the sandbox and, when the
grader runs as root, as an unprivileged user. It never imports student code itself: it drives an
IPython kernel through nbclient.

0. Make itself undumpable (the kernel, same user, cannot read its memory or open its file
   descriptors), read the grading plan (the calls) and delete the plan's file -- all before any
   notebook code runs.
1. Execute the notebook's code cells (outputs discarded) with a per-cell timeout and
   ``allow_errors``. A cell that kills the kernel (``os._exit``, a crash) or does not finish in
   time is skipped and the notebook re-run from the top in a fresh kernel, so the rest of the
   work still counts.
2. For each check, send one *harvest cell*: the sources of :data:`SHIPPED` (values, lockdown,
   runner) executed in a fresh namespace (not the kernel's possibly patched ``coursekit``), which
   connects to a :class:`Relay` on a Unix socket with a token only that cell holds, then gets
   the check's calls one at a time, each sent after the previous one's record came back.
   Each call's array arguments go in fresh ``memfd`` shared memory (:func:`share_arrays`); after
   its record came back this process reads them back itself (:func:`observe_arrays`): a change
   counts whatever the kernel reports.
3. Pass each record, tagged with its check, to the grader on the results pipe, then the
   execution report (which cells failed or were skipped and why, whether the harvest completed).

Nothing the kernel prints is read, and nothing the grader reads is a file: the records and the
report go down a pipe the kernel never holds. Verdicts and points are computed by the grader
from its own copy of the cases.
"""

from __future__ import annotations

import argparse
import hmac
import json
import os
import re
import secrets
import socket
import sys
import threading
from pathlib import Path

REPORT_FORMAT = "coursekit.execution/1"
MAX_RESTARTS = 6
MAX_RECORD = 64 * 2**20  # the longest record line accepted from the kernel

_HARVEST = """def _coursekit_harvest():
    ns = {{"__name__": "coursekit_harvest"}}
    exec(compile({values!r}, "<coursekit-values>", "exec"), ns)
    exec(compile({lockdown!r}, "<coursekit-lockdown>", "exec"), ns)
    exec(compile({source!r}, "<coursekit-harvest>", "exec"), ns)
    from IPython import get_ipython  # not the notebook's global of that name, which it may have replaced
    ip = get_ipython()
    ns["harvest"](ip.user_ns, {address!r}, {token!r}, set(getattr(ip.compile, "_filename_map", None) or ()) or None)
try:
    _coursekit_harvest()
finally:
    del _coursekit_harvest
"""


#: Tasks allowed inside the sandbox beyond ``--max-processes``: ``RLIMIT_NPROC`` counts threads
#: too, and the kernel, numpy's BLAS and torch start pools of about one thread per core.
THREAD_ROOM = 8 * (os.cpu_count() or 1) + 64

#: The modules the harvest cell ships as text, in order, into one fresh namespace.
SHIPPED = ("values.py", "lockdown.py", "runner.py")


def harvest_cell(sources: tuple, address: str, token: str) -> str:
    """The code of one harvest cell: the sources of :data:`SHIPPED` shipped as text, and where to
    fetch the calls."""
    values, lockdown, runner = sources
    return _HARVEST.format(values=values, lockdown=lockdown, source=runner, address=address, token=token)


#: Array arguments travel in shared memory (Linux: ``memfd_create`` and descriptor passing).
SHARED_MEMORY = sys.platform.startswith("linux") and hasattr(os, "memfd_create") and hasattr(socket, "send_fds")


def share_arrays(call):
    """``(call as sent to the kernel, [fds], [(argument index, fd, bytes sent)])``: each non-empty
    array argument is written to a fresh ``memfd`` and replaced by ``{"shared": k, ...}``."""
    from coursekit.grading.values import share

    if not SHARED_MEMORY:
        return call, [], []
    args, fds, watched = [], [], []
    for i, a in enumerate(call["args"]):
        got = share(a)
        if got is None:
            args.append(a)
            continue
        data, shape = got
        fd = os.memfd_create("coursekit-argument", os.MFD_CLOEXEC)
        view = memoryview(data)
        while view:
            view = view[os.write(fd, view):]
        args.append({"shared": len(fds), "dtype": a["dtype"], "shape": shape, "nbytes": len(data)})
        fds.append(fd)
        watched.append((i, fd, data))
    return {**call, "args": args}, fds, watched


def observe_arrays(rec, call, watched) -> None:
    """Read each shared argument back after the call and close it; where the bytes changed, the
    record's ``inputs_after`` gets what the memory holds now, whatever the kernel reported."""
    import numpy as np

    from coursekit.grading.values import unshare

    for i, fd, data in watched:
        try:
            now = os.pread(fd, len(data), 0)
        finally:
            os.close(fd)
        after = rec.get("inputs_after")
        if now != data and rec.get("status") == "ok" and type(after) is list and i < len(after):
            size = np.dtype(call["args"][i]["dtype"]).itemsize
            after[i] = unshare(now[:len(now) - len(now) % size], call["args"][i])


#: A cell's error as the results show it: at most this many characters, cut between words.
ERROR_CHARS = 180


def _error_name(cell) -> str | None:
    """``"Name: message"`` of a cell's error, short: a withheld function's long message as the
    function's name, anything else cut between words."""
    for out in cell.get("outputs", []):
        if out.get("output_type") == "error":
            value = str(out.get("evalue", ""))
            held = re.search(r"coursekit's own (\S+) is withheld while this notebook is graded", value)
            if held:
                return f"uses coursekit's own {held[1]}, withheld while grading (this costs nothing)"
            text = f"{out.get('ename', '?')}: {value}"
            if len(text) <= ERROR_CHARS:
                return text
            cut = text.rfind(" ", 0, ERROR_CHARS - 1)
            return text[:cut if cut > 0 else ERROR_CHARS - 1] + "…"
    return None


def _make_undumpable() -> None:
    """Linux: no process of this user may read this one's memory or open its file descriptors
    (``/proc/<pid>/mem``, ``/proc/<pid>/fd``) or ptrace it: the kernel runs as the same user."""
    try:
        import ctypes

        ctypes.CDLL(None, use_errno=True).prctl(4, 0, 0, 0, 0)  # PR_SET_DUMPABLE, 0
    except (OSError, AttributeError):
        pass


class Results:
    """The one-way channel to the grader: JSON lines on an inherited pipe no other process holds."""

    def __init__(self, fd: int):
        os.set_inheritable(fd, False)  # the kernel and its children never get it
        self.fd = fd
        self.lock = threading.Lock()

    def send(self, obj) -> None:
        data = json.dumps(obj, allow_nan=False).encode() + b"\n"
        with self.lock:
            while data:
                data = data[os.write(self.fd, data):]


class Relay(threading.Thread):
    """Serve one check's calls to the harvest cell, one at a time, and pass its records to the grader.

    Listens on a Unix socket in the box; the first connection that presents ``token`` is served
    (others are dropped: a thread the notebook left behind does not know the token before the
    harvest cell runs). After a case's first failing call its other calls are not sent.
    """

    def __init__(self, path: str, token: str, header: dict, calls: list, results: Results, timeout: float):
        super().__init__(daemon=True)
        self.path, self.token, self.header, self.calls, self.results = path, token, header, calls, results
        self.timeout = timeout
        self.sent = 0
        self.served = False
        self.problem = None
        self.stop = threading.Event()
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(path)
        if not path.startswith("\0"):
            os.chmod(path, 0o600)
        self.listener.listen(4)
        self.listener.settimeout(0.2)

    def run(self):
        try:
            while not self.stop.is_set() and not self.served:
                try:
                    conn, _ = self.listener.accept()
                except socket.timeout:
                    continue
                except OSError:
                    return
                with conn:
                    conn.settimeout(self.timeout)
                    stream = conn.makefile("rwb")
                    try:
                        hello = json.loads(stream.readline(200) or b"null")
                    except (ValueError, OSError):
                        continue
                    if type(hello) is not dict or not hmac.compare_digest(str(hello.get("token", "")), self.token):
                        continue
                    self.served = True
                    self._serve(conn, stream)
        finally:
            self.listener.close()

    def _serve(self, conn, stream):
        def send(obj):
            stream.write(json.dumps(obj).encode() + b"\n")
            stream.flush()

        from coursekit.grading.channel import reject_constant
        from coursekit.grading.runner import send_line

        failed = set()
        try:
            send(self.header)
            for call in self.calls:
                if call["group"] in failed:
                    continue
                sent, fds, watched = share_arrays({k: v for k, v in call.items() if k != "group"})
                rec = None
                try:  # the kernel gets its own copies of the fds; these are kept to read the memory back
                    send_line(conn, json.dumps({"call": sent}).encode() + b"\n", fds)
                    line = stream.readline(MAX_RECORD)
                    try:
                        rec = json.loads(line, parse_constant=reject_constant) if line.endswith(b"\n") else None
                    except (ValueError, RecursionError):
                        pass
                finally:
                    ok = type(rec) is dict and rec.get("id") == call["id"]
                    observe_arrays(rec if ok else {}, call, watched)
                if not ok:
                    self.problem = "the harvest answered out of turn (a record for another call, or not a record)"
                    return
                self.sent += 1
                self.results.send({"check": self.header["name"], **rec})
                if rec.get("status") != "ok":
                    failed.add(call["group"])
            send({"end": True})
        except (OSError, socket.timeout) as exc:
            self.problem = f"the harvest's connection broke ({type(exc).__name__})"
        except Exception as exc:  # noqa: BLE001 -- a record the grader cannot pass on: the harvest is broken, not a call
            self.problem = f"the harvest sent a record the grader cannot pass on ({type(exc).__name__})"


def execute(nb, plan: dict, results: Results, cwd: str, cell_timeout: float) -> dict:
    """Run the notebook then the harvest cells; return the execution report (plain data)."""
    import nbformat
    from nbclient import NotebookClient
    from nbclient.exceptions import CellTimeoutError, DeadKernelError

    sources = tuple(Path(__file__).with_name(name).read_text(encoding="utf-8") for name in SHIPPED)
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    skip: dict[int, str] = {}
    budget = 4 * plan["timeout"] + 30
    harvest_timeout = budget + 60  # the runner stops each check after its budget
    harvested = False
    harvest_problem = None
    cells: dict[int, str] = {}
    sockets = Path(cwd).parent
    for _attempt in range(MAX_RESTARTS + 1):
        run = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(nb.cells[i].source) for i in code])
        client = NotebookClient(run, timeout=cell_timeout, allow_errors=True, interrupt_on_timeout=False,
                                kernel_name="python3", resources={"metadata": {"path": cwd}}, record_timing=False,
                                shutdown_kernel="immediate")
        current = None
        try:
            with client.setup_kernel():
                cells = {}
                for j, i in enumerate(code):
                    if i in skip:
                        continue
                    current = i
                    client.execute_cell(run.cells[j], j)
                    err = _error_name(run.cells[j])
                    cells[i] = f"error: {err}" if err else "ok"
                current = None
                for check in plan["checks"]:
                    token = secrets.token_hex(16)
                    header = {k: check[k] for k in ("name", "function", "output", "refuse", "native")}
                    header.update(timeout=plan["timeout"], memory_mb=plan["memory_mb"], budget=budget)
                    # Linux: an abstract socket (no file, no path-length limit; the sandbox has its own
                    # network namespace, and the token admits only the harvest cell)
                    path = (f"\0coursekit-harvest-{secrets.token_hex(8)}" if sys.platform.startswith("linux")
                            else str(sockets / f"h-{secrets.token_hex(6)}.sock"))
                    relay = Relay(path, token, header, check["calls"], results, harvest_timeout)
                    relay.start()
                    run.cells.append(nbformat.v4.new_code_cell(harvest_cell(sources, path, token)))
                    client.timeout = harvest_timeout
                    try:
                        try:
                            client.execute_cell(run.cells[-1], len(run.cells) - 1)
                        finally:
                            relay.stop.set()
                            relay.join(10)
                            if not path.startswith("\0"):
                                Path(path).unlink(missing_ok=True)
                        err = _error_name(run.cells[-1])
                        if err and harvest_problem is None:  # the harvest itself failed in the kernel
                            harvest_problem = f"calling {check['function']} failed inside the kernel ({err})"
                        elif relay.problem and harvest_problem is None:
                            harvest_problem = f"calling {check['function']}: {relay.problem}"
                        elif not relay.served and harvest_problem is None:
                            harvest_problem = f"calling {check['function']}: the harvest never asked for the calls"
                    except CellTimeoutError:  # the kernel is wedged: remaining checks get no output
                        harvest_problem = f"calling {check['function']} did not finish within {harvest_timeout:g} s"
                        break
                harvested = True
        except CellTimeoutError:
            if current is None:
                break
            skip[current] = f"did not finish within {cell_timeout:g} s"
            continue
        except DeadKernelError:
            if current is None:  # died during harvesting: what reached the grader counts
                harvest_problem = "the kernel stopped while the graded functions were being called"
                break
            skip[current] = "stopped the kernel (os._exit, a crash or out of memory)"
            continue
        break
    cells.update({i: f"skipped: {why}" for i, why in skip.items()})
    return {"format": REPORT_FORMAT, "harvested": harvested, "harvest_problem": harvest_problem,
            "cells": [{"index": i, "status": cells.get(i, "not run")} for i in code]}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m coursekit.grading.executor")
    p.add_argument("--notebook", required=True)
    p.add_argument("--calls", required=True, help="the grading plan; read and deleted before the notebook runs")
    p.add_argument("--results-fd", type=int, required=True, help="pipe to the grader (records, then the report)")
    p.add_argument("--cwd", required=True)
    p.add_argument("--cell-timeout", type=float, required=True)
    p.add_argument("--max-processes", type=int, default=None, help="RLIMIT_NPROC inside the sandbox (see sandbox.limit_processes)")
    a = p.parse_args(argv)
    _make_undumpable()
    if a.max_processes:
        from coursekit.grading.sandbox import limit_processes

        why = limit_processes(a.max_processes + THREAD_ROOM)
        print(f"process limit {'set' if why is None else 'not set: ' + why}", file=sys.stderr)
    results = Results(a.results_fd)
    with open(a.calls, encoding="utf-8") as f:
        plan = json.load(f)
    os.unlink(a.calls)  # the cases exist only in this process's memory now, out of the notebook's reach
    import nbformat

    try:
        nb = nbformat.read(a.notebook, as_version=4)
    except Exception as exc:  # not a notebook: report it, grade as nothing submitted
        report = {"format": REPORT_FORMAT, "harvested": False, "cells": [],
                  "error": f"could not read the notebook: {type(exc).__name__}: {str(exc)[:300]}"}
    else:
        try:
            report = execute(nb, plan, results, a.cwd, a.cell_timeout)
        except Exception as exc:  # the kernel could not be started or driven: the grader reports it not graded
            report = {"format": REPORT_FORMAT, "harvested": False, "cells": [],
                      "harvest_problem": f"the grading child failed: {type(exc).__name__}: {str(exc)[:300]}"}
    results.send({"report": report})
    return 0


if __name__ == "__main__":
    sys.exit(main())
