"""The grading child's sandbox: bubblewrap (``bwrap``), the sandbox Flatpak uses.

Part of the summative grader (seed paper section 4, exercises graded; see
:mod:`coursekit.grading.grader`). The executor and the notebook's kernel run inside a
``bwrap`` sandbox with

- the whole file system bound **read-only** (the installed package, the grader's files, the
  results file: nothing can be rewritten), only the notebook's private box writable;
- ``solutions/`` next to the package hidden under an empty tmpfs, and the other submissions of
  the batch and the results file masked by ``/dev/null``;
- a private ``/tmp`` (a tmpfs of at most :data:`TMP_BYTES` that disappears with the sandbox), private PID, IPC, UTS and
  cgroup namespaces (the grader's processes and their ``/proc/<pid>/environ`` are not there),
  no network (a fresh network namespace with loopback only), every capability dropped, and
  ``--die-with-parent``.

The number of processes is bounded inside, where it holds for a grader who is not root:
:func:`limit_processes` (called by the grading child first thing) sets ``RLIMIT_NPROC`` when the
sandbox has a user namespace of its own (bubblewrap makes one for a grader that is not root).
Since Linux 5.14 that limit counts the processes of the user *in that namespace*, i.e. of this
notebook only, so a fork bomb gets ``EAGAIN`` at the limit instead of filling the instructor's
process table between two polls of :class:`~coursekit.grading.supervisor.Watch` (threads count
too, so the child leaves room for thread pools: ``executor.THREAD_ROOM``). Where it cannot
hold -- real root (exempt from ``RLIMIT_NPROC``), older kernels (which count every process of
the user, the instructor's too) -- :func:`limit_processes` sets nothing and says so; the
grader's user ``nobody`` (when grading as root) and the polling still bound it.

Memory and time are bounded from outside by :mod:`coursekit.grading.supervisor`. Where the
sandbox cannot be set up (no ``bwrap``, or namespaces not permitted), :func:`available` says
why, and ``coursekit grade`` refuses to grade unless the instructor passes ``--unsafe``.

Measured in this project's CI container (Debian 12, root): ``bwrap`` 0.8.0 from the Debian
package works as root and as ``nobody``; starting the sandbox adds well under a second to a
notebook's grading.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

_PROBE: dict = {}
#: Size of the sandbox's private /tmp (a tmpfs: memory the notebook's processes do not hold).
TMP_BYTES = 512 * 2**20


def command(box: Path | None, *, hide_dirs=(), hide_files=()) -> list[str]:
    """The ``bwrap`` argument list that runs a command in the sandbox (append the command).

    Args:
        box: the notebook's private folder, the only writable place (bound at the same path;
            None binds nothing writable, for a probe).
        hide_dirs: folders replaced by an empty tmpfs (``solutions/``).
        hide_files: files replaced by ``/dev/null`` (other submissions, the results file).
    """
    args = ["bwrap", "--die-with-parent", "--unshare-all", "--cap-drop", "ALL", "--new-session",
            "--ro-bind", "/", "/", "--dev", "/dev", "--proc", "/proc", "--size", str(TMP_BYTES), "--tmpfs", "/tmp"]
    for d in _needed_under_tmp():  # a Python, a virtual environment or a checkout under /tmp stays visible
        args += ["--ro-bind", d, d]
    for d in hide_dirs:
        if Path(d).is_dir():
            args += ["--tmpfs", str(d)]
    for f in hide_files:
        if Path(f).is_file():
            args += ["--ro-bind", "/dev/null", str(f)]
    if box is None:
        return args + ["--chdir", "/"]
    return args + ["--bind", str(box), str(box), "--chdir", str(box / "work")]


def _needed_under_tmp() -> list[str]:
    """The folders this Python runs from that the private ``/tmp`` would hide: its prefixes and
    import path (a CI checkout with its virtual environment under ``/tmp``, say), outermost first."""
    tmp = Path("/tmp").resolve()
    found = set()
    for p in [sys.prefix, sys.base_prefix, sys.exec_prefix, *sys.path]:
        try:
            path = Path(p).resolve()
        except (OSError, RuntimeError):
            continue
        if path != tmp and tmp in path.parents and path.is_dir():
            found.add(path)
    outer = [p for p in found if not any(q in p.parents for q in found)]
    return sorted(str(p) for p in outer)


def available(ids=None) -> str | None:
    """None when the sandbox starts this Python (as ``ids`` = (uid, gid), or this user); else why not."""
    key = ids or ()
    if key not in _PROBE:
        if os.name != "posix" or shutil.which("bwrap") is None:
            _PROBE[key] = "bubblewrap (bwrap) is not installed (Debian/Ubuntu: apt-get install bubblewrap)"
        else:
            cmd = command(None) + [sys.executable, "-c", "import nbclient, numpy"]
            try:
                run = subprocess.run(cmd, capture_output=True, timeout=120, stdin=subprocess.DEVNULL,
                                     user=ids[0] if ids else None, group=ids[1] if ids else None,
                                     extra_groups=[] if ids else None)
                _PROBE[key] = None if run.returncode == 0 else \
                    f"bwrap could not start a sandbox here: {run.stderr.decode(errors='replace').strip()[:300] or run.returncode}"
            except (OSError, subprocess.SubprocessError) as exc:
                _PROBE[key] = f"bwrap could not start a sandbox here: {exc}"
    return _PROBE[key]


def _own_user_namespace() -> bool:
    """Is this process in a user namespace of its own (not the initial one, whose map is all ids)?"""
    try:
        with open("/proc/self/uid_map") as f:
            return f.read().split() != ["0", "0", "4294967295"]
    except OSError:
        return False


def _counts_per_namespace() -> bool:
    """Does ``RLIMIT_NPROC`` count per user namespace here (Linux 5.14 and later)?"""
    try:
        major, minor = (int(x) for x in os.uname().release.split(".")[:2])
    except ValueError:
        return False
    return (major, minor) >= (5, 14)


def limit_processes(extra: int) -> str | None:
    """Inside the sandbox: let this user run at most ``extra`` processes (threads count too) more
    than the sandbox holds now, through ``RLIMIT_NPROC``. Returns None when the limit holds, else
    why it was not set (see the module docstring)."""
    import resource

    if os.getuid() == 0:  # bubblewrap maps root to root: still the real root, whom RLIMIT_NPROC does not bind
        return "running as root, whom RLIMIT_NPROC does not bind"
    if not _own_user_namespace():
        return "no user namespace of its own: RLIMIT_NPROC would count the user's other processes"
    if not _counts_per_namespace():
        return f"Linux {os.uname().release} counts RLIMIT_NPROC per user, not per namespace (5.14 and later do)"
    try:
        running = sum(1 for d in os.listdir("/proc") if d.isdigit())  # the sandbox's own PID namespace
        soft, hard = resource.getrlimit(resource.RLIMIT_NPROC)
        want = running + int(extra)
        if hard != resource.RLIM_INFINITY:
            want = min(want, hard)
        resource.setrlimit(resource.RLIMIT_NPROC, (want, want))
    except (OSError, ValueError) as exc:
        return f"RLIMIT_NPROC could not be set: {exc}"
    return None
