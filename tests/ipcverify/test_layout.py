"""The layout rules of docs/develop.md and docs/architecture.md, checked on the source files.

* no module over 600 lines (library and case study);
* no import cycle inside ``ipcverify`` -- every import counts, also those inside functions
  and under ``TYPE_CHECKING``; ``import a.b`` is an edge to ``a.b``;
* no module imports a private name (``_x``) from another ipcverify module;
* no ``isinstance`` on a calibration class outside :mod:`ipcverify.calibration`;
* no ``assert`` statement in library code (a named error is raised instead);
* a LICENSE file, MIT as ``pyproject.toml`` says.
"""

from __future__ import annotations

import ast
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "ipcverify"
MAX_LINES = 600


def _modules(package: Path) -> dict[str, Path]:
    out = {}
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package.parent).with_suffix("")
        parts = list(rel.parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


MODULES = _modules(LIBRARY)


def _imports(path: Path, name: str) -> list[tuple[str, list[str]]]:
    """(module imported, names imported from it) for every import statement in the file."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out: list[tuple[str, list[str]]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, []) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base]) if base else ".".join(anchor)
            out.append((base, [a.name for a in node.names]))
    return out


def _edges() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = {m: set() for m in MODULES}
    for name, path in MODULES.items():
        for module, names in _imports(path, name):
            if module in MODULES and module != name:  # a package importing its own submodules
                graph[name].add(module)
            for n in names:  # "from package import submodule"
                if f"{module}.{n}" in MODULES:
                    graph[name].add(f"{module}.{n}")
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state and (found := visit(nxt)):
                return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return None


def test_the_cycle_finder_finds_a_planted_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert _cycle(graph) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


def test_no_import_cycle_inside_ipcverify():
    cycle = _cycle(_edges())
    assert cycle is None, " -> ".join(cycle or [])


@pytest.mark.parametrize("package", ["ipcverify", "case_studies"])
def test_no_module_is_longer_than_600_lines(package):
    long = {
        str(p.relative_to(ROOT)): n
        for p in sorted((ROOT / package).rglob("*.py"))
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert not long, f"split these modules: {long}"


def test_no_private_name_crosses_a_module_boundary():
    bad = []
    for name, path in MODULES.items():
        for module, names in _imports(path, name):
            if module.startswith("ipcverify") and module != name:
                bad += [f"{name} imports {module}.{n}" for n in names if n.startswith("_")]
    for path in [*(ROOT / "case_studies").rglob("*.py"), *(ROOT / "benchmarks").rglob("*.py")]:
        for module, names in _imports(path, "case_studies._"):
            if module.startswith("ipcverify"):
                bad += [f"{path.relative_to(ROOT)} imports {module}.{n}" for n in names if n.startswith("_")]
    assert not bad, bad


def _isinstance_targets(tree: ast.AST) -> set[str]:
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance":
            if len(node.args) == 2:
                names |= {n.id for n in ast.walk(node.args[1]) if isinstance(n, ast.Name)}
                names |= {n.attr for n in ast.walk(node.args[1]) if isinstance(n, ast.Attribute)}
    return names


def test_no_caller_asks_which_calibration_kind_it_holds():
    kinds = {"GlobalCalibration", "MondrianCalibration", "GroupedCalibration", "Calibration"}
    files = [p for p in LIBRARY.rglob("*.py") if "calibration" not in p.relative_to(LIBRARY).parts[:1]]
    files += list((ROOT / "case_studies").rglob("*.py"))
    bad = [
        str(p.relative_to(ROOT))
        for p in files
        if _isinstance_targets(ast.parse(p.read_text(encoding="utf-8"))) & kinds
    ]
    assert not bad, f"isinstance on a calibration kind in {bad}: use the Calibration protocol"


def test_no_assert_statement_in_library_code():
    bad = [
        f"{p.relative_to(ROOT)}:{node.lineno}"
        for p in sorted(LIBRARY.rglob("*.py"))
        for node in ast.walk(ast.parse(p.read_text(encoding="utf-8")))
        if isinstance(node, ast.Assert)
    ]
    assert not bad, f"raise a named error instead of assert: {bad}"


def test_license_file_matches_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    text = (ROOT / "LICENSE").read_text(encoding="utf-8")
    assert project["license"] == "MIT" and text.startswith("MIT License")
    assert "Permission is hereby granted, free of charge" in text
