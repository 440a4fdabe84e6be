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

A graded function's own helpers go with it (:func:`helpers`): a public ``transposition`` that
hands the work to a private ``_transposition``, or ``Creature.figure1_snake`` to
``generation.figure1_snake``, would otherwise leave the answer one call away. A library function
is withheld with the references when every function or module that refers to it is withheld:
nothing the rest of the library runs needs it.

Hand-written because it is a source transformation no library does: the definitions are found
with :mod:`ast` (by qualified name, ``Class.method`` included) and only their bodies' lines are
replaced, so every other line of the module -- and its line numbers, for tracebacks -- stays. The
references between the package's functions are read from the same syntax trees (names, module
attributes, ``Class.method`` and ``self.method``), which is what a static call graph library
would do for a whole program, with more machinery than one package needs.
"""

from __future__ import annotations

import ast
import functools
import importlib.util
import os
from pathlib import Path

#: What a withheld function says when called inside the sandbox.
MESSAGE = ("coursekit's own {name} is withheld while this notebook is graded: the graded function must do the "
           "work itself (the rest of the library may be used); a cell that uses it stops here, which costs nothing: "
           "only the graded functions are scored")


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
    """What the sandbox withholds while ``checks`` (one notebook's) are graded: their references
    with their helpers (:func:`helpers`), except those the library itself needs for the other
    checks (``Check.library_uses``, and what only they use)."""
    uses = {r for c in checks for r in c.library_uses}
    return sorted(helpers({r for c in checks for r in c.reference} - uses) - uses)


def runs(checks) -> list[tuple[list, list[str]]]:
    """The sandboxed runs of one notebook that grade its ``checks``: ``[(checks, withheld)]``.

    A function the library needs while some of a notebook's functions are graded (the picture
    operators decode with ``karva``) is the answer, or a step of it, for another (``decode``).
    Refusing it inside the kernel is not enough: a kernel can reach an unlocked process of its own
    (a thread, a forked helper, a hijacked harvest) or hide the function from the lockdown. So the
    checks that such a function could answer are graded in a second run of the notebook, in a
    sandbox that withholds every reference of the notebook's checks with its helpers; the others
    in the first, which keeps what the library needs (:func:`of`). A notebook whose checks need
    nothing of the kind runs once.
    """
    uses = {r for c in checks for r in c.library_uses}
    first = [c for c in checks if not helpers(set(c.reference)) & uses]
    second = [c for c in checks if c not in first]
    every = sorted(helpers({r for c in checks for r in c.reference}))
    return [(group, held) for group, held in ((first, of(checks)), (second, every)) if group]


def refused(check, held) -> list[str]:
    """What the process that runs ``check``'s function refuses (:class:`.lockdown.Refusing`): its
    references with their helpers, and what the sandbox withholds in that run (``held``, from
    :func:`runs`), so that a stub's call says which function it stands for."""
    return sorted(helpers(set(check.reference)) | set(held))


def helpers(paths) -> set[str]:
    """``paths`` (``"module:qualname"``) and the package's functions that only they use, all the way
    down: a function every one of whose referrers (functions, or a module's own code) is in the
    set joins it, until none does."""
    held = set(paths)
    users, containers = _users()
    grew = True
    while grew:
        grew = False
        for target, who in users.items():
            if target not in held and who <= held:
                held.add(target)
                grew = True
    return held - containers


