"""The library's layout, measured from its source: the stage packages, their sizes and imports.

Run ``python -m docgen.architecture`` (a few seconds). It reads every module of
``ipcverify/`` with :mod:`ast` (nothing is imported), and writes
``docgen/architecture_results.json`` and ``docs/img/architecture.png``:

* the top-level entries (modules plus packages, ``__init__``/``__main__`` not counted), the
  largest module, and per package its modules, lines and public names (its ``__all__``);
* the package import graph: an edge ``a -> b`` when a module of package ``a`` imports one of
  ``b`` (every import counts, also inside functions and under ``TYPE_CHECKING``), and each
  package's layer (the longest chain of imports below it), so that no edge runs up a layer;
* the figure: above, the pipeline's stages and the objects that flow between them; below, the
  packages placed by layer with their import edges, as measured.

``tests/ipcverify/test_layout.py`` checks the same rules on every run of the tests; this script
shows them.
"""

from __future__ import annotations

import argparse
import ast
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import FancyBboxPatch  # noqa: E402

from benchmarks.common import save_figure, write_json  # noqa: E402
from docgen.import_graph import import_graph, module_files  # noqa: E402
from docgen.import_graph import package_graph as collapse  # noqa: E402

__all__ = ["STAGES", "layers", "main", "package_graph", "plot", "top_entries"]

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = ROOT / "ipcverify"
OUT = Path(__file__).with_name("architecture_results.json")
FIGURE = ROOT / "docs" / "img" / "architecture.png"

#: The pipeline as a user meets it: (package, what it does, the object it hands on).
STAGES: tuple[tuple[str, str, str], ...] = (
    ("io.ingest", "robot logs\n(bags, MCAP, trajectories)", "table of (x, y, ŷ)"),
    ("data", "PerceptionDataset\nchecks, splits", "PerceptionDataset"),
    ("training", "train(recipe=)\npaper / default", "network weights"),
    ("calibration\n+ guard", "calibrate(method=,\ndomain=)", "IPCModel"),
    ("certification", "certify()\nreport, Theorem 1", "Certificate"),
    ("decision", "IPCQuery → set\nprove(), landing", "Decision"),
)


def top_entries() -> list[str]:
    """The top-level modules and packages of ipcverify (not ``__init__``/``__main__``)."""
    return sorted(
        p.stem if p.suffix == ".py" else p.name
        for p in LIBRARY.iterdir()
        if (p.suffix == ".py" and p.stem not in {"__init__", "__main__"})
        or (p.is_dir() and (p / "__init__.py").exists())
    )


def package_graph() -> dict[str, set[str]]:
    """Edges between ipcverify's top-level packages (and modules), from every import."""
    entries = top_entries()
    graph = import_graph(module_files(ROOT, "ipcverify"))
    collapsed = collapse(graph, "ipcverify", keep=set(entries).__contains__)
    return {e: set(collapsed.get(e, {})) for e in entries}


def layers(graph: dict[str, set[str]]) -> dict[str, int]:
    """Each package's layer: 0 with no imports, else one above the highest it imports.

    Raises ``ValueError`` when the packages import each other in a loop (no layering exists).
    """
    out: dict[str, int] = {}
    visiting: set[str] = set()

    def layer(node: str) -> int:
        if node in out:
            return out[node]
        if node in visiting:
            raise ValueError(f"the packages import each other in a loop through {node!r}")
        visiting.add(node)
        out[node] = 1 + max((layer(t) for t in graph[node]), default=-1)
        visiting.discard(node)
        return out[node]

    for node in sorted(graph):
        layer(node)
    return out


