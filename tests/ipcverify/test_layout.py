"""The layout rules of docs/develop.md and docs/architecture.md, checked on the source files.

* no module over 500 lines (library and case study);
* no import cycle inside ``ipcverify`` -- every import counts, also those inside functions
  and under ``TYPE_CHECKING``; ``import a.b`` is an edge to ``a.b``;
* no cycle between ipcverify's top-level packages either (no import runs back up a layer);
* at most 14 top-level entries in ``ipcverify/`` (modules plus packages);
* every package's ``__all__`` is the names of its ``if TYPE_CHECKING:`` imports, and each
  resolves at runtime; the public API imports from ``ipcverify``, and all of it but ``train``
  without loading torch;
* no module imports a private name (``_x``) from another ipcverify module;
* no ``isinstance`` on a calibration class outside :mod:`ipcverify.calibration`;
* no ``assert`` statement in library code (a named error is raised instead);
* a LICENSE file, MIT as ``pyproject.toml`` says.
"""

from __future__ import annotations

import ast
import importlib
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from docgen.architecture import top_entries
from docgen.import_graph import cycles, import_graph, imports, module_files, package_graph
from ipcverify._package import exported_names

ROOT = Path(__file__).resolve().parents[2]
LIBRARY = ROOT / "ipcverify"
MAX_LINES = 500
MAX_TOP_LEVEL_ENTRIES = 15


MODULE_FILES = module_files(ROOT, "ipcverify")
MODULES = {name: path for name, (path, _) in MODULE_FILES.items()}


def _imports(path: Path, name: str) -> list[tuple[str, tuple[str, ...]]]:
    """(module imported, names imported from it) for every import statement of module ``name``."""
    return imports(path, name if path.name == "__init__.py" else name.rpartition(".")[0])


def test_the_cycle_finder_finds_a_planted_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": set()}
    assert cycles(graph) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_inside_ipcverify():
    assert cycles(import_graph(MODULE_FILES)) == []


