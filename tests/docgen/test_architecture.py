"""docgen/architecture.py: the layout measured from the source, and its figure."""

from __future__ import annotations

import json

import pytest

from docgen.architecture import STAGES, layers, main, package_graph, top_entries


def test_layers_place_each_package_above_what_it_imports_and_refuse_a_loop():
    graph = {"a": set(), "b": {"a"}, "c": {"a", "b"}, "d": set()}
    assert layers(graph) == {"a": 0, "b": 1, "c": 2, "d": 0}
    with pytest.raises(ValueError, match="loop"):
        layers({"a": {"b"}, "b": {"c"}, "c": {"a"}})


def test_the_library_is_layered_and_the_figure_and_json_are_written(tmp_path):
    graph = package_graph()
    level = layers(graph)  # raises if two packages import each other
    assert all(level[t] < level[s] for s, targets in graph.items() for t in targets)
    assert len(top_entries()) <= 15 and {"network", "decision", "calibration"} <= set(top_entries())
    assert {s[0].split("\n")[0] for s in STAGES} <= {*top_entries(), "io.ingest", "calibration"}
    result = main(["--out", str(tmp_path / "a.json"), "--figure", str(tmp_path / "a.png")])
    on_disk = json.loads((tmp_path / "a.json").read_text())
    assert on_disk["n_top_level_entries"] == len(top_entries()) == result["n_top_level_entries"]
    assert on_disk["largest_module"]["lines"] <= 500
    assert (tmp_path / "a.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