def _all_names(init: Path) -> list[str]:
    for node in ast.parse(init.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and any(getattr(t, "id", "") == "__all__" for t in node.targets):
            return [e.value for e in getattr(node.value, "elts", []) if isinstance(e, ast.Constant)]
    return []


def measure() -> dict[str, Any]:
    """The layout's numbers (see the module docstring)."""
    graph = package_graph()
    sizes = {
        str(p.relative_to(ROOT)): len(p.read_text(encoding="utf-8").splitlines())
        for p in LIBRARY.rglob("*.py")
    }
    packages = {}
    for entry in top_entries():
        folder = LIBRARY / entry
        if folder.is_dir():
            files = [k for k in sizes if k.startswith(f"ipcverify/{entry}/")]
            packages[entry] = {
                "modules": len(files),
                "lines": sum(sizes[k] for k in files),
                "public_names": len(_all_names(folder / "__init__.py")),
            }
    largest = max(sizes, key=lambda k: sizes[k])
    return {
        "top_level_entries": top_entries(),
        "n_top_level_entries": len(top_entries()),
        "largest_module": {"path": largest, "lines": sizes[largest]},
        "packages": packages,
        "imports": {k: sorted(v) for k, v in sorted(graph.items())},
        "layers": layers(graph),
    }


def _reduced(targets: list[str], imports: dict[str, list[str]]) -> list[str]:
    """The targets not reachable through another target (the transitive reduction's edges)."""

    def below(node: str, seen: set[str]) -> set[str]:
        for nxt in imports.get(node, []):
            if nxt not in seen:
                seen.add(nxt)
                below(nxt, seen)
        return seen

    implied = set().union(*(below(t, set()) for t in targets)) if targets else set()
    return [t for t in targets if t not in implied]


def _box(ax: Any, x: float, y: float, w: float, h: float, text: str, face: str, size: float = 8.0) -> None:
    ax.add_patch(
        FancyBboxPatch((x - w / 2, y - h / 2), w, h, boxstyle="round,pad=0.02", fc=face, ec="#333", lw=0.8)
    )
    ax.text(x, y, text, ha="center", va="center", fontsize=size)


def plot(result: dict[str, Any], path: Path) -> None:
    """Draw the stages (top) and the measured package layers and imports (bottom)."""
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(11, 9.5), gridspec_kw={"height_ratios": [1, 2.4]})
    for ax in (top, bottom):
        ax.set_axis_off()
    n = len(STAGES)
    top.set_xlim(-0.6, n - 0.4)
    top.set_ylim(-0.9, 0.9)
    top.set_title("the pipeline: stages and what flows between them", fontsize=10)
    for i, (package, text, flows) in enumerate(STAGES):
        _box(top, i, 0.2, 0.82, 0.9, f"{package}\n\n{text}", "#dce9f5")
        if i < n - 1:
            top.annotate(
                "", xy=(i + 0.6, 0.2), xytext=(i + 0.4, 0.2), arrowprops={"arrowstyle": "->", "lw": 1.4}
            )
        top.text(i + 0.5 if i < n - 1 else i, -0.45, flows, ha="center", fontsize=7.5, color="#1f4e79")
    level = result["layers"]
    imports = result["imports"]
    rows: dict[int, list[str]] = {}
    for name, k in sorted(level.items(), key=lambda kv: (kv[1], kv[0])):
        rows.setdefault(k, []).append(name)
    where: dict[str, tuple[float, float]] = {}
    for k, names in rows.items():
        for j, name in enumerate(names):
            where[name] = ((j - (len(names) - 1) / 2) * 3.0, k)
    for source, targets in imports.items():
        for target in _reduced(targets, imports):
            (x0, y0), (x1, y1) = where[source], where[target]
            bottom.annotate(
                "",
                xy=(x1, y1 + 0.22),
                xytext=(x0, y0 - 0.22),
                arrowprops={"arrowstyle": "->", "lw": 0.5, "color": "#888", "alpha": 0.7},
            )
    packages = result["packages"]
    for name, (x, y) in where.items():
        info = packages.get(name)
        label = f"{name}/\n{info['modules']} modules, {info['public_names']} names" if info else f"{name}.py"
        _box(bottom, x, y, 1.9, 0.5, label, "#f3e6c8" if info else "#eee", size=7.5)
    xs = [x for x, _ in where.values()]
    bottom.set_xlim(min(xs) - 1.3, max(xs) + 1.3)
    bottom.set_ylim(-0.6, max(level.values()) + 0.6)
    bottom.set_title(
        f"the packages, measured from the imports: each imports only from rows below it\n"
        f"(arrows: imports not implied by others; {result['n_top_level_entries']} top-level entries; "
        f"largest module {result['largest_module']['lines']} lines)",
        fontsize=10,
    )
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    """Measure the layout, write the JSON and the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT, help="JSON path")
    parser.add_argument("--figure", type=Path, default=FIGURE, help="PNG path")
    args = parser.parse_args(argv)
    result = measure()
    write_json(args.out, result)
    plot(result, args.figure)
    print(f"{result['n_top_level_entries']} top-level entries; layers {result['layers']}")
    return result


if __name__ == "__main__":
    main()
