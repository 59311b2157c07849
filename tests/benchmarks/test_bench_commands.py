"""The command-timing benchmark on tiny sizes (its numbers mean nothing; no timing is asserted)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import bench_commands  # noqa: E402


def test_the_commands_are_the_documented_ones(tmp_path):
    names = bench_commands.commands(tmp_path, full=True)
    assert list(names) == [
        "demo",
        "collect",
        "train",
        "train_paper",
        "reproduce_quick",
        "sensitivity",
        "ingest_example",
        "certify_euroc",
        "reproduce_full",
    ]
    described = {k: bench_commands._describe(v, tmp_path) for k, v in names.items()}
    assert described["demo"] == "ipcverify demo --out TMP/demo"
    assert described["reproduce_quick"] == (
        "python -m case_studies.quad_landing reproduce --out TMP/quick --quick --fly-uncalibrated"
    )
    assert described["reproduce_full"].endswith("reproduce --out TMP/full --fly-uncalibrated")
    assert "reproduce_full" not in bench_commands.commands(tmp_path)  # only with --full
    assert described["certify_euroc"].startswith("docs/certify.md's EuRoC example")
    script = names["certify_euroc"][2]  # the same commands as docs/certify.md's example
    for step in ("train train.csv --out model.pt", "--group-column flight", "--domain-flag-rate 0.2"):
        assert step in script and step in (Path(__file__).parents[2] / "docs" / "certify.md").read_text()
    assert set(bench_commands.TARGETS) == {"reproduce_quick", "reproduce_full"}


@pytest.mark.slow
def test_quick_run_times_every_command_and_merges_a_partial_rerun(tmp_path):
    out = tmp_path / "t.json"
    bench_commands.main(["--quick", "--out", str(out)])
    saved = json.loads(out.read_text())
    assert list(saved["commands"]) == ["collect", "train", "train_paper"]
    assert saved["all_succeeded"] is True and saved["targets"] == {}
    for name, r in saved["commands"].items():
        assert r["exit_code"] == 0, name
        assert r["wall_s"] > 0 and r["cpu_s"] > 0, name
        assert "TMP" in r["command"] and "/tmp" not in r["command"], name
    first = saved["commands"]["train"]
    bench_commands.main(["--quick", "--only", "train_paper", "--out", str(out)])
    merged = json.loads(out.read_text())
    assert merged["commands"]["train"] == first  # kept from the first run
    assert set(merged["commands"]) == {"collect", "train", "train_paper"}
