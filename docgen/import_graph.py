"""The import graph of a source tree, read with :mod:`ast` (nothing is imported).

One reading of the layout rules, shared by what checks them (``tests/ipcverify/test_layout.py``,
``tests/quad_landing/test_layout.py``) and what draws them (:mod:`docgen.architecture`).
Every ``import`` counts, also one inside a function or under ``if TYPE_CHECKING:``. An import of
``a.b.c`` is an edge to ``a.b.c``, and ``from a.b import c`` one to ``a.b`` and, if it is a
module, to ``a.b.c``; the parent packages' ``__init__`` it runs are not edges (every module
would otherwise import its package's ``__init__``, which imports back).

Examples
--------
>>> cycles({"a": {"b"}, "b": {"a"}, "c": set()})
[['a', 'b']]
"""

from __future__ import annotations

import ast
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path

__all__ = ["cycles", "import_graph", "imports", "module_files", "package_graph"]


def module_files(root: Path, top: str) -> dict[str, tuple[Path, bool]]:
    """Every module under package ``top`` (a dotted name below ``root``): name -> (file, is a package)."""
    base = root.joinpath(*top.split("."))
    modules = {}
    for path in sorted(base.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts.pop()
        modules[".".join(parts)] = (path, is_package)
    return modules


def _imported(node: ast.AST, package: str) -> Iterator[tuple[str, tuple[str, ...]]]:
    """The modules a node imports: (module, the names taken from it)."""
    if isinstance(node, ast.Import):
        for alias in node.names:
            yield alias.name, ()
    elif isinstance(node, ast.ImportFrom):
        if node.level:
            base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
            module = ".".join(base + ([node.module] if node.module else []))
        else:
            module = node.module or ""
        yield module, tuple(alias.name for alias in node.names)


def imports(path: Path, package: str) -> list[tuple[str, tuple[str, ...]]]:
    """Every import statement of a file: (absolute module, the names taken from it).

    ``package`` is the package relative imports start from (the module's own name for a
    package's ``__init__``, else its parent).
    """
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    return [imported for node in ast.walk(tree) for imported in _imported(node, package)]


def import_graph(modules: Mapping[str, tuple[Path, bool]]) -> dict[str, set[str]]:
    """Module -> the modules of ``modules`` it imports anywhere in its source."""
    graph: dict[str, set[str]] = {}
    for name, (path, is_package) in modules.items():
        edges: set[str] = set()
        for module, names in imports(path, name if is_package else name.rpartition(".")[0]):
            edges.update(m for m in (module, *(f"{module}.{n}" for n in names)) if m in modules)
        edges.discard(name)
        graph[name] = edges
    return graph


def cycles(graph: Mapping[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one node (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def package_graph(
    graph: Mapping[str, set[str]], top: str, keep: Callable[[str], bool]
) -> dict[str, dict[str, list[str]]]:
    """The module graph collapsed to the entries directly below ``top``.

    An entry is the first name after ``top.`` (a subpackage or a module) for which ``keep`` is
    true. Returns every such entry that a module of the graph belongs to, mapped to the other
    entries it imports, each with the module imports that make the edge (``"source -> target"``).
    """
    prefix = top + "."

    def entry(module: str) -> str | None:
        if not module.startswith(prefix):
            return None
        head = module[len(prefix) :].split(".")[0]
        return head if keep(head) else None

    out: dict[str, dict[str, list[str]]] = {}
    for source, targets in graph.items():
        if (a := entry(source)) is None:
            continue
        out.setdefault(a, {})
        for target in targets:
            if (b := entry(target)) is not None and a != b:
                out[a].setdefault(b, []).append(f"{source} -> {target}")
                out.setdefault(b, {})
    return out
