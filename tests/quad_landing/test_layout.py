"""The case study's layout rules: no import cycle between modules, no loop between subpackages.

The graph is read from the source by :mod:`docgen.import_graph` (every ``import`` counts,
also one inside a function or under ``if TYPE_CHECKING:``), the reading the library's layout
test shares. The planted cycles at the end check that the checks can fail.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import pytest

from docgen.import_graph import cycles, import_graph, module_files, package_graph

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


def _layout(root: Path, top: str) -> tuple[dict[str, set[str]], dict[str, dict[str, list[str]]]]:
    """The module graph of ``top`` and the graph of its subpackages (its top-level modules left out)."""
    modules = module_files(root, top)
    graph = import_graph(modules)
    return graph, package_graph(graph, top, keep=lambda head: modules.get(f"{top}.{head}", (root, False))[1])


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
