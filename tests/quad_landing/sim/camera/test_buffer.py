"""One buffer-size rule: every carrier of a buffer size checks it with ``check_buffer_size``."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.data.datasets import DatasetSpec
from case_studies.quad_landing.landing.state_machine import LandingParams
from case_studies.quad_landing.reproduction.config import Sizes
from case_studies.quad_landing.settings import ConfigError
from case_studies.quad_landing.sim.camera import (
    MAX_BUFFER_SIZE,
    FrameLagCamera,
    TimedCamera,
    build_camera_stage,
    check_buffer_size,
)
from case_studies.quad_landing.sim.config import CollectParams, load_config
from ipcverify.errors import InvalidInputError

BAD = [-1, MAX_BUFFER_SIZE + 1, 1.5, True, "2", None, float("nan"), float("inf")]


@pytest.mark.parametrize("good", [0, 1, 3.0, np.int64(MAX_BUFFER_SIZE), MAX_BUFFER_SIZE])
def test_whole_numbers_in_range_pass_as_ints(good):
    size = check_buffer_size(good)
    assert size == good and type(size) is int


@pytest.mark.parametrize("bad", BAD)
def test_anything_else_is_refused_with_the_range(bad):
    in_range = rf"buffer size must be an integer in \[0, {MAX_BUFFER_SIZE}\]"
    with pytest.raises(InvalidInputError, match=in_range):
        check_buffer_size(bad)


def test_lowest_name_and_error_class():
    with pytest.raises(ConfigError, match=r"sizes.extra_landing_buffer must be an integer in \[1, "):
        check_buffer_size(0, name="sizes.extra_landing_buffer", lowest=1, error=ConfigError)


@pytest.mark.parametrize("bad", [-1, MAX_BUFFER_SIZE + 1, 1.5, True])
def test_every_carrier_applies_the_same_rule(bad):
    """The flight's camera stage, a dataset spec and the [collect], [landing] and [sizes] sections."""
    cfg = load_config()
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        build_camera_stage(cfg, bad)
    with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
        DatasetSpec("d", cfg, bad, 10)
    with pytest.raises(ConfigError, match="collect.buffer_size must be an integer"):
        CollectParams.defaults(buffer_size=bad)
    with pytest.raises(ConfigError, match="landing.buffer_size must be an integer"):
        LandingParams.defaults(buffer_size=bad)
    with pytest.raises(ConfigError, match="each of sizes.buffers must be an integer"):
        Sizes.defaults(buffers=(1, bad))
    with pytest.raises(ConfigError, match="sizes.extra_landing_buffer must be an integer"):
        Sizes.defaults(extra_landing_buffer=bad)


def test_carriers_keep_a_whole_float_as_an_int():
    assert CollectParams.defaults(buffer_size=2.0).buffer_size == 2
    assert type(LandingParams.defaults(buffer_size=3.0).buffer_size) is int
    assert Sizes.defaults(buffers=(3, 1.0), extra_landing_buffer=3.0).buffers == (1, 3)


@pytest.mark.parametrize("bad", [-1, MAX_BUFFER_SIZE + 1, 1.5, True])
def test_both_camera_stages_check_their_buffer_size_themselves(bad):
    """Built directly (not by ``build_camera_stage``), the stages apply the rule through ``StageParts``."""
    cfg = load_config()
    stage = build_camera_stage(cfg, 2)
    parts = (stage.camera, stage.renderer, stage.perception, cfg.sim.ground_z)
    for make in (lambda b: FrameLagCamera(b, *parts), lambda b: TimedCamera(cfg.camera_timing, b, *parts)):
        with pytest.raises(InvalidInputError, match="buffer size must be an integer"):
            make(bad)
        size = make(2.0).buffer_size
        assert size == 2 and type(size) is int
    assert FrameLagCamera(0, *parts).buffer_size == 0
    with pytest.raises(InvalidInputError, match="the timed camera needs a buffer size >= 1"):
        TimedCamera(cfg.camera_timing, 0, *parts)
