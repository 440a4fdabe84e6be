"""Worker processes that render parts of a population at once (paper section 3.2, speed).

On the CPU a generation is evaluated genome by genome, each primitive a whole-image operation.
Many of those operations are short, so a good part of the time is the interpreter's, and
threads of one process take turns at its interpreter lock: on two cores two threads reached
only 1.37x one thread (0.134 vs 0.184 s for 20 pictures at 256^2). Worker processes share no
lock; each renders its part of the population straight into one shared-memory block, and the
parent copies the pictures out in population order.

The pool is started on first use (about two seconds: a fork server imports torch once, and the
workers fork from it) and kept for the session, so a gallery pays it once. Where processes
cannot be started (a daemonic process, a sandbox without shared memory) :func:`render_parts`
says so with ``None`` and the caller renders in-process.
"""

from __future__ import annotations

import atexit
import contextlib
import multiprocessing as mp
import signal
import sys
import threading
import warnings
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import shared_memory

import numpy as np
import torch

from .local import render_chunk

__all__ = ["render_parts", "shutdown"]

_CHUNKS = 3  # chunks per worker
_lock = threading.Lock()
_pool: _Pool | None = None
_unavailable = False


class _Pool:
    """``n`` worker processes and the shared output block they write into (grown on demand)."""

    def __init__(self, n: int):
        methods = mp.get_all_start_methods()
        ctx = mp.get_context("forkserver" if "forkserver" in methods else "spawn")
        if ctx.get_start_method() == "forkserver":
            # the fork server imports torch and the evaluator (this module's imports) once;
            # workers fork from it with both loaded, and share their pages
            ctx.set_forkserver_preload([__name__])
        self.n = n
        self.executor = ProcessPoolExecutor(n, mp_context=ctx, initializer=_init_worker)
        self.shm: shared_memory.SharedMemory | None = None

    def block(self, nbytes: int) -> shared_memory.SharedMemory:
        if self.shm is None or self.shm.size < nbytes:
            self._release()
            self.shm = shared_memory.SharedMemory(create=True, size=max(nbytes, 1 << 20))
        return self.shm

    def _release(self):
        if self.shm is not None:
            self.shm.close()
            self.shm.unlink()
            self.shm = None

    def close(self):
        self.executor.shutdown(wait=True, cancel_futures=True)
        self._release()


@contextlib.contextmanager
def _main_hidden():
    """Workers start (inside ``submit``) without being told where ``__main__`` lives: they need
    nothing from it, and a script without an ``if __name__ == "__main__":`` guard must not run
    again in them (what ``spawn`` and ``forkserver`` children otherwise do)."""
    main = sys.modules.get("__main__")
    saved = {k: main.__dict__[k] for k in ("__file__", "__spec__") if main is not None and k in main.__dict__}
    try:
        for k in saved:
            if k == "__spec__":
                main.__spec__ = None
            else:
                del main.__dict__[k]
        yield
    finally:
        if saved:
            main.__dict__.update(saved)


def shutdown() -> None:
    """Stop the worker processes and free the shared block (also done at exit)."""
    global _pool
    with _lock:
        if _pool is not None:
            _pool.close()
            _pool = None


atexit.register(shutdown)


def _chunks(costs: list[float], n: int) -> list[list[int]]:
    """Indices split into at most ``n`` chunks of similar total cost (longest first into the
    cheapest chunk), each chunk's indices in increasing order."""
    loads = [[0.0, []] for _ in range(min(n, len(costs)))]
    for i in sorted(range(len(costs)), key=lambda i: -costs[i]):
        low = min(loads, key=lambda c: c[0])
        low[0] += costs[i]
        low[1].append(i)
    return [sorted(c[1]) for c in sorted(loads, key=lambda c: -c[0]) if c[1]]


def render_parts(units: list[tuple[list[int], list]], costs: list[float], shape: tuple[int, int],
                 options: dict, workers: int) -> np.ndarray | None:
    """Render a population in the worker processes.

    Args:
        units: ``(rows, trees)`` pairs: decoded trees evaluated together as one batch
            (same-shaped trees) and their rows in the population; every row appears once.
        costs: estimated cost of each unit (used to balance the workers).
        shape: ``(H, W)``.
        options: ``window`` (parsed), ``time`` and ``group``.
        workers: number of worker processes.
    Returns:
        ``(N, H, W, 3)`` float32 in population order; ``None`` when worker processes are
        unavailable here.
    """
    global _pool, _unavailable
    H, W = shape
    n = sum(len(rows) for rows, _ in units)
    with _lock:
        if _unavailable:
            return None
        try:
            if _pool is None or _pool.n != workers:
                if _pool is not None:
                    _pool.close()
                _pool = _Pool(workers)
            shm = _pool.block(n * H * W * 3 * 4)
            # a few chunks per worker: a worker that finishes early takes the next one
            with _main_hidden():
                jobs = [_pool.executor.submit(_render_chunk, shm.name, n, H, W, [units[k] for k in chunk],
                                              options) for chunk in _chunks(costs, _CHUNKS * workers)]
            for job in jobs:
                job.result()
        except (OSError, RuntimeError, AssertionError) as e:
            # no processes here (daemonic parent, no /dev/shm, a broken pool): render in-process
            _unavailable = True
            if _pool is not None:
                try:
                    _pool.close()
                except Exception:  # pragma: no cover - best effort on a broken pool
                    pass
                _pool = None
            warnings.warn(f"coursekit.pictures: worker processes unavailable ({e!r}); rendering "
                          "in this process", RuntimeWarning, stacklevel=3)
            return None
        return np.ndarray((n, H, W, 3), np.float32, buffer=shm.buf).copy()


# ---- in the worker ---------------------------------------------------------------------------

def _init_worker() -> None:
    """Workers leave Ctrl-C (and a Jupyter kernel's interrupt, sent to its process group) to the
    parent, which stops them cleanly. Each is one thread for good: torch's and BLAS's thread
    pools would only compete with the other workers for the cores. The stock pictures are
    decoded now (:func:`~.textures.preload`), not in the first render that shows one."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    torch.set_num_threads(1)
    from threadpoolctl import threadpool_limits

    from .textures import preload

    threadpool_limits(1)
    preload()


_attached: dict = {}


def _render_chunk(name: str, n: int, H: int, W: int, part: list, options: dict) -> None:
    shm = _attached.get(name)
    if shm is None:
        for old in _attached.values():
            old.close()
        _attached.clear()
        shm = _attached[name] = _attach(name)
    render_chunk(torch.from_numpy(np.ndarray((n, H, W, 3), np.float32, buffer=shm.buf)), part, **options)


def _attach(name: str) -> shared_memory.SharedMemory:
    """Open the parent's block without registering it for cleanup: only its creator frees it
    (before Python 3.13 every attachment registers, and the resource tracker complains)."""
    if sys.version_info >= (3, 13):
        return shared_memory.SharedMemory(name=name, track=False)
    from multiprocessing import resource_tracker

    register = resource_tracker.register
    resource_tracker.register = lambda *args, **kwargs: None
    try:
        return shared_memory.SharedMemory(name=name)
    finally:
        resource_tracker.register = register
