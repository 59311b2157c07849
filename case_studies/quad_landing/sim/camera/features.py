"""The quadrotor state expressed in the camera frame, ``x_C`` (the IPC's state input).

The paper learns the IPC in the camera frame so that it does not depend on where the
camera is mounted. ``x_C`` keeps the 12-number layout of the state ``[p, v, phi, omega]``
but every part is a frame-free, camera-frame quantity; nothing in it depends on the
world's horizontal origin or heading, so it carries no hint of where the pad is (the
columns are those of the datasets, :data:`case_studies.quad_landing.data.columns.X_COLUMNS`):

========  ===========  ============================================================
column    symbol       meaning
========  ===========  ============================================================
x_0..x_2  ``n_C``      nadir vector: from the camera centre straight down to the
                       floor, in C (m). Its norm is the camera height above the
                       floor; its direction is gravity's.
x_3..x_5  ``v_C``      velocity of the camera centre relative to W, in C (m/s):
                       ``R_CW (v + R_WQ (omega x t_QC))``.
x_6..x_8  ``g_C``      unit "down" direction in C (camera roll/pitch; equals
                       ``n_C / |n_C|``, kept separately so attitude is explicit
                       and well scaled).
x_9..x_11 ``omega_C``  angular velocity of the camera (= of the body) in C (rad/s):
                       ``R_QC^T omega``.
========  ===========  ============================================================

For a pad fixed in W, ``d/dt y_C = -omega_C x y_C - v_C``, so a camera image that is
``tau`` seconds old sees the pad displaced by about ``tau (omega_C x y_C + v_C)``: the
lag error is predicted by ``v_C``, ``omega_C`` and ``yhat_C``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.sim.camera.pinhole import Camera
from case_studies.quad_landing.sim.frames import Pose, world_from_quad

__all__ = ["camera_frame_state", "camera_velocity_world"]


def camera_velocity_world(state: ArrayLike, camera: Camera) -> FloatArray:
    """Velocity of the camera centre in W (m/s): ``v + R_WQ (omega x t_QC)``."""
    x = np.asarray(state, dtype=np.float64).reshape(12)
    R_WQ = world_from_quad(x).R
    return x[3:6] + R_WQ @ np.cross(x[9:12], np.asarray(camera.params.offset))


def camera_frame_state(state: ArrayLike, camera: Camera, ground_z: float = 0.0) -> tuple[FloatArray, Pose]:
    """``x_C`` (12,) for a world-frame state, and the camera pose ``T_WC`` used.

    Parameters
    ----------
    state : array_like, shape (12,)
        ``[p, v, (roll, pitch, yaw), omega]`` in W (omega in Q).
    camera : Camera
        The camera and its mount.
    ground_z : float
        Height of the floor in W (m).

    Returns
    -------
    x_c : ndarray, shape (12,)
        See the module docstring for the columns.
    world_from_camera : Pose
        ``T_WC`` at this state.

    Examples
    --------
    >>> from case_studies.quad_landing.sim.config import load_config
    >>> cam = Camera(load_config().camera)  # downward camera, 5 cm below the body
    >>> x_c, T_WC = camera_frame_state(np.r_[0, 0, 1.05, np.zeros(9)], cam)
    >>> np.round(x_c[:3], 12)  # 1 m straight down the optical axis
    array([0., 0., 1.])
    """
    x = np.asarray(state, dtype=np.float64).reshape(12)
    T_WC = camera.world_from_camera(x)
    R_CW = T_WC.R.T
    down_c = R_CW @ np.array([0.0, 0.0, -1.0])
    height = T_WC.t[2] - ground_z
    x_c = np.empty(12)
    x_c[0:3] = height * down_c
    x_c[3:6] = R_CW @ camera_velocity_world(x, camera)
    x_c[6:9] = down_c
    x_c[9:12] = camera.quad_from_camera.R.T @ x[9:12]
    return x_c, T_WC
