"""The start-up benchmark on one round and a tiny model (its numbers mean nothing; no timing is asserted)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import bench_startup  # noqa: E402


@pytest.mark.slow
def test_one_round_writes_every_command_and_the_target(tmp_path):
    res = bench_startup.main(["--quick", "--out", str(tmp_path / "s.json")])
    saved = json.loads((tmp_path / "s.json").read_text())
    assert (
        saved["commands"].keys()
        == res["commands"].keys()
        == {
            "bare",
            "version",
            "help",
            "predict_help",
            "predict",
            "import_torch",
        }
    )
    assert saved["all_succeeded"] is True
    assert saved["commands"]["version"]["command"] == "ipcverify --version"
    assert saved["commands"]["bare"]["command"] == 'python -c "import numpy, click"'
    for name, r in saved["commands"].items():
        assert r["exit_codes"] == [0], name
        assert len(r["wall_s_runs"]) == len(r["cpu_s_runs"]) == saved["repeats"] == 2
        assert r["wall_s"] > 0 and r["cpu_s"] >= 0
    # what each ipcverify command imported: nothing heavy until a command needs it, and never torch
    heavy = {name: r["heavy_modules_imported"] for name, r in saved["commands"].items()}
    assert heavy["version"] == heavy["help"] == heavy["predict_help"] == []
    assert "pandas" in heavy["predict"] and "torch" not in heavy["predict"]
    assert heavy["bare"] is None and heavy["import_torch"] is None  # not ipcverify commands
    t = saved["target"]
    assert t["limit"] == bench_startup.TARGET_FACTOR == 3.0
    assert t["value"] == max(saved["ratio_to_bare"]["help"], saved["ratio_to_bare"]["version"])
    assert t["met"] == (t["value"] <= 3.0)
    assert saved["load_average_before"] and saved["machine"]["cpu_count"] >= 1
