"""The grading child's sandbox: bubblewrap (``bwrap``), the sandbox Flatpak uses.

Part of the summative grader (seed paper section 4, exercises graded; see
:mod:`coursekit.grading.grader`). The executor and the notebook's kernel run inside a
``bwrap`` sandbox with

- an empty root in which only the system folders (:data:`SYSTEM`), this Python and the
  coursekit package are bound, **read-only**, and the notebook's private box writable: no home
  folder, no checkout around the package (its ``.git`` history holds the solutions), no other
  submission, no results file;
- the library's modules that define the functions being graded seen with those functions
  taken out, and their compiled ``__pycache__`` files masked (:mod:`.withheld`), so that no
  trick inside the kernel -- not even one that takes over the grading harvest -- can run
  coursekit's own version of a graded function;
- a private ``/tmp`` (a tmpfs of at most :data:`TMP_BYTES` that disappears with the sandbox), a ``/dev``
  of device nodes only, read-only but for a ``/dev/shm`` of at most :data:`SHM_BYTES` (bubblewrap's
  own ``/dev`` is a writable tmpfs as large as half the machine's memory), private PID, IPC, UTS and
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
#: Size of its /dev/shm (POSIX shared memory and multiprocessing's semaphores); the rest of /dev is read-only.
SHM_BYTES = 64 * 2**20


#: What the sandbox sees of the system: programs, libraries and configuration (each read-only;
#: a top-level symlink such as Debian's ``/bin -> usr/bin`` is recreated as the same symlink).
SYSTEM = ("/usr", "/bin", "/sbin", "/lib", "/lib32", "/lib64", "/libx32", "/etc", "/sys")


def command(box: Path | None, *, show=(), hide_dirs=(), hide_files=(), replace=(), python=True) -> list[str]:
    """The ``bwrap`` argument list that runs a command in the sandbox (append the command).

    The sandbox starts from an empty root: it sees :data:`SYSTEM`, this Python (its prefixes),
    the folders of ``show`` and the box, nothing else -- no home folders, no checkout (its
    ``.git``, ``solutions/``, tests and builds), no other copy of the library or submission.

    Args:
        box: the notebook's private folder, the only writable place (bound at the same path;
            None binds nothing writable, for a probe).
        show: more folders seen read-only (the coursekit package this grader runs).
        hide_dirs: folders replaced by an empty tmpfs, where a folder seen holds them.
        hide_files: files replaced by ``/dev/null`` where seen (other submissions, the results
            file, the compiled code of the library's graded functions).
        replace: ``(file, path)`` pairs: ``file`` seen read-only at ``path`` (the library's
            modules with its graded functions taken out, :mod:`.withheld`).
        python: bind this Python's prefixes (False: a command that runs the system's Python
            from ``/usr``, as a user who cannot read this one).
    """
    args = ["bwrap", "--die-with-parent", "--unshare-all", "--cap-drop", "ALL", "--new-session"]
    for d in SYSTEM:
        if os.path.islink(d):
            args += ["--symlink", os.readlink(d), d]
        elif os.path.isdir(d):
            args += ["--ro-bind", d, d]
    args += ["--dev", "/dev", "--perms", "1777", "--size", str(SHM_BYTES), "--tmpfs", "/dev/shm", "--remount-ro", "/dev",
             "--proc", "/proc", "--size", str(TMP_BYTES), "--tmpfs", "/tmp"]
    seen = _outermost([*((sys.prefix, sys.base_prefix, sys.exec_prefix) if python else ()), *show])
    for d in seen:  # after the private /tmp: a Python or checkout under /tmp (a CI clone) stays visible
        args += ["--ro-bind", d, d]

    def visible(p):
        p = os.path.abspath(p)
        return any(p == d or p.startswith(d.rstrip("/") + "/") for d in seen)

    for d in hide_dirs:
        if Path(d).is_dir() and visible(d):
            args += ["--tmpfs", str(d)]
    for f in hide_files:
        if Path(f).is_file() and visible(f):
            args += ["--ro-bind", "/dev/null", str(f)]
    for file, path in replace:
        args += ["--ro-bind", str(file), str(path)]
    if box is None:
        return args + ["--chdir", "/"]
    return args + ["--bind", str(box), str(box), "--chdir", str(box / "work")]


def _outermost(paths) -> list[str]:
    """The existing folders of ``paths``, absolute, without those inside another of them."""
    found = {os.path.abspath(p) for p in paths if p and os.path.isdir(p)}
    return sorted(p for p in found if not any(q != p and p.startswith(q.rstrip("/") + "/") for q in found))


def available(ids=None, show=()) -> str | None:
    """None when the sandbox starts this Python (as ``ids`` = (uid, gid), or this user), with the
    folders of ``show`` in view; else why not."""
    key = (ids or (), tuple(map(str, show)))
    if key not in _PROBE:
        if os.name != "posix" or shutil.which("bwrap") is None:
            _PROBE[key] = "bubblewrap (bwrap) is not installed (Debian/Ubuntu: apt-get install bubblewrap)"
        else:
            cmd = command(None, show=show) + [sys.executable, "-c", "import nbclient, numpy"]
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
