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


def test_the_reproduction_keeps_the_paper_network_and_hinge_whatever_the_library_default():
    """The library's default recipe changed (``tight``); the reproduction pins the earlier one.

    The reproduction trained ``ModelConfig()`` (offset centre, Cholesky head) with
    ``TrainConfig(**[ipc])`` when those were the library's defaults; ``IPC_RECIPE = "v1"``
    gives the same network and the same training whatever the library's default is now.
    """
    import dataclasses

    from case_studies.quad_landing.reproduction.config import IPC_RECIPE
    from ipcverify.architecture import DEFAULT_RECIPE, ModelConfig
    from ipcverify.training import TrainConfig

    ipc = load_reproduce_config().ipc
    assert IPC_RECIPE != DEFAULT_RECIPE == "tight"
    mc = ModelConfig.recipe(IPC_RECIPE, x_dim=12, y_dim=3, hidden=ipc.hidden)
    assert (mc.param, mc.center, mc.lowrank, mc.hidden) == ("cholesky", "offset", False, (64, 128))
    t = ipc.train
    # the reproduce.toml keys, then the earlier library defaults for everything the file leaves out
    assert (t.epochs, t.lr, t.batch_size, t.alpha, t.lam, t.seed) == (40, 1e-3, 64, 0.1, 0.01, 0)
    assert (t.loss, t.schedule, t.val_fraction, t.patience, t.warmup_epochs, t.center_warm_start) == (
        "hinge",
        "constant",
        0.0,
        None,
        0,
        False,
    )
    # nothing the file leaves out comes from the default recipe
    default = TrainConfig()
    differing = {
        f.name for f in dataclasses.fields(TrainConfig) if getattr(t, f.name) != getattr(default, f.name)
    }
    assert {"loss", "schedule", "epochs"} <= differing
