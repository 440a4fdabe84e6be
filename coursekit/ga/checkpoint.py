"""Checkpoints: the complete state of a run after a generation, so a killed run can resume.

Sims' runs took hours (paper section 2.4 and Sims 1994 section 6); a classroom run dies with its
kernel. A checkpoint stores the population, its fitness, the history, the generation number and
the random generator's bit-generator state -- everything the next generation depends on -- so a
resumed run ends bit for bit where an uninterrupted one would.

File layout (binary)::

    b"coursekit.ga.checkpoint/2\\n"   magic and format version
    8 bytes                          payload length, little-endian
    32 bytes                         HMAC-SHA256 of the payload under this machine's checkpoint key
    payload                          pickle of the state dict (with a "format" field)

**What is trusted.** The payload is a pickle, because a population may hold any genome a lab
defines (numpy arrays, picture genomes, creatures, a student's own class) and the run stores its
``select`` and ``diversity`` functions; unpickling such data can run code. So a checkpoint is
unpickled only when its HMAC verifies under the *local key*: 32 random bytes created on first
use in ``$COURSEKIT_CHECKPOINT_KEY`` (a file path), else ``$XDG_CONFIG_HOME/coursekit/checkpoint.key``
(``~/.config/...``), readable by this user only. A file written by this user's coursekit verifies;
a file from anywhere else -- a classmate, a download, a forged payload with a recomputed SHA-256,
the older unsigned format 1 -- is refused with a ``ValueError`` *before anything is unpickled*.
Whoever can read the key file can sign checkpoints: keep it private. To use a checkpoint someone
else wrote, and only when you trust its author, pass ``trust_foreign=True`` (it is then unpickled
without a key check, i.e. it may run code). A stdlib HMAC is used rather than a signing library:
the writer and the reader are the same user, so a shared secret is all that is needed.

Files are written atomically (temporary file in the same folder, fsync, ``os.replace``), so a
crash while saving leaves the previous checkpoint intact. A truncated or corrupted file is refused
with a ``ValueError`` too.
"""

from __future__ import annotations

from coursekit.atomic import atomic_write

import hashlib
import hmac
import os
import pickle
import secrets
import struct
from pathlib import Path

__all__ = ["FORMAT", "save_checkpoint", "load_checkpoint", "key_path"]

FORMAT = "coursekit.ga.checkpoint/2"
_MAGIC = (FORMAT + "\n").encode()
_FAMILY = b"coursekit.ga.checkpoint/"
_HEADER = struct.Struct("<Q32s")
_KEY_BYTES = 32

REQUIRED = ("format", "generation", "population", "fitness", "history", "rng_state")


def key_path() -> Path:
    """Where this user's checkpoint key lives (see the module docstring)."""
    env = os.environ.get("COURSEKIT_CHECKPOINT_KEY")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "coursekit" / "checkpoint.key"


def _key(create: bool) -> bytes | None:
    """The local key; created (0600, atomically, first writer wins) when ``create``; None if absent."""
    path = key_path()
    try:
        key = path.read_bytes()
    except FileNotFoundError:
        if not create:
            return None
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}")
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "wb") as f:
            f.write(secrets.token_bytes(_KEY_BYTES))
            f.flush()
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)  # fails if another process created the key meanwhile: use theirs
        except FileExistsError:
            pass
        finally:
            tmp.unlink(missing_ok=True)
        key = path.read_bytes()
    if len(key) != _KEY_BYTES:
        raise ValueError(f"checkpoint key {path}: expected {_KEY_BYTES} bytes, found {len(key)}; "
                         "delete it to make a new one (checkpoints signed with it will no longer load)")
    return key


def _mac(key: bytes, payload: bytes) -> bytes:
    return hmac.new(key, payload, hashlib.sha256).digest()


def save_checkpoint(path: str | os.PathLike[str], state: dict) -> None:
    """Write a checkpoint atomically, signed with this user's key (created on first use).

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
    atomic_write(path, _MAGIC + _HEADER.pack(len(payload), _mac(_key(create=True), payload)) + payload)


def load_checkpoint(path: str | os.PathLike[str], *, trust_foreign: bool = False) -> dict:
    """Read a checkpoint written by :func:`save_checkpoint`.

    Args:
        path: the checkpoint file.
        trust_foreign: unpickle a checkpoint whose signature does not verify under the local key
            (one written by someone else). Unpickling can run code: only for files whose author
            you trust.
    Raises:
        FileNotFoundError: no such file.
        ValueError: the file is not a coursekit GA checkpoint, has another format version, is
            truncated, or was not signed with this user's key (nothing was unpickled).
    """
    path = Path(path)
    data = path.read_bytes()
    if not data.startswith(_MAGIC):
        if data.startswith(_FAMILY):
            version = data[len(_FAMILY) :].split(b"\n", 1)[0][:20].decode(errors="replace")
            if version == "1":
                raise ValueError(f"{path}: checkpoint format 1 (an unsigned pickle) is no longer loaded, since loading "
                                 f"it could run any code; rerun to write format {FORMAT!r}")
            raise ValueError(f"{path}: checkpoint format version {version!r} is not supported; this coursekit reads {FORMAT!r}")
        raise ValueError(f"{path}: not a coursekit GA checkpoint (expected it to start with {FORMAT!r})")
    body = data[len(_MAGIC) :]
    if len(body) < _HEADER.size:
        raise ValueError(f"{path}: checkpoint is truncated (header incomplete)")
    length, mac = _HEADER.unpack_from(body)
    payload = body[_HEADER.size :]
    if len(payload) != length:
        raise ValueError(f"{path}: checkpoint is truncated or padded (payload {len(payload)} bytes, header says {length})")
    if not trust_foreign:
        key = _key(create=False)
        if key is None or not hmac.compare_digest(_mac(key, payload), mac):
            raise ValueError(f"{path}: checkpoint was not signed with this user's key ({key_path()}): it is corrupted, "
                             "or someone else wrote it. Nothing was loaded (loading could run code); "
                             "load_checkpoint(path, trust_foreign=True) loads it if you trust its author")
    state = pickle.loads(payload)
    if not isinstance(state, dict) or state.get("format") != FORMAT:
        raise ValueError(f"{path}: checkpoint payload has no {FORMAT!r} format field")
    missing = [k for k in REQUIRED if k not in state]
    if missing:
        raise ValueError(f"{path}: checkpoint is missing {missing}")
    return state
