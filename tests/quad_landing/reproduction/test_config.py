"""The reproduction's settings: unknown keys, bad values, override files, the quick overlay."""

from __future__ import annotations

import pytest

from case_studies.quad_landing.reproduction.config import load_reproduce_config
from case_studies.quad_landing.settings import ConfigError


def _refused(tmp_path, text, match):
    """A settings file holding ``text`` is refused with a :class:`ConfigError` matching ``match``."""
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_reproduce_config(bad)


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
    _refused(tmp_path, "[landing\n", "not valid TOML")
    good = tmp_path / "good.toml"
    good.write_text("[landing]\nmax_measurements = 4\n[quick.sizes]\nmc_runs = 3\n")
    assert load_reproduce_config(good).landing.max_measurements == 4
    assert load_reproduce_config(good, quick=True).sizes.mc_runs == 3


def test_the_default_contract_is_the_default_recipe_and_v1_keeps_its_own_file():
    """``[ipc] recipe`` picks the library's recipe of ``default_calibrated``: ``tight`` by default;
    ``v1_head.toml`` gives ipcverify's earlier Cholesky head on an offset centre (not the paper's)."""
    import dataclasses

    from case_studies.quad_landing.settings import V1_HEAD_PATH
    from ipcverify.network._architecture import DEFAULT_RECIPE, ModelConfig
    from ipcverify.training._train import TrainConfig

    ipc = load_reproduce_config().ipc
    assert ipc.recipe == DEFAULT_RECIPE == "tight"
    assert ipc.train == TrainConfig.recipe("tight", seed=0)  # nothing of the paper's training leaks in
    mc = ModelConfig.recipe(ipc.recipe, x_dim=12, y_dim=3, hidden=ipc.hidden)
    assert (mc.lowrank, mc.hidden, mc.members) == (True, (64, 128), 5)

    v1 = load_reproduce_config(V1_HEAD_PATH).ipc
    mc = ModelConfig.recipe(v1.recipe, x_dim=12, y_dim=3, hidden=v1.hidden)
    assert (v1.recipe, mc.param, mc.center, mc.lowrank, mc.hidden, mc.n_outputs) == (
        "v1",
        "cholesky",
        "offset",
        False,
        (64, 128),
        9,
    )
    t = v1.train
    assert (t.epochs, t.lr, t.batch_size, t.alpha, t.lam, t.seed) == (40, 1e-3, 64, 0.1, 0.01, 0)
    assert (t.loss, t.schedule, t.val_fraction, t.patience, t.warmup_epochs, t.center_warm_start) == (
        "hinge",
        "constant",
        0.0,
        None,
        0,
        False,
    )
    default = TrainConfig()
    differing = {
        f.name for f in dataclasses.fields(TrainConfig) if getattr(t, f.name) != getattr(default, f.name)
    }
    assert {"loss", "schedule", "epochs"} <= differing


def test_the_paper_section_is_the_papers_network_and_loss_and_paper_head_spells_it_out():
    """``[paper]``: 12 outputs (centre outright + 9 entries of C), hidden (64, 128), ReLU, hinge,
    Adam 1e-3, 20 epochs, p = 10,892 for 15 inputs; ``paper_head.toml`` holds the same values."""
    from case_studies.quad_landing.settings import PAPER_HEAD_PATH
    from ipcverify.network._architecture import ModelConfig

    paper = load_reproduce_config().paper
    mc = ModelConfig.recipe("paper", x_dim=12, y_dim=3, hidden=paper.hidden)
    assert (mc.param, mc.center, mc.activation, mc.hidden, mc.n_outputs) == (
        "full",
        "raw",
        "relu",
        (64, 128),
        12,
    )
    t = paper.train_config()
    assert (t.loss, t.epochs, t.lr, t.schedule, t.val_fraction, t.start_at_estimate) == (
        "hinge",
        20,
        1e-3,
        "constant",
        0.0,
        True,
    )
    rule = paper.selection()
    assert (rule.target_miss, rule.val_fraction, len(rule.grid())) == (0.002, 0.2, 9)
    assert paper.fly_uncalibrated is False  # flying without a guarantee is asked for explicitly
    assert load_reproduce_config(PAPER_HEAD_PATH).paper == paper


def test_bad_paper_settings_are_config_errors(tmp_path):
    for text, match in [
        ("[paper]\nalphas = []\n", "at least one value in alphas"),
        ("[paper]\ntarget_miss = 1.5\n", "target_miss"),
        ("[paper]\nfly_uncalibrated = 1\n", "fly_uncalibrated must be true or false"),
        ("[paper]\nepsilon = 0\n", "paper.epsilon"),
    ]:
        _refused(tmp_path, text, match)


@pytest.mark.parametrize("section", ["ipc", "paper"])
@pytest.mark.parametrize(
    ("line", "match"),
    [
        ("hidden = []", "hidden must be a list of positive integers"),
        ("hidden = [64, 0]", "hidden must be a list of positive integers"),
        ("hidden = [64, true]", "hidden must be a list of positive integers"),
        ("delta = 1.0", "delta must lie strictly between 0 and 1"),
        ("coverage_quantile = true", "coverage_quantile must lie strictly between 0 and 1"),
        ('epsilon = "0.1"', "epsilon must lie strictly between 0 and 1"),
    ],
)
def test_the_network_and_calibration_levels_are_checked_in_both_sections(tmp_path, section, line, match):
    _refused(tmp_path, f"[{section}]\n{line}\n", f"{section}.{match}")


def test_an_unknown_recipe_is_a_config_error(tmp_path):
    _refused(tmp_path, '[ipc]\nrecipe = "best"\n', "ipc.recipe must be one of")
