"""Atomic file writes: nothing is lost when a write fails or a kernel dies half-way.

Every file coursekit writes (genomes, creatures, checkpoints, gallery sessions, pictures, grading
results) goes to a temporary sibling first and is moved onto its name with ``os.replace`` only
once complete, so a reader sees the old file or the new one, never half of one.

A temporary sibling is named ``.NAME.PID.RANDOM.SUFFIX`` after the process writing it; a
process killed mid-write cannot remove its own, so the next write of the same file removes
the temporaries whose process is gone (or, without a process id, that are over an hour old).
"""

from __future__ import annotations

import errno
import os
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path: str | os.PathLike[str], suffix: str = ".tmp") -> Iterator[Path]:
    """A temporary sibling of ``path`` for writers that take a file name (OpenImageIO, VTK).

    Yields the temporary path; when the block succeeds the file is moved onto ``path``, when it
    fails the temporary file is removed and the old ``path`` (if any) is untouched. ``suffix``
    lets writers that choose a format by extension see the right one.
    """
    path = Path(path)
    if not path.parent.is_dir():  # named here: mkstemp's error names the temporary file
        raise FileNotFoundError(errno.ENOENT, f"the folder {str(path.parent)!r} does not exist", str(path))
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, "is a folder; give a file name", str(path))
    sweep(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.{os.getpid()}.", suffix=suffix)
    os.close(fd)
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes 0600; give the file the usual mode
    try:
        yield Path(tmp)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's process
        return True
    return True


def sweep(path: str | os.PathLike[str], max_age: float = 3600.0) -> list[Path]:
    """Remove the temporary siblings of ``path`` left by writers that died; returns them.

    A temporary whose process id (in its name) is not running is removed; one without a
    process id (written before names carried it) once it is ``max_age`` seconds old."""
    path = Path(path)
    prefix, gone = f".{path.name}.", []
    try:
        entries = list(os.scandir(path.parent))
    except OSError:
        return gone
    for entry in entries:
        if not entry.name.startswith(prefix) or not entry.is_file(follow_symlinks=False):
            continue
        tag = entry.name[len(prefix):].split(".", 1)[0]
        try:
            stale = not _alive(int(tag)) if tag.isdigit() else time.time() - entry.stat().st_mtime > max_age
        except OSError:
            continue
        if stale:
            try:
                os.unlink(entry.path)
                gone.append(Path(entry.path))
            except OSError:
                pass
    return gone


def atomic_write(path: str | os.PathLike[str], data: bytes | str) -> Path:
    """Write ``data`` (text is UTF-8) to ``path`` atomically, flushed to disk before the move."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)
