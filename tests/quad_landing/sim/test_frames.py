"""Frames W, Q, C: rotations, poses, the camera mount, projection and x_C features."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing import Flight, hover_state, load_config
from case_studies.quad_landing.sim.camera.features import camera_frame_state, camera_velocity_world
from case_studies.quad_landing.sim.camera.pinhole import Camera, CameraParams
from case_studies.quad_landing.sim.frames import (
    Pose,
    euler_to_matrix,
    matrix_to_euler,
    mount_rotation,
    world_from_quad,
    wrap_angle,
)
from ipcverify.errors import InvalidInputError

CFG = load_config()
CAM = Camera(CFG.camera)
angle = st.floats(-np.pi, np.pi, allow_nan=False)
coord = st.floats(-5, 5, allow_nan=False)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(roll=angle, pitch=st.floats(-1.5, 1.5), yaw=angle)
def test_euler_round_trip(roll, pitch, yaw):
    R = euler_to_matrix(roll, pitch, yaw)
    np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-12)
    back = matrix_to_euler(R)
    np.testing.assert_allclose(wrap_angle(back - [roll, pitch, yaw]), 0.0, atol=1e-9)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(r1=angle, p1=st.floats(-1.5, 1.5), y1=angle, r2=angle, p2=st.floats(-1.5, 1.5), y2=angle,
       t1=st.tuples(coord, coord, coord), t2=st.tuples(coord, coord, coord),
       pt=st.tuples(coord, coord, coord))  # fmt: skip
def test_pose_inverse_and_compose_round_trip(r1, p1, y1, r2, p2, y2, t1, t2, pt):
    A = Pose(euler_to_matrix(r1, p1, y1), t1)
    B = Pose(euler_to_matrix(r2, p2, y2), t2)
    p = np.array(pt)
    np.testing.assert_allclose(A.inverse().apply(A.apply(p)), p, atol=1e-9)
    np.testing.assert_allclose(A.compose(B).apply(p), A.apply(B.apply(p)), atol=1e-9)
    np.testing.assert_allclose(A.compose(A.inverse()).matrix(), np.eye(4), atol=1e-9)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(p=st.tuples(st.floats(-3, 3), st.floats(-3, 3), st.floats(0.5, 3)),
       att=st.tuples(st.floats(-0.5, 0.5), st.floats(-0.5, 0.5), angle),
       point=st.tuples(coord, coord, st.floats(0, 0.5)))  # fmt: skip
def test_world_quad_camera_transforms_round_trip(p, att, point):
    x = np.r_[p, np.zeros(3), att, np.zeros(3)]
    T_WQ, T_QC = world_from_quad(x), CAM.quad_from_camera
    T_WC = CAM.world_from_camera(x)
    y_w = np.array(point)
    y_c = T_WC.inverse().apply(y_w)
    y_q = T_WQ.inverse().apply(y_w)
    np.testing.assert_allclose(T_QC.apply(y_c), y_q, atol=1e-9)
    np.testing.assert_allclose(T_WC.apply(y_c), y_w, atol=1e-9)
    # the camera centre is the mount offset, carried by the body
    np.testing.assert_allclose(T_WC.t, T_WQ.apply(np.asarray(CFG.camera.offset)), atol=1e-12)


def test_mount_rotation_axes():
    down, fwd = mount_rotation(90.0), mount_rotation(0.0)
    # downward camera: optical axis -z_Q, image up (-y_C) is the nose x_Q, image right -y_Q
    np.testing.assert_allclose(down @ [0, 0, 1], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(down @ [0, -1, 0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(down @ [1, 0, 0], [0, -1, 0], atol=1e-12)
    # forward camera: optical axis x_Q, image up z_Q
    np.testing.assert_allclose(fwd @ [0, 0, 1], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(fwd @ [0, -1, 0], [0, 0, 1], atol=1e-12)
    for tilt in np.linspace(0, 90, 7):
        R = mount_rotation(tilt)
        assert np.linalg.det(R) == pytest.approx(1.0)
    with pytest.raises(InvalidInputError, match=r"tilt must be in \[0, 90\]"):
        mount_rotation(120.0)


def test_pose_refuses_non_rotations():
    with pytest.raises(InvalidInputError, match="not a rotation"):
        Pose(np.diag([1.0, 1.0, -1.0]), np.zeros(3))
    with pytest.raises(InvalidInputError, match="3 finite numbers"):
        Pose(np.eye(3), [0.0, np.nan, 0.0])


def test_projection_and_view_check():
    pts = np.array([[0.1, -0.2, 2.0], [0.0, 0.0, 1.0]])
    uv = CAM.project(pts)
    p = CFG.camera
    np.testing.assert_allclose(uv[0], [p.fx * 0.05 + p.cx, -p.fy * 0.1 + p.cy])
    assert CAM.in_view(pts)
    assert not CAM.in_view(np.array([[5.0, 0.0, 1.0]]))
    assert not CAM.in_view(np.array([[0.0, 0.0, -1.0]]))
    with pytest.raises(InvalidInputError, match="behind the camera"):
        CAM.project(np.array([[0.0, 0.0, -1.0]]))


def test_camera_params_validate():
    with pytest.raises(InvalidInputError, match="principal point"):
        CameraParams.defaults(cx=400.0, cy=120.0)


def test_x_c_of_a_level_hover_with_the_downward_camera():
    x = hover_state((1.0, -0.5, 1.55), yaw=0.7)
    x_c, T_WC = camera_frame_state(x, CAM)
    np.testing.assert_allclose(x_c[0:3], [0, 0, 1.5], atol=1e-12)  # 5 cm below the body
    np.testing.assert_allclose(x_c[6:9], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(x_c[[3, 4, 5, 9, 10, 11]], 0.0, atol=1e-12)
    # the pad straight below is straight along the optical axis
    pad_c = T_WC.inverse().apply([1.0, -0.5, 0.0])
    np.testing.assert_allclose(pad_c, [0, 0, 1.5], atol=1e-12)


def test_x_c_velocity_and_rates_in_camera_axes():
    x = hover_state((0, 0, 1.0))
    x[3] = 1.0  # flying forward (nose) at 1 m/s
    x[11] = 0.5  # yawing left
    x_c, _ = camera_frame_state(x, CAM)
    # image up is the nose, so forward motion is -y_C; yaw about z_Q is -z_C
    np.testing.assert_allclose(x_c[3:6], [0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(x_c[9:12], [0, 0, -0.5], atol=1e-12)
    assert np.linalg.norm(x_c[6:9]) == pytest.approx(1.0)
    assert np.linalg.norm(x_c[0:3]) == pytest.approx(0.95)


def test_x_c_carries_the_lag_kinematics():
    """d/dt y_C = -omega_C x y_C - v_C, checked against the simulated motion."""
    f = Flight(CFG, buffer_size=0, seed=0)
    x0 = hover_state((0.1, -0.1, 1.5), yaw=0.3)
    x0[3:6] = [0.6, -0.3, 0.2]
    x0[9:12] = [0.4, -0.3, 0.6]
    f.reset(x0)
    m0 = f.measure()
    # one short physics step with the motors at hover thrust barely changes v and omega
    from case_studies.quad_landing.sim.dynamics import hover_thrust, rk4_step

    dt = 1e-4
    x1 = np.asarray(rk4_step(CFG.quad, dt)(x0, np.full(4, hover_thrust(CFG.quad)))).ravel()
    y1 = CAM.world_from_camera(x1).inverse().apply(CFG.pad.position)
    predicted = -np.cross(m0.x_c[9:12], m0.y_c) - m0.x_c[3:6]
    np.testing.assert_allclose((y1 - m0.y_c) / dt, predicted, rtol=1e-3, atol=1e-3)
    # and the camera velocity in W is the body velocity plus omega x offset
    v_cam = camera_velocity_world(x0, CAM)
    R = world_from_quad(x0).R
    np.testing.assert_allclose(v_cam, x0[3:6] + R @ np.cross(x0[9:12], CFG.camera.offset))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(att=st.tuples(angle, st.floats(-1.5, 1.5), angle), t=st.tuples(coord, coord, coord),
       seed=st.integers(0, 10_000))  # fmt: skip
def test_ellipsoid_moves_with_its_points(att, t, seed):
    from case_studies.quad_landing.sim.frames import transform_ellipsoid

    rng = np.random.default_rng(seed)
    T = Pose(euler_to_matrix(*att), t)
    c, C = rng.normal(size=3), rng.normal(size=(3, 3)) + 3 * np.eye(3)
    pts = c + rng.normal(size=(50, 3)) * 0.5
    inside_b = np.linalg.norm((pts - c) @ C.T, axis=1)
    cw, Cw = transform_ellipsoid(c, C, T)
    inside_a = np.linalg.norm((T.apply(pts) - cw) @ Cw.T, axis=1)
    np.testing.assert_allclose(inside_a, inside_b, rtol=1e-9, atol=1e-9)


def test_pad_in_view_matches_the_geometry():
    f = Flight(CFG, buffer_size=0)
    f.reset(hover_state((0.0, 0.0, 1.0)))
    assert f.pad_in_view()
    assert not f.pad_in_view(hover_state((1.5, 0.0, 1.0)))
    assert not f.pad_in_view(hover_state((0.0, 0.0, 0.3)))  # too close: pad bigger than view
