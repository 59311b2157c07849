"""Hover LQR: stability, waypoint reaching, tilt bound, path tracking, motors off."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, Reference, hover_state, load_config
from case_studies.quad_landing.sim.dynamics import linearize_hover
from case_studies.quad_landing.sim.lqr import HoverLqr, LqrParams
from case_studies.quad_landing.sim.paths import ExplorationPath
from ipcverify.errors import InvalidInputError

CFG = load_config()


@pytest.fixture(scope="module")
def flight() -> Flight:
    return Flight(CFG, buffer_size=1, seed=0)


def test_closed_loop_linearisation_is_stable():
    A, B = linearize_hover(CFG.quad)
    K = HoverLqr.design(CFG.quad, CFG.lqr).gain
    assert np.max(np.linalg.eigvals(A - B @ K).real) < -0.1


def test_hover_is_an_equilibrium_of_the_closed_loop(flight):
    flight.reset(hover_state((0.5, -0.5, 1.2), yaw=0.4))
    flight.hold(1.0)
    assert np.max(np.abs(flight.state - hover_state((0.5, -0.5, 1.2), yaw=0.4))) < 1e-9


@pytest.mark.parametrize(
    ("start", "goal", "yaw"),
    [((0, 0, 1.0), (1.0, 0, 1.0), 0.0), ((0, 0, 1.5), (0, 0.6, 0.7), 1.2),
     ((1, 1, 2), (1.6, 0.2, 2.3), -2.5)],
)  # fmt: skip
def test_lqr_reaches_a_1m_waypoint_within_5cm(flight, start, goal, yaw):
    flight.reset(hover_state(start, yaw))
    assert np.linalg.norm(np.subtract(goal, start)) >= 0.99
    result = flight.fly_to(goal, max_time=10.0)
    assert result.settled
    assert result.position_error < 0.05
    assert np.linalg.norm(flight.state[:3] - np.asarray(goal)) < 0.05
    assert abs(flight.state[8] - yaw) < CFG.settle.yaw_tolerance


def test_far_waypoint_keeps_the_tilt_small():
    # the clamp on the position error bounds the commanded tilt
    f = Flight(CFG, buffer_size=0, seed=0)
    f.reset(hover_state((-2.5, -2.5, 1.0)))
    ref = Reference((2.5, 2.5, 2.5))
    tilt = 0.0
    for _ in range(int(6 * CFG.camera.fps)):
        f.step(ref)
        tilt = max(tilt, float(np.hypot(*f.state[6:8])))
    assert np.degrees(tilt) < 15.0
    assert f.fly_to((2.5, 2.5, 2.5), max_time=15).settled


def test_yaw_frame_rotation_makes_the_response_heading_independent():
    # the same waypoint offset in the body frame gives the same body-frame trajectory
    tracks = []
    for yaw in (0.0, 2.0):
        f = Flight(CFG, buffer_size=0, seed=0)
        f.reset(hover_state((0, 0, 1.5), yaw))
        offset = np.array([np.cos(yaw), np.sin(yaw), 0.0]) * 0.8
        for _ in range(90):
            f.step(Reference(np.array([0, 0, 1.5]) + offset, yaw=yaw))
        c, s = np.cos(yaw), np.sin(yaw)
        tracks.append(np.array([[c, s, 0], [-s, c, 0], [0, 0, 1]]) @ f.state[:3])
    np.testing.assert_allclose(tracks[0], tracks[1], atol=1e-9)


def _track_circle(feedforward: bool) -> tuple[float, float]:
    f = Flight(CFG, buffer_size=0, seed=0)
    path = ExplorationPath(name="circle", center=(0, 0, 1.5), amplitude=(0.5, 0.5, 0.1),
                           omega=(2.5, 2.5, 1.0), phase=(0, -np.pi / 2, 0), yaw_rate=0.5,
                           duration=4.0)  # fmt: skip
    ref0 = path.reference(0.0)
    f.reset(np.r_[ref0.position, ref0.velocity, np.zeros(6)])
    errors, speeds = [], []
    for _ in range(int(4.0 * CFG.camera.fps)):
        r = path.reference(f.time)
        if feedforward:
            f.step(path.reference)
        else:
            f.step(lambda t: Reference(path.reference(t).position, path.reference(t).velocity,
                                       path.reference(t).yaw))  # fmt: skip
        errors.append(np.linalg.norm(f.state[:3] - path.reference(f.time).position))
        speeds.append(np.linalg.norm(r.velocity))
    return float(np.max(errors[60:])), float(np.median(speeds))


def test_feedforward_tracks_a_fast_path_to_a_few_centimetres():
    # a 0.5 m circle at 1.25 m/s (3.1 m/s^2 centripetal) while spinning at 0.5 rad/s
    err_ff, speed = _track_circle(feedforward=True)
    err_plain, _ = _track_circle(feedforward=False)
    assert speed > 1.2
    assert err_ff < 0.06  # after the first second
    assert err_ff < 0.3 * err_plain  # the feedforward is what does it


def test_follow_matches_stepping_with_the_path_reference():
    path = ExplorationPath(name="wave", center=(0, 0, 1.5), amplitude=(0.3, 0.2, 0.2),
                           omega=(2.0, 1.0, 1.5), phase=(0.3, 0.0, 1.0), yaw_amplitude=0.4,
                           yaw_omega=1.0, duration=1.0)  # fmt: skip
    a, b = Flight(CFG, buffer_size=0), Flight(CFG, buffer_size=0)
    x0 = hover_state((0.1, 0.0, 1.6))
    a.reset(x0)
    b.reset(x0)
    for _ in a.follow(path):
        b.step(path.reference)
    np.testing.assert_allclose(a.state, b.state, atol=1e-12)


def test_motors_off_falls_and_lands(flight):
    flight.reset(hover_state((0.2, 0.1, 1.0)))
    landing = flight.cut_motors()
    assert landing.landed and flight.on_ground
    assert landing.elapsed == pytest.approx(np.sqrt(2 * 1.0 / CFG.quad.gravity), abs=0.03)
    np.testing.assert_allclose(landing.position, [0.2, 0.1, 0.0], atol=1e-9)
    with pytest.raises(InvalidInputError, match="motors are off"):
        flight.fly_to((0, 0, 1))


def test_fly_to_refuses_points_outside_the_workspace(flight):
    flight.reset(hover_state((0, 0, 1)))
    with pytest.raises(InvalidInputError, match="outside the workspace"):
        flight.fly_to((0, 0, 3.5))


def test_fly_to_reports_not_settled_when_out_of_time(flight):
    flight.reset(hover_state((0, 0, 1)))
    result = flight.fly_to((2.0, 0, 1), max_time=0.5)
    assert not result.settled and result.elapsed == pytest.approx(0.5, abs=1 / 60)


def test_lqr_params_validate_themselves():
    with pytest.raises(InvalidInputError, match="q_position must be 3 positive"):
        LqrParams.defaults(q_position=(1.0, 2.0))
    with pytest.raises(InvalidInputError, match="max_position_error_xy"):
        LqrParams.defaults(max_position_error_xy=0.0)