@functools.lru_cache(maxsize=1)
def _users() -> tuple[dict[str, frozenset], frozenset]:
    """``{function: what refers to it}`` over the whole package, and the module-level containers
    among them: functions by ``"module:qualname"``, a module's own code (outside its functions) as
    ``"module:"``. A module-level tuple, list, set or dict of functions (``MODIFY_STEPS = (...)``)
    is a node of its own, ``"module:NAME"``, referred to by what uses the name: its functions
    are needed only as far as it is. Functions nothing refers to are left out (nothing in the
    library needs them, but nothing withheld leads to them either)."""
    root = Path(importlib.util.find_spec("coursekit").origin).parent
    modules = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root.parent).with_suffix("").parts
        if "_course" in parts:  # the course's copies in a wheel: benchmarks and notebooks, not the library
            continue
        package = path.name == "__init__.py"
        name = ".".join(parts[:-1] if package else parts)
        modules[name] = (ast.parse(path.read_text(encoding="utf-8"), str(path)), package)
    defined = {}  # module -> {name: "function" | "container" | {method names}}
    for name, (tree, _) in modules.items():
        defined[name] = {n.name: ({m.name for m in n.body if isinstance(m, (ast.FunctionDef, ast.AsyncFunctionDef))}
                                  if isinstance(n, ast.ClassDef) else "function")
                         for n in tree.body if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))}
        defined[name].update({_container(n): "container" for n in tree.body if _container(n)})
    users: dict[str, set] = {}
    scopes = {}
    for name, (tree, package) in modules.items():
        here = name if package else name.rpartition(".")[0]
        scopes[name] = scope = {k: (name, k) for k in defined[name]}  # local name -> (module, attribute) or (module, None)
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = here.split(".")[:len(here.split(".")) - node.level + 1]
                    base = ".".join(up + ([node.module] if node.module else []))
                for a in node.names:
                    full = f"{base}.{a.name}"
                    scope[a.asname or a.name] = (full, None) if full in modules else (base, a.name)
            elif isinstance(node, ast.Import):
                for a in node.names:
                    if a.asname and a.name in modules:
                        scope[a.asname] = (a.name, None)

    def origin(module, attr):
        """Where a name of ``module`` is defined: through re-exports (``from .operators import mutate``
        in a package's ``__init__``), to the module that defines it."""
        for _ in range(8):
            head, dot, rest = attr.partition(".")
            if head in defined.get(module, {}) or (module, head) == scopes.get(module, {}).get(head, (module, head)):
                return module, attr
            module, head = scopes[module][head]
            if head is None:
                return None
            attr = head + dot + rest
        return None

    for name, (tree, package) in modules.items():
        scope = scopes[name]

        def refer(user, body, cls=None):
            for node in (n for part in body for n in ast.walk(part)):
                target = None
                if isinstance(node, ast.Name) and node.id in scope:
                    module, attr = scope[node.id]
                    target = (module, attr)
                elif isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
                    owner = node.value.id
                    if owner in ("self", "cls") and cls is not None:
                        target = (name, f"{cls}.{node.attr}")
                    elif owner in scope:
                        module, attr = scope[owner]
                        target = (module, node.attr) if attr is None else (module, f"{attr}.{node.attr}")
                if target is None or target[1] is None or target[0] not in defined:
                    continue
                target = origin(*target)
                if target is None:
                    continue
                head, _, method = target[1].partition(".")
                kind = defined[target[0]].get(head)
                if kind in ("function", "container") and not method or isinstance(kind, set) and method in kind:
                    users.setdefault(f"{target[0]}:{target[1]}", set()).add(user)

        own = []
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                refer(f"{name}:{node.name}", [node])
            elif isinstance(node, ast.ClassDef):
                for item in node.body:
                    if isinstance(item, (ast.FunctionDef, ast.AsyncFunctionDef)):
                        refer(f"{name}:{node.name}.{item.name}", [item], node.name)
                    else:
                        own.append(item)
                own += node.decorator_list + node.bases
            elif _container(node):
                refer(f"{name}:{_container(node)}", [node.value])
            else:
                own.append(node)
        refer(f"{name}:", own)
    containers = frozenset(f"{m}:{k}" for m, names in defined.items() for k, kind in names.items() if kind == "container")
    return {k: frozenset(v) for k, v in users.items()}, containers


def _container(node) -> str | None:
    """The name a module-level statement binds to a tuple, list, set or dict display, or None."""
    target = node.targets[0] if isinstance(node, ast.Assign) and len(node.targets) == 1 else \
        node.target if isinstance(node, ast.AnnAssign) and node.value is not None else None
    if isinstance(target, ast.Name) and isinstance(node.value, (ast.Tuple, ast.List, ast.Set, ast.Dict)):
        return target.id
    return None


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
