"""The case study's layout rules: no import cycle between modules, no loop between subpackages.

Read from the source with :mod:`ast`, not by importing it: every ``import`` counts, also one
inside a function or under ``if TYPE_CHECKING:``. An import of ``a.b.c`` is an edge to
``a.b.c`` (and ``from a.b import c`` to ``a.b`` and, if it is a module, ``a.b.c``); the
parent packages' ``__init__`` it runs are not edges (every module would otherwise import its
package's ``__init__``, which imports back). The planted cycles at the end check that the
checks can fail.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CASE_STUDY = "case_studies.quad_landing"

#: The case study's subpackages from the bottom up: each imports only from those before it
#: (and from the top-level modules ``settings``); the CLI and the package ``__init__`` sit on top.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("perception",),
    ("sim",),
    ("landing",),
    ("data",),
    ("studies", "reproduction"),
)


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


def import_graph(modules: Mapping[str, tuple[Path, bool]]) -> dict[str, set[str]]:
    """Module -> the modules of ``modules`` it imports anywhere in its source."""
    graph: dict[str, set[str]] = {}
    for name, (path, is_package) in modules.items():
        package = name if is_package else name.rpartition(".")[0]
        edges: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            for module, names in _imported(node, package):
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
    graph: Mapping[str, set[str]], modules: Mapping[str, tuple[Path, bool]], top: str
) -> dict[str, dict[str, list[str]]]:
    """Subpackage of ``top`` -> the other subpackages it imports, each with the imports that do it."""
    prefix = top + "."

    def subpackage(module: str) -> str | None:
        if not module.startswith(prefix):
            return None
        head = prefix + module[len(prefix) :].split(".")[0]
        return head[len(prefix) :] if modules.get(head, (None, False))[1] else None

    out: dict[str, dict[str, list[str]]] = {}
    for source, targets in graph.items():
        a = subpackage(source)
        for target in targets:
            b = subpackage(target)
            if a is not None and b is not None and a != b:
                out.setdefault(a, {}).setdefault(b, []).append(f"{source} -> {target}")
    return out


def _layout(root: Path, top: str) -> tuple[dict[str, set[str]], dict[str, dict[str, list[str]]]]:
    modules = module_files(root, top)
    graph = import_graph(modules)
    return graph, package_graph(graph, modules, top)


def test_no_module_level_import_cycle_in_case_studies():
    graph = import_graph(module_files(ROOT, "case_studies"))
    assert len(graph) > 50  # the whole case study was read
    assert cycles(graph) == []


def test_no_loop_between_the_case_study_subpackages():
    _, packages = _layout(ROOT, CASE_STUDY)
    assert {"sim", "landing", "data", "studies", "reproduction"} <= set(packages)  # all were read
    loops = cycles({a: set(b) for a, b in packages.items()})
    where = {a: {b: packages[a][b][:3] for b in packages[a] if b in loop} for loop in loops for a in loop}
    assert loops == [], where


def test_subpackages_import_only_from_the_layers_below():
    _, packages = _layout(ROOT, CASE_STUDY)
    rank = {name: i for i, layer in enumerate(LAYERS) for name in layer}
    assert set(packages) <= set(rank), "a new subpackage: give it a place in LAYERS"
    upward = {
        f"{a} -> {b}": edges[:3]
        for a, targets in packages.items()
        for b, edges in targets.items()
        if rank[b] >= rank[a]
    }
    assert upward == {}


def test_the_camera_package_does_not_import_the_rest_of_the_simulator_above_it():
    """``sim.camera`` uses the frames, the pad and the state history; not the flight or the config."""
    graph = import_graph(module_files(ROOT, "case_studies"))
    camera = f"{CASE_STUDY}.sim.camera"
    allowed = {f"{CASE_STUDY}.sim.{m}" for m in ("frames", "marker", "history")}
    outside = {
        f"{m} -> {t}"
        for m, targets in graph.items()
        if m == camera or m.startswith(camera + ".")
        for t in targets
        if t.startswith(f"{CASE_STUDY}.sim.") and not t.startswith(camera) and t not in allowed
    }
    assert outside == set()


def _plant(root: Path, files: Mapping[str, str]) -> None:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


@pytest.mark.parametrize(
    "b_source",
    [
        "from pkg.a import f\n",  # at module level
        "def g():\n    from . import a\n    return a\n",  # inside a function, relative
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.a\n",  # for the types only
    ],
)
def test_a_planted_module_cycle_is_found(tmp_path, b_source):
    _plant(tmp_path, {"pkg/__init__.py": "", "pkg/a.py": "from pkg.b import g\n", "pkg/b.py": b_source})
    graph = import_graph(module_files(tmp_path, "pkg"))
    assert cycles(graph) == [["pkg.a", "pkg.b"]]


def test_a_planted_package_loop_is_found_and_a_clean_tree_passes(tmp_path):
    files = {
        "top/__init__.py": "from top.low.x import X\nfrom top.high.y import Y\n",
        "top/low/__init__.py": "",
        "top/low/x.py": "X = 1\n",
        "top/high/__init__.py": "",
        "top/high/y.py": "from top.low.x import X\nY = X\n",
    }
    _plant(tmp_path, files)
    graph, packages = _layout(tmp_path, "top")
    assert cycles(graph) == [] and cycles({a: set(b) for a, b in packages.items()}) == []
    # A module in the low package that uses the high one, only in a function: a loop, no module cycle.
    _plant(tmp_path, {"top/low/z.py": "def f():\n    from top.high.y import Y\n    return Y\n"})
    graph, packages = _layout(tmp_path, "top")
    assert cycles(graph) == []
    assert cycles({a: set(b) for a, b in packages.items()}) == [["high", "low"]]
