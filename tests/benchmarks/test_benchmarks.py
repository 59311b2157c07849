"""Smoke test of the benchmark harness on tiny sizes (its numbers mean nothing), and of the target logic."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.bench_tightness import METHODS  # noqa: E402
from benchmarks.report import targets  # noqa: E402
from benchmarks.run import RunConfig, run  # noqa: E402


@pytest.mark.slow
def test_quick_run_writes_every_required_key(tmp_path):
    pytest.importorskip("onnxruntime")
    run(RunConfig.quick(), tmp_path, tmp_path / "plot.png", datasets=("synthetic",))
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["latency"]["single_query_ratio_to_bare_forward"] > 0
    assert set(res["latency"]["single_query"]["paths"]) >= {"bare_forward", "decide", "decide_float"}
    tight = res["tightness"]["synthetic"]
    assert set(tight) == set(METHODS)
    for method in ("ipc", "global_mahalanobis", "bonferroni_box", "raw_ipc"):
        r = tight[method]
        assert r["mean_volume"] > 0 and r["median_volume"] > 0 and 0.0 <= r["coverage"] <= 1.0
    assert tight["ipc"]["calibrated"] and not tight["raw_ipc"]["calibrated"]
    assert "mean_volume" in tight["mapie_multivariate"] or "skipped" in tight["mapie_multivariate"]
    assert res["latency"]["onnx_check"]["float64"]["vs_engine_shape"] < 1e-12
    md = (tmp_path / "results.md").read_text()
    assert "| method | calibrated | mean volume |" in md and "UNCALIBRATED" in md
    assert (tmp_path / "plot.png").stat().st_size > 1000


def _fake(ipc, gm, mapie, ratio, float_ratio):
    quad = {
        "ipc": {"mean_volume": ipc},
        "global_mahalanobis": {"mean_volume": gm},
        "mapie_multivariate": {"mean_volume": mapie} if mapie else {"skipped": "not installed"},
    }
    return {
        "tightness": {"quad_landing": quad},
        "latency": {
            "single_query_ratio_to_bare_forward": ratio,
            "single_query_float_ratio_to_bare_forward": float_ratio,
        },
    }


def test_targets_are_computed_from_the_numbers():
    t = targets(_fake(ipc=1.0, gm=4.0, mapie=0.8, ratio=1.1, float_ratio=1.3))
    assert t["quad_ipc_vs_global_mahalanobis"]["met"] and t["quad_ipc_vs_global_mahalanobis"]["value"] == 0.25
    assert not t["quad_ipc_vs_mapie"]["met"] and t["quad_ipc_vs_mapie"]["by"] == pytest.approx(1.25)
    assert t["single_query_latency"]["met"] and not t["single_query_latency_float_decision"]["met"]
    missing = targets(_fake(ipc=1.0, gm=1.5, mapie=None, ratio=2.0, float_ratio=1.0))
    assert missing["quad_ipc_vs_mapie"]["met"] is None
    assert not missing["quad_ipc_vs_global_mahalanobis"]["met"]
