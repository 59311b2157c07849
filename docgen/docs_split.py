"""The picture of docs/quickstart.md's split: whole runs (``--by``) against blocks of time (``--block``).

Run ``python -m docgen.docs_split`` (a few seconds). It splits the repository's EuRoC log
(``data/euroc_mh04_vislam.csv``: 20 runs that replay one trajectory, two estimators x 10 runs)
with :func:`ipcverify.data.split_file` twice, as ``ipcverify split`` does -- ``--by method,run``
and ``--block 10`` -- and draws every row of the log at its run and time, coloured by the part it
went to: ``docs/img/split_parts.png``.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from benchmarks.common import save_figure
from ipcverify.data import split_file

__all__ = ["FIGURE", "LOG", "SPLITS", "main", "parts_of"]

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "data" / "euroc_mh04_vislam.csv"
FIGURE = ROOT / "docs" / "img" / "split_parts.png"
#: The two splits drawn: a title and the keyword arguments of :func:`split_file`.
SPLITS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("ipcverify split log.csv --by method,run", {"group_column": ["method", "run"]}),
    ("ipcverify split log.csv --block 10", {"block": 10.0}),
)
_COLORS = {"train": "tab:blue", "calibration": "tab:orange", "test": "tab:green"}


def parts_of(log: Path, **kwargs: Any) -> pd.DataFrame:
    """Every row of ``log`` with the part :func:`split_file` put it in (column ``part``)."""
    with tempfile.TemporaryDirectory() as tmp:
        s = split_file(log, Path(tmp), seed=0, **kwargs)
        frames = [pd.read_csv(p.path).assign(part=p.name) for p in s.parts if p.path is not None]
    return pd.concat(frames, ignore_index=True)


def main(argv: list[str] | None = None) -> None:
    """Split the log both ways and draw the parts."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--figure", type=Path, default=FIGURE, help="PNG path")
    args = parser.parse_args(argv)
    fig, axes = plt.subplots(1, len(SPLITS), figsize=(11, 4.2), sharey=True)
    for ax, (title, kwargs) in zip(axes, SPLITS, strict=True):
        df = parts_of(LOG, **kwargs)
        runs = sorted(set(zip(df["method"], df["run"], strict=True)))
        row = {r: i for i, r in enumerate(runs)}
        y = np.array([row[r] for r in zip(df["method"], df["run"], strict=True)])
        for name, color in _COLORS.items():
            mask = (df["part"] == name).to_numpy()
            ax.scatter(df["t"][mask], y[mask], s=2, color=color, label=name)
        ax.set_title(title, fontsize=9, family="monospace")
        ax.set_xlim(-2, 90)  # room for the legend right of the runs' ends
        ax.set_xlabel("t, seconds since the run's start (column t)")
        ax.set_yticks(range(len(runs)), [f"{m.removeprefix('vislam_')}:{r}" for m, r in runs], fontsize=6)
    axes[0].set_ylabel("run (method:run)")
    axes[1].legend(loc="center right", fontsize=8, markerscale=4)
    fig.suptitle("Whole runs in each part (left), or stretches of time (right: the same 10 s of every run)")
    save_figure(fig, args.figure)
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
