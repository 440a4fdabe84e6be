"""Watching a graded notebook's processes from outside: resident memory, wall time, leftovers.

Part of the summative grader (seed paper section 4, exercises graded; see
:mod:`coursekit.grading.grader`). The grader runs each notebook in a child process tree (the
executor, its IPython kernel, the kernel's forked workers, and any orphan the grader adopts as a
child subreaper). This module bounds that tree by what it really uses:

- **Memory is resident memory, not address space.** A CUDA build of torch reserves about 3 GB of
  address space on import and touches little of it, so an ``RLIMIT_AS`` starves a kernel that
  uses a few hundred MiB. :class:`Watch` polls the proportional set size (PSS: shared pages
  split between the processes sharing them, so the kernel and its copy-on-write forks are not
  counted twice; RSS where PSS cannot be read) of every process of the tree, and when the total
  passes the limit it ``SIGKILL``s the largest one and records why. The executor then sees a dead
  kernel (the cell is skipped) or the runner a dead worker, and the grader reports the notebook
  as not graded, with the reason. Measured on this project's CI container: cgroup v2 offers no
  memory controller there (``cgroup.controllers`` lists only ``hugetlb``), so polling is the
  mechanism that works on every Linux, with or without cgroups.
- **Processes and files are bounded too.** More than :data:`MAX_PROCESSES` processes at once
  (a fork bomb) or more than :data:`DISK_MB` MiB written in the notebook's folder and every
  process of the notebook is killed; the grader reports it not graded. Inside the sandbox the
  kernel also runs under ``RLIMIT_NPROC`` where that holds (a user of its own, ``nobody``, or the
  sandbox's own user namespace: :func:`coursekit.grading.sandbox.limit_processes`), and
  ``RLIMIT_FSIZE`` bounds any one file. Files without a name count too (:func:`held_files`;
  psutil's ``open_files`` leaves them out): shared memory made with ``memfd_create`` counts as
  memory, a deleted file still held open as disk -- neither is in a process's PSS or under a
  folder. What no process shows at all (a file whose only reference is in flight in a socket, a
  SysV segment nothing attaches, the untouched pages of a shared mapping) meets a machine-wide
  backstop: the machine's shared memory and the box's free disk, against their values when the
  notebook started, may change by the notebook's limits plus :data:`BACKSTOP_SLACK` (other
  programs' work) and no more. So such memory is bounded, though more loosely than the limit; a cgroup with a
  memory controller would bound it exactly, and the CI container offers none.
- **Private folders are removed even after a kill.** Each is named
  ``coursekit-grade-<pid>-*`` after the grading process; :func:`remove_stale` deletes those of
  grading processes that are gone (a ``SIGKILL`` leaves no chance to clean up), and
  :func:`handle_termination` turns ``SIGTERM``/``SIGHUP`` into an exception so that ``finally``
  blocks kill the notebook's processes and delete the folder.
- **The child itself**: the unprivileged user it runs as (:func:`grading_user`), its rlimits
  (:func:`limits`), and stopping it with everything it started (:func:`stop`; as a child
  subreaper, :func:`become_subreaper`, the grader adopts double-forked daemons, and
  :func:`sweep` kills every child it has).
"""

from __future__ import annotations

import ctypes
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
from pathlib import Path

import psutil

import coursekit
from coursekit.grading.sandbox import SHM_BYTES, TMP_BYTES

MAX_FILE_BYTES = 2**30  # the largest file a graded notebook's processes may write
PKG_ROOT = Path(os.path.abspath(coursekit.__file__)).parent.parent  # the coursekit this grader runs (not symlink-resolved)

PREFIX = "coursekit-grade-"
_OWN = re.compile(rf"^{re.escape(PREFIX)}(\d+)-")


def private_dir() -> Path:
    """A new private folder for one notebook, named after this grading process."""
    return Path(tempfile.mkdtemp(prefix=f"{PREFIX}{os.getpid()}-"))


def remove_stale(parent=None) -> list[str]:
    """Delete the private folders of grading processes that no longer run; return their names.

    Only folders named ``coursekit-grade-<pid>-*`` owned by this user are considered, and only
    when no process ``<pid>`` exists (a live process keeps its folders, whoever it is).
    """
    parent = Path(parent or tempfile.gettempdir())
    removed = []
    try:
        entries = list(parent.iterdir())
    except OSError:
        return removed
    for entry in entries:
        m = _OWN.match(entry.name)
        if not m or int(m.group(1)) == os.getpid():
            continue
        try:
            st = entry.lstat()
        except OSError:
            continue
        if not entry.is_dir() or entry.is_symlink() or st.st_uid != os.geteuid() or psutil.pid_exists(int(m.group(1))):
            continue
        shutil.rmtree(entry, ignore_errors=True)
        removed.append(entry.name)
    return removed


class Terminated(Exception):
    """The grading process was asked to stop (``SIGTERM``, ``SIGHUP``)."""

    def __init__(self, signum):
        super().__init__(f"stopped by signal {signal.Signals(signum).name}")
        self.signum = signum


