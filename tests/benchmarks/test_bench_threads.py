"""benchmarks/bench_threads.py: the record behind ipcverify's default torch threads, and the page quoting it.

No timing is asserted: the record's numbers are checked against the page and against each other,
and the harness is run on tiny sizes.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks import bench_threads  # noqa: E402
from benchmarks.bench_threads import OUT, TARGET, busy_processes, markdown_table, summarize  # noqa: E402
from ipcverify.training._threads import DEFAULT_THREADS  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
TRAINING = ("train_demo", "train_python", "train_euroc")


def _run(wall: float, cpu: float, sha: str | None = None) -> dict:
    r = {"wall_s": wall, "cpu_s": cpu, "foreign_cpu_s": 0.0, "busy_cpu_s": 0.0, "other_cores": 0.0}
    return r | {"disturbed": False, "exit_code": 0} | ({} if sha is None else {"model_sha256": sha})


def _record(busy_default: float, sha_python: str = "a") -> dict:
    runs = {
        "train_demo": {
            "0": {"default": [_run(8.0, 8.0, "a"), _run(10.0, 9.0, "a")], "2": [_run(8.5, 11.0, "a")]},
            "1": {"default": [_run(busy_default, 9.0, "a")], "2": [_run(16.0, 12.0, "a")]},
        },
        "train_python": {"0": {"default": [_run(8.0, 8.0, sha_python)], "2": [_run(9.0, 9.0, "a")]}},
        "evaluate_demo": {"0": {"default": [_run(2.0, 2.0)]}, "1": {"default": [_run(2.2, 2.1)]}},
    }
    workloads = {"train_demo": {"what": "t", "torch": True}, "train_python": {"what": "p", "torch": True}}
    return {"runs": runs, "workloads": workloads | {"evaluate_demo": {"what": "e", "torch": False}}}


def test_the_summary_is_medians_against_idle_and_the_target_follows_them():
    record = _record(busy_default=10.0)
    s = summarize(record)
    row = {(r["workload"], r["busy"], r["setting"]): r for r in s["table"]}
    assert row["train_demo", 0, "default"]["wall_s"] == 9.0 and row["train_demo", 0, "default"]["n"] == 2
    assert row["train_demo", 1, "default"]["x_idle"] == round(10.0 / 9.0, 2)
    assert row["train_demo", 1, "2"]["x_idle"] == round(16.0 / 8.5, 2)
    assert row["train_demo", 0, "2"]["x_idle"] == 1.0
    assert s["fastest"]["train_demo"] == {"0": "2", "1": "default"}
    assert s["target"]["x_idle"] == round(10.0 / 9.0, 2) and s["target"]["met"] is True
    assert s["models_identical"] == {"train_demo": True, "train_python": True} and s["cli_equals_python"]
    slow = summarize(_record(busy_default=11.0, sha_python="b"))
    assert slow["target"]["met"] is False  # 11 / 9 = 1.22 > 1.2
    assert slow["models_identical"]["train_python"] == ["a", "b"] and slow["cli_equals_python"] is False


def test_the_docs_table_has_a_row_per_workload_and_setting():
    record = _record(busy_default=10.0)
    record["summary"] = summarize(record)
    lines = markdown_table(record).splitlines()
    assert lines[0] == "| command | threads | idle | 1 busy |"
    two = "| `train_demo` | 2 (torch's default) | 8.5 s, 11.0 CPU-s | 16.0 s, 12.0 CPU-s (1.88×) |"
    assert lines[2] == two
    assert lines[3] == "| `train_demo` | default (1) | 9.0 s, 8.5 CPU-s | 10.0 s, 9.0 CPU-s (1.11×) |"
    assert lines[-1] == "| `evaluate_demo` | default | 2.0 s, 2.0 CPU-s | 2.2 s, 2.1 CPU-s (1.10×) |"
    assert "| `train_python` | default (1) | 8.0 s, 8.0 CPU-s | — |" in lines


def test_a_disturbed_run_is_marked_and_a_partial_rerun_replaces_only_its_cells():
    record = _record(busy_default=10.0)
    record["runs"]["train_demo"]["1"]["default"] = [_run(10.0, 9.0, "a") | {"disturbed": True}]
    record["summary"] = summarize(record)
    assert "| 10.0 s, 9.0 CPU-s (1.11×)* |" in markdown_table(record)
    keep = {"command": "first", "date_utc": "d", "machine": {}, "settings": {}, "runtime_s": 1.0}
    rerun = {"runs": {"train_demo": {"1": {"default": [_run(9.5, 9.0, "a")]}}}, "workloads": {}}
    merged = bench_threads.merge(record | keep, rerun | keep | {"command": "second"})
    busy = merged["runs"]["train_demo"]["1"]
    assert busy == {"default": [_run(9.5, 9.0, "a")], "2": [_run(16.0, 12.0, "a")]}
    assert merged["runs"]["train_demo"]["0"] == record["runs"]["train_demo"]["0"]
    assert merged["command"] == "first" and [r["command"] for r in merged["reruns"]] == ["second"]
    assert "*" not in markdown_table(merged | {"summary": summarize(merged)})


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc (Linux)")
def test_busy_processes_spin_while_the_block_runs_and_are_gone_after():
    with busy_processes(2) as pids:
        assert len(pids) == 2
        start = [_cpu_s(p) for p in pids]
        time.sleep(0.5)
        assert all(_cpu_s(p) > s for p, s in zip(pids, start, strict=True))  # they use CPU
    assert not any(Path(f"/proc/{p}").exists() for p in pids)  # killed and reaped
    with busy_processes(0) as none:
        assert none == []


def test_the_page_shows_the_records_table_and_the_default_is_the_records_choice():
    record = json.loads(OUT.read_text())
    page = (ROOT / "docs" / "benchmarks.md").read_text()
    assert markdown_table(record) in page
    assert summarize(record) == record["summary"]  # the summary is computed from the runs, not typed
    assert all(r["exit_code"] == 0 for w in record["runs"].values() for b in w.values()
               for rs in b.values() for r in rs)  # fmt: skip
    s = record["summary"]
    # the default changes timings only: every training run wrote the same model file, from the
    # command line and from Python, at every thread setting and load
    assert s["models_identical"] == dict.fromkeys(TRAINING, True) and s["cli_equals_python"] is True
    assert DEFAULT_THREADS == 1 and record["settings"]["omp_num_threads"]["1"] == "1"
    assert record["machine"]["torch_default_threads"] == 2  # so "2" is what ipcverify did before
    cells = {(r["workload"], r["busy"], r["setting"]): r for r in s["table"]}
    for name in TRAINING:  # beside busy processes one thread (the default) beats torch's default
        for busy in (1, 2):
            assert cells[name, busy, "default"]["wall_s"] < cells[name, busy, "2"]["wall_s"], (name, busy)
    t = s["target"]
    assert {k: t[k] for k in TARGET} == TARGET and t["met"] is True
    assert t["x_idle"] == cells["train_demo", 1, "default"]["x_idle"]


@pytest.mark.slow
def test_a_quick_run_times_every_setting_and_leaves_no_busy_process(tmp_path):
    out = tmp_path / "t.json"
    argv = ["--quick", "--repeats", "1", "--loads", "0", "1", "--only", "train_demo", "evaluate_demo"]
    bench_threads.main([*argv, "--out", str(out)])
    saved = json.loads(out.read_text())
    assert set(saved["runs"]) == {"train_demo", "evaluate_demo"}
    assert set(saved["runs"]["train_demo"]["1"]) == {"1", "2", "default"}
    assert set(saved["runs"]["evaluate_demo"]["1"]) == {"1", "default"}  # runs no torch: no "2"
    for w in saved["runs"].values():
        for by_setting in w.values():
            for (r,) in by_setting.values():
                assert r["exit_code"] == 0 and r["wall_s"] > 0 and r["cpu_s"] > 0
    beside = [r["busy_cpu_s"] for (r,) in saved["runs"]["train_demo"]["1"].values()]
    assert all(b > 0 for b in beside)  # the busy process ran beside each run of load 1
    assert saved["summary"]["models_identical"] == {"train_demo": True}
    assert saved["summary"]["target"]["workload"] == "train_demo"
    assert not [c for c in _children() if "while True" in c]  # the busy processes are gone


def _children() -> list[str]:
    """Command lines of this process's children (``/proc``)."""
    out = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        with contextlib.suppress(OSError):
            if Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1] == str(os.getpid()):
                out.append(Path(f"/proc/{pid}/cmdline").read_text().replace("\0", " "))
    return out
