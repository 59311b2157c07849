"""The reproduction's settings: unknown keys, bad values, override files, the quick overlay."""

from __future__ import annotations

import pytest

from case_studies.quad_landing.reproduction.config import load_reproduce_config
from case_studies.quad_landing.settings import ConfigError


def test_reproduce_config_rejects_unknown_keys_and_bad_values(tmp_path):
    with pytest.raises(ConfigError, match="unknown key landing.cap"):
        load_reproduce_config(overrides={"landing": {"cap": 3}})
    with pytest.raises(ConfigError, match="unknown section"):
        load_reproduce_config(overrides={"flight": {}})
    with pytest.raises(ConfigError, match="tracking_tolerance"):
        load_reproduce_config(overrides={"landing": {"tracking_tolerance": 0.03}})
    with pytest.raises(ConfigError, match="must include 1"):
        load_reproduce_config(overrides={"sizes": {"buffers": [2, 3]}})
    with pytest.raises(ConfigError, match="two numbers"):
        load_reproduce_config(overrides={"scenario": {"transit_speed": [1.0]}})
    bad = tmp_path / "bad.toml"
    bad.write_text("[landing\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_reproduce_config(bad)
    good = tmp_path / "good.toml"
    good.write_text("[landing]\nmax_measurements = 4\n[quick.sizes]\nmc_runs = 3\n")
    assert load_reproduce_config(good).landing.max_measurements == 4
    assert load_reproduce_config(good, quick=True).sizes.mc_runs == 3