def _raise_terminated(signum, frame):
    raise Terminated(signum)


def handle_termination() -> None:
    """Turn ``SIGTERM`` and ``SIGHUP`` into :class:`Terminated` so that cleanup code runs."""
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_terminated)


def _memory(proc: psutil.Process) -> int:
    """Bytes ``proc`` holds in memory: PSS when readable, else RSS; 0 when it is gone."""
    try:
        try:
            return int(proc.memory_full_info().pss)
        except (AttributeError, psutil.AccessDenied):
            return int(proc.memory_info().rss)
    except (psutil.NoSuchProcess, psutil.ZombieProcess, psutil.AccessDenied):
        return 0


def _role(proc: psutil.Process) -> str:
    try:
        cmd = " ".join(proc.cmdline())
    except (psutil.Error, OSError):
        return "a process"
    if "ipykernel" in cmd:
        return "the notebook's kernel"
    if "coursekit.grading.executor" in cmd:
        return "the grading child"
    return "a process the notebook ran (a forked call or a program it started)"


#: Processes a graded notebook may run at once (kernel, forked calls, programs it starts).
MAX_PROCESSES = 64
#: MiB a graded notebook may write in its folder (the sandbox's private /tmp is a bounded tmpfs).
DISK_MB = 1024
#: Bytes the machine's shared memory, or its free disk, may change by while a notebook runs beyond
#: what the notebook may hold (its limit, and for memory its /tmp and /dev/shm): other programs'
#: work. Past it the machine-wide backstop of :class:`Watch` stops the notebook.
BACKSTOP_SLACK = 2**30


def machine_shared_memory() -> int:
    """Bytes of shared memory on the machine (``Shmem``: tmpfs, memfd and SysV pages, whoever holds
    them); 0 where it cannot be read."""
    return getattr(psutil.virtual_memory(), "shared", 0)


def free_disk(folder) -> int:
    """Bytes free on the file system that holds ``folder``; 0 where it cannot be read."""
    try:
        return shutil.disk_usage(folder).free
    except OSError:
        return 0


def folder_bytes(folder) -> int:
    """Bytes of the regular files under ``folder`` (symlinks are not followed; vanishing files are skipped)."""
    total, todo = 0, [str(folder)]
    while todo:
        try:
            entries = list(os.scandir(todo.pop()))
        except OSError:
            continue
        for e in entries:
            try:
                if e.is_dir(follow_symlinks=False):
                    todo.append(e.path)
                elif e.is_file(follow_symlinks=False):
                    total += e.stat(follow_symlinks=False).st_blocks * 512
            except OSError:
                pass
    return total


def held_files(pids) -> tuple[dict, int]:
    """Bytes of the files without a name that the processes ``pids`` hold open, each file once (for
    the first process that holds it): ``({pid: memfd_create shared memory}, deleted files)``. Read
    from ``/proc/PID/fd``."""
    seen, memory, disk = set(), {}, 0
    for pid in pids:
        fds = f"/proc/{pid}/fd"
        try:
            entries = os.listdir(fds)
        except OSError:
            continue
        for fd in entries:
            try:
                target = os.readlink(f"{fds}/{fd}")
                memfd = target.startswith("/memfd:")
                if not (memfd or target.endswith(" (deleted)")):
                    continue
                st = os.stat(f"{fds}/{fd}")
            except OSError:
                continue
            if stat.S_ISREG(st.st_mode) and (st.st_dev, st.st_ino) not in seen:
                seen.add((st.st_dev, st.st_ino))
                if memfd:
                    memory[pid] = memory.get(pid, 0) + st.st_blocks * 512
                else:
                    disk += st.st_blocks * 512
    return memory, disk


