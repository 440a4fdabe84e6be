"""The course material (lessons, exercises, demos, benchmarks) wherever coursekit is installed.

A wheel carries the student material as package data (``coursekit/_course/``: the lessons, the
generated exercises, the demos and the benchmark scripts; never the solutions). A checkout or an
editable install reads the same folders from the repository. :func:`copy_course` copies the
notebooks into a working folder of the student's, so their runs and autosaves never touch the
installed or committed notebooks, and a second copy into the same folder never overwrites what
they changed.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import os
import shutil
from collections.abc import Sequence
from pathlib import Path

from coursekit.atomic import atomic_path, atomic_write

#: The folders a student's working copy holds (lessons link to ``../exercises``).
STUDENT_FOLDERS = ("lessons", "exercises", "demos")
#: What the wheel carries: the student folders and the benchmark scripts, by pattern.
PACKAGED = {"lessons": "*.ipynb", "exercises": "*.ipynb", "demos": "*.ipynb", "benchmarks": "*.py", "benchmarks/data": "*.json"}

_PACKAGE = Path(__file__).resolve().parent
_CHECKOUT = _PACKAGE.parent
#: The record of what was copied, inside the working folder.
MANIFEST = Path(".coursekit") / "course.json"


def source() -> Path:
    """The folder holding ``lessons/``, ``exercises/``, ``demos/`` and ``benchmarks/``.

    The wheel's package data (``coursekit/_course``) when present, else the repository this
    package was imported from (a checkout or an editable install).

    Raises:
        FileNotFoundError: neither is there (a broken install), naming both places looked at.
    """
    packaged = _PACKAGE / "_course"
    for root in (packaged, _CHECKOUT):
        if (root / "lessons").is_dir():
            return root
    raise FileNotFoundError(f"coursekit: no course material at {packaged} nor at {_CHECKOUT / 'lessons'}; "
                            "reinstall coursekit (pip install coursekit) or run from a checkout")


def files(root: Path | None = None, folders: Sequence[str] = STUDENT_FOLDERS) -> list[str]:
    """The course files under ``root`` (default :func:`source`), as sorted POSIX paths relative to it."""
    root = source() if root is None else Path(root)
    out = []
    for folder in folders:
        out += [p.relative_to(root).as_posix() for p in sorted((root / folder).glob(PACKAGED[folder])) if p.is_file()]
    return sorted(out)


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


@dataclasses.dataclass
class CopyReport:
    """What :func:`copy_course` did, file by file (paths relative to the working folder)."""

    folder: Path
    added: list[str]
    updated: list[str]  # course files changed since the last copy, not touched by the student
    kept: list[str]  # the student's changed files, left as they are
    unchanged: list[str]

    def __str__(self) -> str:
        parts = [f"{len(self.added)} copied", f"{len(self.updated)} updated", f"{len(self.unchanged)} unchanged"]
        text = f"course in {self.folder}: " + ", ".join(parts)
        if self.kept:
            text += f"; kept your changes to {len(self.kept)} ({', '.join(self.kept)})"
        return text


def copy_course(dest: str | os.PathLike[str], *, src: Path | None = None) -> CopyReport:
    """Copy the student folders into ``dest`` without ever overwriting a student's changes.

    A file not yet in ``dest`` is copied. A file already there is left alone, unless it is
    byte for byte what an earlier copy put there and the course has a newer version (then the
    new version replaces it). The record of what was copied is ``dest/.coursekit/course.json``.

    Args:
        dest: the working folder (created if missing).
        src: where the course comes from (default :func:`source`).

    Returns:
        A :class:`CopyReport`.

    Raises:
        NotADirectoryError: ``dest`` exists and is not a folder.
    """
    src = source() if src is None else Path(src)
    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise NotADirectoryError(f"course folder: {dest} exists and is not a folder")
    dest.mkdir(parents=True, exist_ok=True)
    manifest_path = dest / MANIFEST
    try:
        copied = json.loads(manifest_path.read_text())["files"]
    except (OSError, ValueError, KeyError, TypeError):
        copied = {}
    report = CopyReport(dest.resolve(), [], [], [], [])
    for rel in files(src):
        new = _digest(src / rel)
        target = dest / rel
        if not target.exists():
            bucket = report.added
        else:
            have = _digest(target)
            if have == new:
                report.unchanged.append(rel)
                copied[rel] = new
                continue
            if copied.get(rel) != have:  # changed by the student (or not ours): never overwritten
                report.kept.append(rel)
                continue
            bucket = report.updated
        target.parent.mkdir(parents=True, exist_ok=True)
        with atomic_path(target, target.suffix) as tmp:
            shutil.copyfile(src / rel, tmp)
        copied[rel] = new
        bucket.append(rel)
    manifest_path.parent.mkdir(exist_ok=True)
    atomic_write(manifest_path, json.dumps({"format": "coursekit.course-copy/1", "files": copied}, indent=1, sort_keys=True))
    return report
