"""The picture of docs/benchmarks.md's torch-threads section, drawn from its record.

Run ``python -m docgen.threads_figure`` after ``python -m benchmarks.bench_threads``. It reads
``benchmarks/threads_results.json`` and writes ``docs/img/threads.png``: for each training
workload, the median wall seconds (bars) and CPU-seconds (ticks) of every thread setting idle
and beside one and two busy processes. It measures nothing itself.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from matplotlib.figure import Figure

from ipcverify.certification._report_plots import figure_to_png
from ipcverify.data._files import atomic_write

__all__ = ["FIGURE", "RECORD", "draw", "main"]

ROOT = Path(__file__).resolve().parent.parent
RECORD = ROOT / "benchmarks" / "threads_results.json"
FIGURE = ROOT / "docs" / "img" / "threads.png"
#: The thread settings drawn, in order, with their legend labels.
SETTINGS = {"default": "default (1 thread)", "2": "2 threads (torch's default)"}
COLORS = {"default": "#1b7837", "2": "#b2182b"}


def draw(record: dict[str, Any]) -> Figure:
    """One panel per training workload: wall and CPU seconds by load and thread setting.

    Examples
    --------
    >>> rows = [{"workload": "train_demo", "busy": b, "setting": s, "wall_s": 1.0 + b, "cpu_s": 1.0}
    ...         for b in (0, 1) for s in ("default", "2")]
    >>> rec = {"workloads": {"train_demo": {"what": "t", "torch": True}}, "summary": {"table": rows}}
    >>> len(draw(rec).axes)
    1
    """
    table = record["summary"]["table"]
    names = [n for n, meta in record["workloads"].items() if meta["torch"]]
    loads = sorted({r["busy"] for r in table})
    fig = Figure(figsize=(3.6 * len(names), 3.4), layout="constrained")
    axes = fig.subplots(1, len(names), sharey=True, squeeze=False)[0]
    width = 0.8 / len(SETTINGS)
    for ax, name in zip(axes, names, strict=True):
        for i, (setting, label) in enumerate(SETTINGS.items()):
            cells = {r["busy"]: r for r in table if r["workload"] == name and r["setting"] == setting}
            xs = [b + (i - (len(SETTINGS) - 1) / 2) * width for b in loads if b in cells]
            wall = [cells[b]["wall_s"] for b in loads if b in cells]
            cpu = [cells[b]["cpu_s"] for b in loads if b in cells]
            ax.bar(xs, wall, width, color=COLORS[setting], label=f"{label}: wall s")
            ax.scatter(xs, cpu, marker="_", s=300, color="black", zorder=3,
                       label="CPU-seconds" if i == 0 else None)  # fmt: skip
        ax.set_xticks(loads, ["idle" if b == 0 else f"{b} busy" for b in loads])
        ax.set_title(f"ipcverify: {name}", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    axes[0].set_ylabel("seconds (median)")
    axes[0].legend(fontsize=8, loc="upper left")
    return fig


def main(argv: list[str] | None = None) -> Path:
    """Draw the record's picture; return the path written."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--record", type=Path, default=RECORD)
    parser.add_argument("--out", type=Path, default=FIGURE)
    args = parser.parse_args(argv)
    png = figure_to_png(draw(json.loads(args.record.read_text())))
    atomic_write(args.out, lambda f: f.write(png))
    print(f"wrote {args.out}")
    return args.out


if __name__ == "__main__":
    main()
