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
from docgen.readme import DOCUMENTS, console_block, load_results, render_blocks, replace_blocks  # noqa: E402


@pytest.mark.slow
def test_quick_run_writes_every_required_key(tmp_path):
    pytest.importorskip("onnxruntime")
    run(RunConfig.quick(), tmp_path, tmp_path / "plot.png", datasets=("synthetic",))
    res = json.loads((tmp_path / "results.json").read_text())
    assert res["latency"]["single_query_ratio_to_bare_forward"] > 0
    assert set(res["latency"]["single_query"]["paths"]) >= {"bare_forward", "decide", "decide_float"}
    # the decision of record is timed as a default calibration ships it: with its domain test
    assert res["latency"]["single_query_has_domain_test"] is True
    assert "decide_without_domain_test" in res["latency"]["single_query"]["paths"]
    # the float64 ceiling of batch throughput is measured beside predict at every size
    lat = res["latency"]
    assert set(lat["batch_float64_layers_ratio_to_bare_forward"]) == set(
        lat["batch_predict_ratio_to_bare_forward"]
    )
    assert all(r > 0 for r in lat["batch_float64_layers_ratio_to_bare_forward"].values())
    # the guarded batch path and the domain test's methods, per workload with its share outside
    assert set(lat["batch_guarded_ratio_to_bare_forward"]) == set(lat["batch_predict_ratio_to_bare_forward"])
    assert lat["workload"] == "synthetic" and list(lat["workloads"]) == ["synthetic"]
    work = lat["workloads"]["synthetic"]
    assert 0.0 <= work["outside_fraction"] < 0.2 and work["batch_throughput"]["outside_fraction"] is not None
    methods = work["domain_methods"]
    assert methods["agree"] and set(methods["methods"]) == {
        "exact_ckdtree",
        "blas_product",
        "tree_search",
        "distance",
    }
    assert sum(v for k, v in methods["tree_tiers"].items() if k != "index") == pytest.approx(1.0)
    assert "predict_sets" in work["batch_throughput"]["paths"]
    tight = res["tightness"]["synthetic"]
    assert set(tight) == set(METHODS)
    for method in ("ipc", "ipc_v1", "ipc_paper", "global_mahalanobis", "bonferroni_box", "oracle", "raw_ipc"):
        r = tight[method]
        assert r["mean_volume"] > 0 and r["median_volume"] > 0 and 0.0 <= r["coverage"] <= 1.0
        assert 0.0 <= r["worst_bin_coverage"] <= r["coverage"]
    assert tight["ipc"]["calibrated"] and not tight["raw_ipc"]["calibrated"]
    assert tight["ipc"]["settings"]["recipe"] == "tight" and tight["ipc_v1"]["settings"]["recipe"] == "v1"
    assert "mean_volume" in tight["mapie_multivariate"] or "skipped" in tight["mapie_multivariate"]
    # the oracle reference and the ratios to it (same PAC order statistic, and exact 1 - epsilon)
    oracle = tight["oracle"]["mean_volume"]
    assert tight["ipc"]["mean_volume_ratio_to_oracle"] == tight["ipc"]["mean_volume"] / oracle
    assert tight["oracle"]["mean_volume_ratio_to_oracle_exact"] > 1.0  # the PAC margin costs the oracle too
    # at its own coverage the oracle's PAC sets are the oracle (up to the Monte Carlo coverage estimate)
    assert tight["oracle"]["mean_volume_ratio_to_oracle_same_coverage"] == pytest.approx(1.0, rel=0.1)
    diag = tight["ipc_v1"]["diagnosis"]
    sym = diag["factors_symmetric"]
    assert sym["centre"] * sym["shape"] * sym["calibration"] == pytest.approx(diag["volume_ratio_to_oracle"])
    shift = res["shift"]
    assert {"hetlag_shift0", "hetlag_shift1", "fresh_shift0.5"} <= set(shift)
    assert set(shift["hetlag_shift1"]) == {"ipc", "ipc_v1", "global_mahalanobis"}
    assert 0.0 <= shift["hetlag_shift1"]["ipc"]["violation_mean"] <= 1.0
    assert res["latency"]["onnx_check"]["float64"]["vs_engine_shape"] < 1e-12
    assert res["startup"]["all_succeeded"] and res["targets"]["cli_startup"]["limit"] == 3.0
    md = (tmp_path / "results.md").read_text()
    assert "| method | calibrated | mean volume |" in md and "UNCALIBRATED" in md
    assert "Before and after" in md and "diagnosis against the oracle" in md and "Under shift" in md
    assert "every workload, in-distribution first" in md and "% outside the domain" in md
    for png in ("plot.png", "bench_throughput.png"):  # the tightness and throughput figures
        assert (tmp_path / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert (tmp_path / "plot.png").stat().st_size > 1000
    # the documents' generated blocks render from any run's results, and only their bodies change
    blocks = render_blocks(res, None)
    assert {"bench-summary", "bench-table", "before-after", "diagnosis", "shift", "targets"} <= set(blocks)
    assert "guarded `predict_sets`" in blocks["latency-table"] and "SciPy k-d tree" in blocks["guard-latency"]
    doc = (
        "a\n<!-- BEGIN generated:targets (python -m docgen.readme) -->\nold\n"
        "<!-- END generated:targets -->\nb"
    )
    new, changed = replace_blocks(doc, blocks)
    assert changed == ["targets"] and blocks["targets"] in new and "old" not in new
    assert new.startswith("a\n<!-- BEGIN") and new.endswith("<!-- END generated:targets -->\nb")
    assert replace_blocks(new, blocks)[1] == []


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


def test_tightness_targets_are_computed_from_the_numbers():
    def row(mean_volume, **ratios):
        return {"mean_volume": mean_volume, **ratios}

    ipc = {
        **row(1.0, mean_volume_ratio_to_mapie=0.9, mean_volume_ratio_to_oracle=1.2),
        "mean_volume_ratio_to_oracle_exact": 1.4,
        "mean_volume_ratio_to_global_mahalanobis": 0.04,
        "worst_bin_coverage": 0.977,
        "train_seconds": 6.0,
        "epsilon": 0.01,
        "test_n": 5000,
        "spread": {"coverage": {"min": 0.993}},
    }
    res = {
        "tightness": {
            "synthetic": {"ipc": ipc, "mapie_multivariate": {"worst_bin_coverage": 0.985}},
            "fresh": {"ipc": {**ipc, "mean_volume_ratio_to_oracle": 1.6}, "mapie_multivariate": {}},
        }
    }
    t = targets(res)
    assert t["synthetic_ipc_vs_mapie"]["met"] and t["synthetic_ipc_vs_oracle"]["met"]
    assert (
        not t["synthetic_ipc_vs_oracle_exact"]["met"] and t["synthetic_ipc_vs_oracle_exact"]["limit"] == 1.3
    )
    assert not t["fresh_ipc_vs_oracle"]["met"] and t["fresh_ipc_vs_oracle"]["limit"] == 1.5
    assert t["fresh_ipc_vs_global_mahalanobis"]["met"]
    assert t["fresh_ipc_violation"]["value"] == pytest.approx(0.007) and t["fresh_ipc_violation"]["met"]
    # worst-bin coverage: at least MAPIE's minus two binomial sd of a 500-sample bin (0.0089)
    wb = t["synthetic_worst_bin_vs_mapie"]
    assert wb["at_least"] and wb["limit"] == pytest.approx(0.985 - 0.0089, abs=1e-4) and wb["met"]
    assert t["synthetic_train_seconds"]["met"] and t["quad_landing_train_seconds"]["met"] is None


def test_targets_are_computed_from_the_numbers():
    t = targets(_fake(ipc=1.0, gm=4.0, mapie=0.8, ratio=0.95, float_ratio=1.3))
    assert t["quad_ipc_vs_global_mahalanobis"]["met"] and t["quad_ipc_vs_global_mahalanobis"]["value"] == 0.25
    assert not t["quad_ipc_vs_mapie"]["met"] and t["quad_ipc_vs_mapie"]["by"] == pytest.approx(1.25)
    assert t["single_query_latency"]["met"] and not t["single_query_latency_float_decision"]["met"]
    assert t["single_query_latency"]["limit"] == 1.0  # issue 30: the decision of record <= 1.0x at p50
    slow = targets(_fake(ipc=1.0, gm=4.0, mapie=0.8, ratio=1.1, float_ratio=1.0))
    assert not slow["single_query_latency"]["met"]
    guarded = _fake(ipc=1.0, gm=4.0, mapie=0.8, ratio=0.9, float_ratio=1.0)
    guarded["latency"]["batch_guarded_ratio_to_bare_forward"] = {"1000": 0.1, "10000": 0.85, "100000": 0.7}
    g = targets(guarded)
    assert g["batch_guarded_10000"]["met"] and not g["batch_guarded_100000"]["met"]
    assert "batch_guarded_1000" not in g and g["batch_guarded_10000"]["at_least"]
    missing = targets(_fake(ipc=1.0, gm=1.5, mapie=None, ratio=2.0, float_ratio=1.0))
    assert missing["quad_ipc_vs_mapie"]["met"] is None
    assert not missing["quad_ipc_vs_global_mahalanobis"]["met"]


def test_the_demo_block_is_the_console_output_with_its_wrapped_last_line():
    """The README's demo block keeps every line the user sees: the files line wraps at 80 columns,
    and dropping only its first part once left a stray 'model.pt, calibrated.pt, sets.png'."""
    out = (
        "table  \n"
        "files in ipcverify-demo/: train.csv, calibration.csv, test.csv, model.pt, calibrated.pt, \n"
        "sets.png\n"
    )
    assert console_block(out) == (
        "```\ntable\nfiles in ipcverify-demo/: train.csv, calibration.csv, test.csv, model.pt, "
        "calibrated.pt,\nsets.png\n```\n"
    )


def test_the_documents_numbers_are_the_committed_results():
    """README.md and docs/benchmarks.md hold exactly what ``python -m docgen.readme`` pastes."""
    blocks = render_blocks(*load_results())
    for doc in DOCUMENTS:
        text = doc.read_text(encoding="utf-8")
        assert replace_blocks(text, blocks)[1] == [], f"{doc.name}: run python -m docgen.readme"
        assert "READING_" not in text


@pytest.mark.slow
def test_the_guard_scale_benchmark_runs_quickly_and_writes_its_numbers(tmp_path):
    from benchmarks.bench_guard import main as guard_main

    res = guard_main(["--quick", "--out", str(tmp_path)])
    saved = json.loads((tmp_path / "guard_results.json").read_text())
    assert [r["calibration_rows"] for r in saved["calibration"]] == [300, 1000]
    assert all(r["references"] <= r["calibration_rows"] for r in saved["calibration"])
    assert [r["references"] for r in saved["reference_cap"]] == [300, 1000, 3000]
    assert all(0.0 <= r["flagged_in_distribution"] <= 1.0 for r in saved["reference_cap"])
    assert [r["queries"] for r in saved["batches"]] == [100, 1000]
    cli = saved["cli_predict"]
    assert (
        cli["rows"] == 2000
        and cli["distances_finite"]
        and set(cli["runs"]) == {"one_blas_thread", "default_threads"}
    )
    assert cli["cpu_seconds"] > 0 and res["cli_predict"]["wall_seconds"] == cli["wall_seconds"]
    assert (tmp_path / "guard_scale.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
