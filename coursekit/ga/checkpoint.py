"""Checkpoints: the complete state of a run after a generation, so a killed run can resume.

Sims' runs took hours (paper section 2.4 and Sims 1994 section 6); a classroom run dies with its
kernel. A checkpoint stores the population, its fitness, the history, the generation number and
the random generator's bit-generator state -- everything the next generation depends on -- so a
resumed run ends bit for bit where an uninterrupted one would.

File layout (binary)::

    b"coursekit.ga.checkpoint/1\\n"   magic and format version
    8 bytes                          payload length, little-endian
    32 bytes                         SHA-256 of the payload
    payload                          pickle of the state dict (with a "format" field)

Files are written atomically (temporary file in the same folder, fsync, ``os.replace``), so a
crash while saving leaves the previous checkpoint intact. A truncated, corrupted or foreign file
is refused with a ValueError before anything is unpickled. As with any pickle, load only
checkpoints you (or your course) wrote.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import hashlib
import pickle
import struct
from pathlib import Path

__all__ = ["FORMAT", "save_checkpoint", "load_checkpoint"]

FORMAT = "coursekit.ga.checkpoint/1"
_MAGIC = (FORMAT + "\n").encode()
_FAMILY = b"coursekit.ga.checkpoint/"
_HEADER = struct.Struct("<Q32s")

REQUIRED = ("format", "generation", "population", "fitness", "history", "rng_state")


def save_checkpoint(path, state: dict) -> None:
    """Write a checkpoint atomically.

    Args:
        path: file to write (its folder must exist).
        state: dict with at least ``generation``, ``population``, ``fitness``, ``history``
            (a dict) and ``rng_state``; ``format`` is added.
    """
    state = {**state, "format": FORMAT}
    missing = [k for k in REQUIRED if k not in state]
    if missing:
        raise ValueError(f"state: checkpoint is missing {missing}")
    payload = pickle.dumps(state, protocol=5)
    atomic_write(path, _MAGIC + _HEADER.pack(len(payload), hashlib.sha256(payload).digest()) + payload)


def load_checkpoint(path) -> dict:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is not a coursekit GA checkpoint, has another format version, is
            truncated or corrupted.
    """
    path = Path(path)
    data = path.read_bytes()
    if not data.startswith(_MAGIC):
        if data.startswith(_FAMILY):
            version = data[len(_FAMILY) :].split(b"\n", 1)[0][:20].decode(errors="replace")
            raise ValueError(f"{path}: checkpoint format version {version!r} is not supported; this coursekit reads {FORMAT!r}")
        raise ValueError(f"{path}: not a coursekit GA checkpoint (expected it to start with {FORMAT!r})")
    body = data[len(_MAGIC) :]
    if len(body) < _HEADER.size:
        raise ValueError(f"{path}: checkpoint is truncated (header incomplete)")
    length, digest = _HEADER.unpack_from(body)
    payload = body[_HEADER.size :]
    if len(payload) != length:
        raise ValueError(f"{path}: checkpoint is truncated or padded (payload {len(payload)} bytes, header says {length})")
    if hashlib.sha256(payload).digest() != digest:
        raise ValueError(f"{path}: checkpoint is corrupted (SHA-256 of the payload does not match its header)")
    state = pickle.loads(payload)
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise ValueError(f"{path}: checkpoint payload has no {FORMAT!r} format field")
    missing = [k for k in REQUIRED if k not in state]
    if missing:
        raise ValueError(f"{path}: checkpoint is missing {missing}")
    return state
