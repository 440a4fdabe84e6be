"""The library as the grading sandbox shows it: the functions being graded withheld.

Part of the summative grader (seed paper section 4, exercises graded; issue: the library's own
implementation is not the student's answer). :class:`.lockdown.Refusing` refuses coursekit's
own version of a graded function inside the process that runs the student's; but that process
is the student's kernel, and a kernel that takes over the harvest itself (an IPython input
transformer sees the harvest cell, with its socket address and token) can answer the calls from
a process that was never locked down. So the sandbox does not hold those functions at all:
:func:`withhold` writes a copy of each module that defines one, with the function's body
replaced by a ``raise``, for the sandbox to bind over the module (:func:`.sandbox.command`'s
``replace``), and names the module's compiled files in ``__pycache__`` for it to mask. Nothing
inside the kernel can then run the library's version: it is not on any disk the kernel sees.

Hand-written because it is a source transformation no library does: the definitions are found
with :mod:`ast` (by qualified name, ``Class.method`` included) and only their bodies' lines are
replaced, so every other line of the module -- and its line numbers, for tracebacks -- stays.
"""

from __future__ import annotations

import ast
import importlib.util
import os
from pathlib import Path

#: What a withheld function says when called inside the sandbox.
MESSAGE = ("coursekit's own {name} is withheld while this notebook is graded: the graded function must do the "
           "work itself (the rest of the library may be used)")


def _definition(tree, qualname):
    """The ``def`` node of ``qualname`` (``"f"`` or ``"Class.method"``) at module level, or None."""
    body = tree.body
    node = None
    for part in qualname.split("."):
        node = next((n for n in body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                     and n.name == part), None)
        if node is None:
            return None
        body = node.body
    return node if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) else None


def of(checks) -> list[str]:
    """What the sandbox withholds while ``checks`` (one notebook's) are graded: their references,
    except those the library itself needs for the other checks (``Check.library_uses``)."""
    return sorted({r for c in checks for r in c.reference} - {r for c in checks for r in c.library_uses})


def withhold(paths, out: Path) -> tuple[list[tuple[Path, str]], list[str]]:
    """Copies of the modules that define ``paths`` (``"module:qualname"``), those functions withheld.

    Args:
        paths: the library functions to withhold (a check's ``reference``).
        out: a folder to write the copies in (created; the copies are world-readable, for a
            sandbox that runs as another user).
    Returns:
        ``(replacements, compiled)``: ``(copy, module file)`` pairs to bind, and the module
        files' compiled ``__pycache__`` files to mask.
    Raises:
        ValueError: a path names no coursekit module or no function defined in one (a check's
            authoring error: grading stops there rather than go on with the function reachable;
            ``tests/test_grading_withheld.py`` withholds every registered check's references).
    """
    wanted: dict[str, list[str]] = {}
    for path in paths:
        module, _, qualname = path.partition(":")
        if not (module == "coursekit" or module.startswith("coursekit.")) or not qualname:
            raise ValueError(f"reference {path!r}: expected 'coursekit.module:function'")
        spec = importlib.util.find_spec(module)
        if spec is None or not spec.origin or not spec.origin.endswith(".py"):
            raise ValueError(f"reference {path!r}: no source file for {module}")
        wanted.setdefault(spec.origin, []).append(qualname)
    out.mkdir(parents=True, exist_ok=True)
    os.chmod(out, 0o755)
    replacements, compiled = [], []
    for i, (origin, names) in enumerate(sorted(wanted.items())):
        text = Path(origin).read_text(encoding="utf-8")
        lines = text.splitlines(keepends=True)
        tree = ast.parse(text, origin)
        spans = []
        for name in names:
            node = _definition(tree, name)
            if node is None:
                raise ValueError(f"reference {name!r}: no such function in {origin}")
            first = node.body[0]
            if first.lineno == node.lineno:
                raise ValueError(f"reference {name!r}: its body shares the line of its def in {origin}")
            spans.append((first.lineno, node.end_lineno, first.col_offset, name))
        for start, end, indent, name in sorted(spans, reverse=True):
            lines[start - 1:end] = [" " * indent + f"raise RuntimeError({MESSAGE.format(name=name)!r})\n"]
        copy = "".join(lines)
        compile(copy, origin, "exec")  # the copy must still import
        target = out / f"{i}-{Path(origin).name}"
        target.write_text(copy, encoding="utf-8")
        os.chmod(target, 0o644)
        replacements.append((target, origin))
        cache = Path(importlib.util.cache_from_source(origin)).parent
        stem = Path(origin).stem
        compiled += sorted(str(p) for p in cache.glob(f"{stem}.*.pyc"))
    return replacements, compiled
