"""The simulator's configuration: overrides, unknown keys, cross-section checks."""

from __future__ import annotations

import pytest

from case_studies.quad_landing import load_config
from case_studies.quad_landing.settings import ConfigError


def test_config_overrides_and_unknown_keys(tmp_path):
    assert load_config().camera.width == 320
    f = tmp_path / "c.toml"
    f.write_text("[camera]\nfx = 250.0\n[collect]\nbuffer_size = 4\n")
    cfg = load_config(f)
    assert cfg.camera.fx == 250.0 and cfg.collect.buffer_size == 4 and cfg.camera.fy == 220.0
    with pytest.raises(ConfigError, match="unknown key camera.focal; valid keys: .*fx"):
        load_config(overrides={"camera": {"focal": 1}})
    with pytest.raises(ConfigError, match=r"unknown section \[cam\]"):
        load_config(overrides={"cam": {}})
    with pytest.raises(ConfigError, match="integer multiple of camera.fps"):
        load_config(overrides={"sim": {"physics_rate": 250.0}})
    f.write_text("[camera\nfx = 1")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(f)
