"""The camera-timing parameters come from the TOML file only; the source switches; the reader's times."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from case_studies.quad_landing import Flight, hover_state
from case_studies.quad_landing.settings import DEFAULTS_PATH, ConfigError, read_toml
from case_studies.quad_landing.sim.camera.timed import TimedCamera, flight_timing
from case_studies.quad_landing.sim.camera.timing import SOURCES, CameraTimingParams
from case_studies.quad_landing.sim.config import load_config
from case_studies.quad_landing.sim.history import StateHistory
from ipcverify.calibration._bounds import clopper_pearson_interval


def test_every_timing_parameter_is_read_from_defaults_toml_and_has_no_code_default():
    table = read_toml(DEFAULTS_PATH)["camera_timing"]
    fields = {f.name: f for f in dataclasses.fields(CameraTimingParams)}
    assert set(fields) == set(table)  # every parameter in the file, nothing else
    assert all(f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING
               for f in fields.values())  # fmt: skip
    p = load_config().camera_timing
    for key, value in table.items():
        got = getattr(p, key)
        assert (list(got) if isinstance(got, tuple) else got) == value, key


def test_a_config_file_changes_what_the_simulator_uses(tmp_path):
    override = tmp_path / "timing.toml"
    override.write_text("[camera_timing]\nexposure = 0.002\nisp_latency = 0.009\nmocap_rate = 200.0\n")
    cfg = load_config(override)
    flight = Flight(cfg, buffer_size=2, seed=0)
    flight.reset(hover_state((0.0, 0.0, 1.2)))
    stage = flight.camera_stage
    assert isinstance(stage, TimedCamera)
    t = stage.timing
    assert (t.exposure, t.isp_latency, t.mocap_rate, t.buffers) == (0.002, 0.009, 200.0, 2)
    with pytest.raises(ConfigError, match="unknown key camera_timing.exposure_time"):
        load_config(overrides={"camera_timing": {"exposure_time": 0.01}})


def test_bad_values_are_refused_with_the_key_named():
    with pytest.raises(ConfigError, match="camera_timing.disabled: unknown sources"):
        CameraTimingParams.defaults(disabled=["lag"])
    with pytest.raises(ConfigError, match="camera_timing.policy"):
        CameraTimingParams.defaults(policy="ring")
    with pytest.raises(ConfigError, match="detector_ms must be at least two increasing"):
        CameraTimingParams.defaults(detector_ms=[2.0, 1.0])
    with pytest.raises(ConfigError, match="stall_duration"):
        CameraTimingParams.defaults(stall_duration=[0.1, 0.01])


def test_switches_remove_exactly_their_source():
    p = CameraTimingParams.defaults()
    assert p.disabled == () and all(p.enabled(s) for s in SOURCES)
    assert p.only("queue").disabled == tuple(s for s in SOURCES if s != "queue")
    rng = np.random.default_rng(0)
    assert p.without("blur").effective_exposure == 0.0 and p.without("shutter").effective_readout == 0.0
    t = flight_timing(p.without("latency"), 3, 60.0, 240, rng)
    assert t.isp_latency == 0.0 and t.exposure == p.exposure and t.buffers == 3
    t = flight_timing(p.without("jitter"), 1, 60.0, 240, rng)
    assert t.delivery_jitter == 0.0 and t.delivery_delay == p.delivery_jitter  # the mean stays
    assert p.without("queue").process_sampler()(rng) == 0.0 and p.without("queue").convert_seconds == 0.0
    constant = p.without("jitter", "stalls").process_sampler()
    assert len({constant(rng) for _ in range(20)}) == 1
    t = flight_timing(p.without("clock"), 1, 60.0, 240, rng)
    assert math.isinf(t.mocap_rate) and t.rate_ppm == 0.0
    assert t.reference_time(5) == pytest.approx(5 / 60.0)  # frames on the simulator's grid


def test_reader_time_is_the_scaled_measured_distribution():
    p = CameraTimingParams.defaults(os_jitter=0.0, overhead=0.0).without("stalls")
    draw, rng = p.process_sampler(), np.random.default_rng(1)
    ms = np.array([draw(rng) for _ in range(4000)]) * 1e3
    scale = p.cpu_scale / p.parallel_speedup
    lo, hi = p.detector_ms[0] * scale, p.detector_ms[-1] * scale
    assert lo - 1e-9 <= ms.min() and ms.max() <= hi + 1e-9
    assert np.median(ms) == pytest.approx(np.median(p.detector_ms) * scale, rel=0.02)


def test_stalls_arrive_at_their_rate():
    """Per iteration a stall happens with probability 1 - exp(-rate t): checked by a binomial interval."""
    p = CameraTimingParams.defaults(os_jitter=0.0, stall_rate=2.0).without("jitter")
    draw, rng = p.process_sampler(), np.random.default_rng(2)
    t = np.array([draw(rng) for _ in range(20000)])
    quiet = t.min()
    stalled = int(np.sum(t > quiet + 1e-9))
    expected = -math.expm1(-p.stall_rate * quiet)
    lo, hi = clopper_pearson_interval(stalled, t.size, 1e-3)
    assert lo <= expected <= hi
    extra = t[t > quiet + 1e-9] - quiet
    assert p.stall_duration[0] - 1e-9 <= extra.min() and extra.max() <= p.stall_duration[1] + 1e-9


def test_history_interpolates_a_constant_acceleration_exactly():
    h = StateHistory()
    a = np.array([0.5, -0.2, 0.1])
    for t in np.arange(0.0, 0.2, 1 / 60):
        x = np.zeros(12)
        x[0:3], x[3:6] = 0.5 * a * t**2 + np.array([0.0, 0.0, 1.0]), a * t
        h.append(t, x)
    for t in (0.01, 0.077, 0.15):
        np.testing.assert_allclose(h.state_at(t)[0:3], 0.5 * a * t**2 + [0.0, 0.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(h.state_at(-0.1)[0:3], [0.0, 0.0, 1.0])  # before the start: start velocity 0