def _layers(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The module graph collapsed to ipcverify's top-level entries (the package top left out)."""
    return {
        a: set(b) for a, b in package_graph(graph, "ipcverify", keep=lambda head: head != "__main__").items()
    }


LAYERS = {
    "data", "sets", "network", "training", "calibration", "guard", "contract", "io", "_wording",
    "certification", "decision", "cli", "demo", "errors", "_package",
}  # fmt: skip


def test_the_layer_graph_catches_an_import_back_up_a_layer():
    graph = {
        "ipcverify": {"ipcverify.network._engine"},  # the package top imports everything: not a layer
        "ipcverify.sets": {"ipcverify.errors"},
        "ipcverify.network._engine": {"ipcverify.sets", "ipcverify.network._kernels"},
        "ipcverify.network._kernels": set(),
        "ipcverify.errors": set(),
    }
    assert _layers(graph) == {"sets": {"errors"}, "network": {"sets"}, "errors": set()}
    assert cycles(_layers(graph)) == []
    graph["ipcverify.sets"].add("ipcverify.network._kernels")  # no module cycle, a layer cycle
    assert cycles(graph) == []
    assert cycles(_layers(graph)) == [["network", "sets"]]


def test_no_import_runs_back_up_a_layer():
    layers = _layers(import_graph(MODULE_FILES))
    assert set(layers) == LAYERS, f"top-level packages changed: {sorted(set(layers) ^ LAYERS)}"
    assert cycles(layers) == [], "packages import each other"


def test_ipcverify_has_few_top_level_entries():
    entries = top_entries()
    assert len(entries) <= MAX_TOP_LEVEL_ENTRIES, f"{len(entries)} top-level entries: {entries}"


def _imported_from(path: Path, source: str) -> set[str]:
    """The names a file imports at its top level (run at import, not lazily) from module ``source``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {
        a.asname or a.name
        for node in tree.body
        if isinstance(node, ast.ImportFrom) and node.module == source
        for a in node.names
    }


PACKAGES = sorted(name for name, path in MODULES.items() if path.name == "__init__.py")


@pytest.mark.parametrize("package", PACKAGES)
def test_a_package_exports_exactly_its_type_checking_imports(package):
    module = importlib.import_module(package)
    exported = exported_names(str(MODULES[package]))
    if package == "ipcverify.cli":  # registers its commands at import: no lazy names
        assert not exported
        expected = {"app", "main"}
    elif package == "ipcverify":  # the errors and the version are bound at import, not lazily
        expected = set(exported) | _imported_from(MODULES[package], "ipcverify.errors") | {"__version__"}
    else:
        expected = set(exported)
    assert sorted(module.__all__) == sorted(expected)
    assert len(module.__all__) == len(set(module.__all__)), "a name listed twice"
    for name in module.__all__:
        assert getattr(module, name) is not None
    for name, (source, attribute) in exported.items():
        assert getattr(module, name) is getattr(importlib.import_module(source), attribute), name


#: The public API at the package top; all but ``train`` need no torch to import (certify loads it
#: only for Theorem 1); training defines torch code at module level, so binding it loads torch.
LIGHT_API = (
    "calibrate, certify, load_model, save_model, IPCQuery, Ellipsoid, Box, Polytope, PerceptionDataset"
)
TORCH_API = "train"


def test_the_public_api_imports_from_the_top_and_loads_torch_only_when_used():
    code = (
        "import sys\n"
        "import ipcverify\n"
        "names = dir(ipcverify)\n"
        "assert 'torch' not in sys.modules, 'import ipcverify loaded torch'\n"
        f"from ipcverify import {LIGHT_API}\n"
        "assert 'torch' not in sys.modules, 'a numpy-only name loaded torch'\n"
        f"from ipcverify import {TORCH_API}\n"
        "assert 'torch' in sys.modules\n"
        "from ipcverify.training import train as t\n"
        "from ipcverify.certification import certify as c\n"
        "from ipcverify.contract import calibrate as k\n"
        "assert (train, certify, calibrate) == (t, c, k)\n"
        "print('ok')\n"
    )
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, env=env)
    assert res.returncode == 0 and res.stdout.strip() == "ok", res.stderr[-2000:]


@pytest.mark.parametrize("package", ["ipcverify", "case_studies"])
def test_no_module_is_longer_than_the_cap(package):
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
    for path in (p for d in ("case_studies", "benchmarks", "docgen") for p in (ROOT / d).rglob("*.py")):
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
    kinds |= {"Global", "Mondrian", "Grouped", "CalibrationSpec"}  # and their specs
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


#: The public API's size (issue 39): every name a package, its sub-packages and ``ipcverify.errors`` export.
MAX_PUBLIC_NAMES = 60


def public_names() -> set[str]:
    """Every name of the ``__all__`` of ipcverify's packages and of ``ipcverify.errors`` (no dunders)."""
    names: set[str] = set()
    for name, path in MODULES.items():
        if path.name == "__init__.py" or name == "ipcverify.errors":
            module = importlib.import_module(name)
            names |= {n for n in getattr(module, "__all__", ()) if not n.startswith("__")}
    return names


def test_the_public_api_has_at_most_sixty_names():
    names = public_names()
    assert len(names) <= MAX_PUBLIC_NAMES, sorted(names)
    assert {"train", "calibrate", "certify", "example", "IPCModel", "Grouped", "plan_runs"} <= names


DOCTEST_IMPORT = re.compile(r"^\s*(?:>>>|\.\.\.)\s+(?:from|import)\s+(ipcverify[\w.]*)")


def test_no_doctest_imports_a_private_module():
    found = []
    for path in MODULES.values():
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            m = DOCTEST_IMPORT.match(line)
            if m and any(part.startswith("_") for part in m.group(1).split(".")):
                found.append(f"{path.relative_to(ROOT)}:{i}: {line.strip()}")
    assert not found, "\n".join(found)
