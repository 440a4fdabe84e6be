"""Atomic file writes: nothing is lost when a write fails or a kernel dies half-way.

Every file coursekit writes (genomes, creatures, checkpoints, gallery sessions, pictures, grading
results) goes to a temporary sibling first and is moved onto its name with ``os.replace`` only
once complete, so a reader sees the old file or the new one, never half of one.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_path(path, suffix: str = ".tmp"):
    """A temporary sibling of ``path`` for writers that take a file name (OpenImageIO, VTK).

    Yields the temporary path; when the block succeeds the file is moved onto ``path``, when it
    fails the temporary file is removed and the old ``path`` (if any) is untouched. ``suffix``
    lets writers that choose a format by extension see the right one.
    """
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=suffix)
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


def atomic_write(path, data: bytes | str) -> Path:
    """Write ``data`` (text is UTF-8) to ``path`` atomically, flushed to disk before the move."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data.encode("utf-8") if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
    return Path(path)
