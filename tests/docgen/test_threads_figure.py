"""docs/benchmarks.md's threads picture is drawn from the committed record."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from docgen.threads_figure import FIGURE, RECORD, SETTINGS, draw, main

ROOT = Path(__file__).resolve().parents[2]


def test_the_bars_are_the_records_medians():
    record = json.loads(RECORD.read_text())
    fig = draw(record)
    training = [n for n, meta in record["workloads"].items() if meta["torch"]]
    assert [ax.get_title() for ax in fig.axes] == [f"ipcverify: {n}" for n in training]
    table = record["summary"]["table"]
    for ax, name in zip(fig.axes, training, strict=True):
        heights = [p.get_height() for p in ax.patches]
        expected = [
            r["wall_s"]
            for s in SETTINGS
            for b in (0, 1, 2)
            for r in table
            if (r["workload"], r["setting"], r["busy"]) == (name, s, b)
        ]
        np.testing.assert_allclose(heights, expected)


def test_main_writes_a_png_and_the_page_shows_the_committed_one(tmp_path):
    out = main(["--out", str(tmp_path / "t.png")])
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert FIGURE.is_file()
    assert "](img/threads.png)" in (ROOT / "docs" / "benchmarks.md").read_text()