class Watch:
    """Bound a graded notebook's processes from outside: resident memory, their number, the disk they fill.

    Args:
        limit_mb: MiB the descendants of ``root`` may hold together; over it the largest is killed.
        interval: seconds between polls.
        root: the process whose descendants are watched (default: this process). As a child
            subreaper the grader adopts orphans, so daemons the notebook started are included.
        max_processes: descendants allowed at once; more (a fork bomb) and every one is killed.
        folder: the notebook's writable folder; ``disk_mb`` bounds what it holds (polled every
            second), and past it every process is killed.
    """

    def __init__(self, limit_mb: int, interval: float = 0.1, root: int | None = None, *,
                 max_processes: int = MAX_PROCESSES, folder=None, disk_mb: int = DISK_MB):
        self.limit = int(limit_mb) * 2**20
        self.interval = float(interval)
        self.root = psutil.Process(root or os.getpid())
        self.max_processes = int(max_processes)
        self.folder, self.disk = folder, int(disk_mb) * 2**20
        self.events: list[str] = []
        self.peak = 0
        self._next_disk = 0.0
        self._held_memory: dict = {}  # {pid: memfd shared memory it holds}, at the last files poll
        # The machine-wide backstop: what no process shows (a memfd or a deleted file whose only reference is
        # in flight in a socket, a SysV segment no process attaches) still fills the machine's memory or disk.
        self._shared0, self._shared_cap = machine_shared_memory(), self.limit + TMP_BYTES + SHM_BYTES + BACKSTOP_SLACK
        self._free0 = free_disk(folder) if folder is not None else 0

    def _kill_all(self, procs, why):
        for p in procs:
            try:
                p.kill()
            except psutil.Error:
                pass
        if why not in self.events:
            self.events.append(why)

    def poll(self) -> int:
        """Measure once and enforce the limits. Returns the memory total in bytes."""
        try:
            procs = self.root.children(recursive=True)
        except psutil.Error:
            return 0
        if len(procs) > self.max_processes:
            self._kill_all(procs, f"the notebook ran {len(procs)} processes at once, over the limit of "
                                  f"{self.max_processes}; all were stopped")
            return 0
        if time.monotonic() >= self._next_disk:  # files, once a second: the folder and what is held without a name
            self._next_disk = time.monotonic() + 1.0
            self._held_memory, deleted = held_files(p.pid for p in procs)
            used = deleted + (folder_bytes(self.folder) if self.folder is not None else 0)
            if used > self.disk:
                self._kill_all(procs, f"the notebook wrote {used / 2**20:.0f} MiB of files, over the limit of "
                                      f"{self.disk / 2**20:.0f} MiB; all its processes were stopped")
                return 0
            if self._backstop(procs):
                return 0
        sizes = [(_memory(p) + self._held_memory.get(p.pid, 0), p) for p in procs]
        total = sum(s for s, _ in sizes)
        self.peak = max(self.peak, total)
        if total > self.limit and sizes:
            size, victim = max(sizes, key=lambda sp: sp[0])
            role = _role(victim)
            try:
                victim.kill()
            except psutil.Error:
                return total
            self._held_memory.pop(victim.pid, None)
            self.events.append(f"{role} was stopped: the notebook's processes held {total / 2**20:.0f} MiB of memory, "
                               f"over the limit of {self.limit / 2**20:.0f} MiB (--memory-mb); it held {size / 2**20:.0f} MiB")
        return total

    def _backstop(self, procs) -> bool:
        """Stop the notebook when the machine's shared memory grew, or its free disk shrank, by more
        than the notebook may hold plus :data:`BACKSTOP_SLACK` since it started: memory or files it
        hides from the per-process count. True when it was stopped."""
        grown = machine_shared_memory() - self._shared0
        if self._shared0 and grown > self._shared_cap:
            self._kill_all(procs, f"the machine's shared memory grew by {grown / 2**20:.0f} MiB while the notebook ran, "
                                  f"more than it may hold ({self.limit / 2**20:.0f} MiB, --memory-mb, with its /tmp and "
                                  "/dev/shm) and what other programs may use meanwhile; all its processes were stopped")
            return True
        lost = self._free0 - free_disk(self.folder) if self.folder is not None and self._free0 else None
        if lost is not None and lost > self.disk + BACKSTOP_SLACK:
            self._kill_all(procs, f"the disk's free space shrank by {lost / 2**20:.0f} MiB while the notebook ran, more "
                                  f"than it may write ({self.disk / 2**20:.0f} MiB, --disk-mb) and what other programs "
                                  "may use meanwhile; all its processes were stopped")
            return True
        return False

    def wait(self, child, timeout: float) -> bool:
        """Poll until ``child`` (a ``subprocess.Popen``) exits or ``timeout`` s pass; True when it exited."""
        end = time.monotonic() + timeout
        while True:
            if child.poll() is not None:
                return True
            left = end - time.monotonic()
            if left <= 0:
                return False
            self.poll()
            try:
                child.wait(timeout=min(self.interval, left))
                return True
            except Exception as exc:  # subprocess.TimeoutExpired
                if type(exc).__name__ != "TimeoutExpired":
                    raise


# -- the child process: its user, its limits, stopping it and everything it started ----------------

#: True once :func:`become_subreaper` succeeded: orphans of the notebook are this process's children.
ADOPTING = False


def become_subreaper() -> bool:
    """Adopt orphaned descendants (Linux ``PR_SET_CHILD_SUBREAPER``); False where unsupported.

    Only a dedicated grading process should do this: afterwards :func:`coursekit.grading.grader.grade_notebook` kills
    *every* child of the process once each notebook is done.
    """
    global ADOPTING
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        ADOPTING = libc.prctl(36, 1, 0, 0, 0) == 0
    except (OSError, AttributeError):
        ADOPTING = False
    return ADOPTING


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
                                   extra_groups=[], env={"PYTHONPATH": str(PKG_ROOT)}, cwd="/", capture_output=True, timeout=60)
            _USABLE[user] = (pw.pw_uid, pw.pw_gid) if probe.returncode == 0 else None
        except (KeyError, OSError, subprocess.SubprocessError):
            _USABLE[user] = None
    return _USABLE[user]


def limits(max_processes: int, uid: int | None = None):
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


def stop(child) -> None:
    """Kill the child's process group and every process this one adopted; reap them."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    child.wait()
    if ADOPTING:  # orphans of this notebook (kernel, daemons) are our children now: none survives
        sweep()

