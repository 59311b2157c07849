"""The V4L2 queue model against its textbook cases (closed forms, no jitter).

``T`` camera period, ``R`` reader period, ``L`` base latency (exposure and readout 0, so the
ISP latency is all of it). Ages are measured at the dequeue (``t_dequeue - t_ref``):

* reader faster than the camera: it waits for every frame, age = ``L`` whatever ``b``;
* reader slightly slower: the queue is full, age = ``L + (b - 1) T ... L + b T``;
* reader much slower, ``drop_newest`` (videobuf2): the frame read was the first to finish
  after the read ``b`` iterations earlier, age = ``b R - phi`` with ``phi ~ U(0, T)``;
* reader much slower, ``latest_slot`` (the Pi's legacy stack): the newest capture waits for
  the buffer given back, age = ``b R + U(0, T)`` on average ``b R + T / 2``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from case_studies.quad_landing.sim.camera.driver_queue import DriverQueue, FlightTiming
from case_studies.quad_landing.sim.camera.timing import POLICIES
from ipcverify.errors import InvalidInputError

T = 1.0 / 60.0
BASE = 0.005


def _iterations(b: int, policy: str, process: float, seconds: float = 20.0, phase: float = 0.003) -> list:
    tm = FlightTiming(fps=60.0, height=240, buffers=b, policy=policy, isp_latency=BASE, phase=phase)
    sim = DriverQueue(tm, lambda rng: process, np.random.default_rng(0), t_start=-1.0)
    its = sim.iterations(seconds)[60:]
    frames = [it.frame for it in its]
    assert frames == sorted(frames) and len(set(frames)) == len(frames), "in order, each frame once"
    return its


def _ages(*args: object, **kw: object) -> np.ndarray:
    return np.array([it.t_dequeue - it.t_ref for it in _iterations(*args, **kw)])  # type: ignore[arg-type]


@pytest.mark.parametrize("policy", POLICIES)
@pytest.mark.parametrize("b", [1, 2, 3, 5])
def test_fast_reader_sees_the_base_latency(policy, b):
    age = _ages(b, policy, process=0.3 * T)
    np.testing.assert_allclose(age, BASE, atol=1e-9)


@pytest.mark.parametrize("policy", ["drop_newest", "drop_oldest"])
@pytest.mark.parametrize("b", [1, 2, 3, 5])
def test_slightly_slower_reader_lags_base_plus_about_b_frames(policy, b):
    age = _ages(b, policy, process=1.05 * T)
    frames = (age.mean() - BASE) / T
    assert b - 1 <= frames <= b, frames


@pytest.mark.parametrize("b", [1, 2, 3, 5])
def test_slow_reader_drop_newest_lags_b_reader_periods(b):
    R = 0.030  # 1.8 camera periods
    age = _ages(b, "drop_newest", process=R, seconds=40.0, phase=0.0011)
    assert abs(age.mean() - (b * R - 0.5 * T)) < 0.1 * T
    assert age.min() >= b * R - T - 1e-9 and age.max() <= b * R + 1e-9


@pytest.mark.parametrize("b", [1, 2, 3])
def test_slow_reader_latest_slot_lags_b_reader_periods_plus_the_wait(b):
    R = 0.030
    age = _ages(b, "latest_slot", process=R, seconds=40.0, phase=0.0011)
    assert abs(age.mean() - (b * R + 0.5 * T)) < 0.1 * T


def test_queue_occupancy_is_b_minus_one_when_full_and_zero_when_fast():
    assert {it.queued for it in _iterations(3, "drop_newest", process=1.05 * T)} <= {1, 2}
    assert {it.queued for it in _iterations(3, "drop_newest", process=0.5 * T)} == {0}


def test_motion_capture_sample_and_hold():
    tm = FlightTiming(fps=60.0, height=240, mocap_rate=100.0, mocap_latency=0.01, mocap_phase=0.002)
    assert tm.mocap_sample(0.0305) == pytest.approx(0.012)  # samples at .002, .012, ...; usable 10 ms later
    assert tm.mocap_sample(0.0325) == pytest.approx(0.022)
    assert FlightTiming(fps=60.0, height=240).mocap_sample(0.123) == 0.123  # inf rate: the exact state


def test_state_is_read_after_processing_and_never_later():
    its = _iterations(2, "latest_slot", process=0.012)
    assert all(it.t_dequeue <= it.t_state <= it.t_done for it in its)
    assert all(it.age > 0 for it in its)


def test_camera_clock_rate_offset_and_phase():
    tm = FlightTiming(fps=60.0, height=240, rate_ppm=50.0, phase=0.004, exposure=0.008, readout=0.0045)
    assert tm.period == pytest.approx(T * (1 + 50e-6))
    assert tm.exposure_start(600) - tm.exposure_start(0) == pytest.approx(600 * T + 0.0005)
    assert tm.row_time == pytest.approx(0.0045 / 240)
    assert tm.reference_time(0) == pytest.approx(0.004 + 0.00625)


def test_bad_queue_settings_are_refused():
    with pytest.raises(InvalidInputError, match="policy must be one of"):
        FlightTiming(fps=60.0, height=240, policy="ring")
    with pytest.raises(InvalidInputError, match="at least one buffer"):
        FlightTiming(fps=60.0, height=240, buffers=0)
    with pytest.raises(InvalidInputError, match="exposure must be >= 0"):
        FlightTiming(fps=60.0, height=240, exposure=-1.0)
    assert math.isinf(FlightTiming(fps=60.0, height=240).mocap_rate)
