"""The shape of the house: no import cycle inside ``coursekit`` and no module over 600 lines.

The import graph is read statically (``ast``, nothing is imported): an edge ``a -> b`` for every
``import b`` / ``from b import ...`` in module ``a`` that names a module of the package, wherever
it stands. Imports inside functions count like those at the top: an import put inside a function
to dodge a cycle still makes the modules depend on each other, only later and out of sight. Only
imports under ``if TYPE_CHECKING:`` (never executed) are left out. ``from package import name``
is an edge to the submodule ``package.name`` when there is one, else to the package's
``__init__``; a module's own parent packages are not counted for the import machinery's implicit
loading of them (``from . import sibling`` reaches the sibling, not the package's ``__init__``;
the check modules of ``coursekit.grading.checks`` import ``register`` from their package, which
finds them on disk rather than importing them by name).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "coursekit"

MAX_LINES = 600

# Modules allowed over MAX_LINES (the test also fails when a listed module has come under the limit).
OVER_THE_LIMIT: set[str] = set()

# Known cycles, each to be removed (the test also fails when a listed one is gone).
KNOWN_CYCLES: list[set[str]] = []


def modules() -> dict[str, tuple[Path, bool]]:
    """Dotted name -> (file, is a package ``__init__``) for every module of the package."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if package else parts)] = (path, package)
    return out


def _type_checking_only(node: ast.AST) -> bool:
    test = node.test if isinstance(node, ast.If) else None
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _imports(tree: ast.AST):
    """Import statements anywhere in the module, except under ``if TYPE_CHECKING:``."""
    stack = [tree]
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _type_checking_only(child):
                stack.extend(child.orelse)
            else:
                stack.append(child)


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    graph: dict[str, set[str]] = {}
    for name, (path, package) in mods.items():
        here = name if package else name.rpartition(".")[0]
        edges = set()
        for node in _imports(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base = here.split(".")[: len(here.split(".")) - node.level + 1]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                subs = [f"{module}.{a.name}" for a in node.names if f"{module}.{a.name}" in mods]
                targets = subs if len(subs) == len(node.names) else subs + [module]
            for target in targets:
                while target and target not in mods:  # import a.b.c: the deepest module named
                    target = target.rpartition(".")[0]
                if target and target != name and not name.startswith(target + "."):
                    edges.add(target)
        graph[name] = edges
    return graph


def cycles(graph: dict[str, set[str]]) -> list[set[str]]:
    """Strongly connected components of more than one module (Tarjan, iterative)."""
    index, low, on, stack, out, counter = {}, {}, set(), [], [], [0]
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter[0]
        counter[0] += 1
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = set()
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.add(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(comp)
    return out


def _path(graph, comp: set[str]) -> str:
    """One cycle through ``comp``, written out (a -> b -> a)."""
    start = min(comp)
    prev, queue = {start: None}, [start]
    while queue:
        v = queue.pop(0)
        for w in sorted(graph[v] & comp):
            if w == start:
                chain = [v]
                while prev[chain[-1]] is not None:
                    chain.append(prev[chain[-1]])
                return " -> ".join(reversed(chain)) + f" -> {start}"
            if w not in prev:
                prev[w] = v
                queue.append(w)
    return ", ".join(sorted(comp))  # pragma: no cover - a component always holds a cycle


def test_the_cycle_finder_finds_cycles_and_only_cycles():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}, "f": set()}
    assert cycles(graph) == [{"a", "b", "c"}]
    assert _path(graph, {"a", "b", "c"}) == "a -> b -> c -> a"


def test_the_import_graph_sees_relative_absolute_and_function_level_imports():
    graph = import_graph()
    assert "coursekit.pictures.genome" in graph["coursekit.pictures.operators"]  # from .genome import ...
    assert "coursekit.pictures.operators" in graph["coursekit.pictures.session"]  # from . import operators as O
    assert "coursekit.creatures.phenotype" in graph["coursekit.creatures.genotype"]
    # coursekit.demos imports the creatures inside a function (the CLI stays quick to start)
    assert "coursekit.creatures" in graph["coursekit.demos"]


def test_no_import_cycle_inside_coursekit():
    graph = import_graph()
    found = cycles(graph)
    unknown = [_path(graph, c) for c in found if c not in KNOWN_CYCLES]
    assert not unknown, "import cycles:\n" + "\n".join(unknown)
    gone = [sorted(c) for c in KNOWN_CYCLES if c not in found]
    assert not gone, f"these cycles are gone: remove them from KNOWN_CYCLES: {gone}"


def test_no_module_over_600_lines():
    sizes = {p.relative_to(PACKAGE.parent).as_posix(): len(p.read_text(encoding="utf-8").splitlines())
             for p, _ in modules().values()}
    over = {name: n for name, n in sizes.items() if n > MAX_LINES}
    unexpected = {name: n for name, n in over.items() if name not in OVER_THE_LIMIT}
    assert not unexpected, f"modules over {MAX_LINES} lines: {unexpected}"
    back = sorted(OVER_THE_LIMIT - set(over))
    assert not back, f"now within {MAX_LINES} lines: remove from OVER_THE_LIMIT: {back}"
