"""The reproduction's mixed datasets: no pad edges on the image axes, the cache key."""

from __future__ import annotations

import json

from case_studies.quad_landing.data.approach import ApproachParams
from case_studies.quad_landing.data.datasets import (
    alignment_deg,
    as_dataset,
    cached_mixed,
    collect_mixed,
    is_cached,
)
from case_studies.quad_landing.sim.config import load_config

CFG = load_config()


def test_mixed_data_hold_no_measurement_with_pad_edges_on_the_image_axes():
    params = ApproachParams.defaults(hover_points=1)
    data = collect_mixed(300, buffer_size=1, seed=1, approach=params)
    paths = data[data["source"] == 0]
    assert len(data) == 300 and len(paths) == 150
    assert alignment_deg(paths["xw_8"].to_numpy(), CFG.pad.yaw).min() >= params.aligned_margin_deg
    assert as_dataset(data).extra["source"].shape == (300,)


def test_a_cached_dataset_records_its_buffer_size_once(tmp_path):
    params = ApproachParams.defaults(hover_points=1)
    path = tmp_path / "d.parquet"
    cfg = CFG.replace(collect={"buffer_size": 4})  # the collect command's default: not this dataset's
    data, cached = cached_mixed(path, 40, buffer_size=1, seed=3, approach=params, config=cfg)
    assert not cached and len(data) == 40

    def keys(obj, name):
        if isinstance(obj, dict):
            return sum((k == name) + keys(v, name) for k, v in obj.items())
        return sum(keys(v, name) for v in obj) if isinstance(obj, list) else 0

    key = json.loads(path.with_suffix(".key.json").read_text())
    assert key["buffer_size"] == 1 and keys(key, "buffer_size") == 1
    assert is_cached(path, 40, buffer_size=1, seed=3, approach=params, config=CFG)
    assert not is_cached(path, 40, buffer_size=2, seed=3, approach=params, config=CFG)
