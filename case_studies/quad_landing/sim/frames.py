"""Coordinate frames W (world), Q (quadrotor body) and C (camera), and moves between them.

Conventions
-----------
* **W** — world, right-handed, ``z`` up, origin on the floor. The workspace is
  ``[-3, 3] x [-3, 3] x [0, 3]`` m.
* **Q** — quadrotor body: origin at the centre of mass, ``x`` forward, ``y`` left,
  ``z`` up (FLU). Its attitude is the ZYX Euler triple (roll ``phi``, pitch ``theta``,
  yaw ``psi``): ``R_WQ = Rz(psi) @ Ry(theta) @ Rx(phi)``.
* **C** — camera, the OpenCV convention: ``x`` right in the image, ``y`` down in the
  image, ``z`` along the optical axis. ``R_QC`` and ``t_QC`` are the mount
  (extrinsics); see :func:`mount_rotation`.

A :class:`Pose` ``T_AB = (R_AB, t_AB)`` maps coordinates in frame B to frame A:
``p_A = R_AB @ p_B + t_AB``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from ipcverify.errors import InvalidInputError

__all__ = [
    "Pose",
    "rot_x",
    "rot_y",
    "rot_z",
    "euler_to_matrix",
    "matrix_to_euler",
    "mount_rotation",
    "wrap_angle",
    "world_from_quad",
    "transform_ellipsoid",
]


#: Tolerance on ``||R^T R - I||`` and ``|det R - 1|`` for a matrix to count as a rotation.
ROTATION_TOL = 1e-6


def rot_x(angle: float) -> FloatArray:
    """Rotation by ``angle`` (rad) about the x axis.

    Examples
    --------
    >>> rot_x(np.pi / 2) @ np.array([0.0, 1.0, 0.0])  # y goes to z
    array([0.000000e+00, 6.123234e-17, 1.000000e+00])
    """
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> FloatArray:
    """Rotation by ``angle`` (rad) about the y axis.

    Examples
    --------
    >>> np.round(rot_y(np.pi / 2) @ np.array([0.0, 0.0, 1.0]), 12)  # z goes to x
    array([1., 0., 0.])
    """
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> FloatArray:
    """Rotation by ``angle`` (rad) about the z axis.

    Examples
    --------
    >>> np.round(rot_z(np.pi / 2) @ np.array([1.0, 0.0, 0.0]), 12)  # x goes to y
    array([0., 1., 0.])
    """
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def euler_to_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """ZYX Euler angles (rad) to the rotation ``R_WQ = Rz(yaw) Ry(pitch) Rx(roll)``.

    Examples
    --------
    >>> R = euler_to_matrix(0.1, -0.2, 0.3)
    >>> np.allclose(matrix_to_euler(R), [0.1, -0.2, 0.3])
    True
    """
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def matrix_to_euler(R: ArrayLike) -> FloatArray:
    """Inverse of :func:`euler_to_matrix` for ``|pitch| < pi/2``; returns ``[roll, pitch, yaw]``.

    Examples
    --------
    >>> matrix_to_euler(np.eye(3)).tolist()
    [0.0, -0.0, 0.0]
    """
    m = np.asarray(R, dtype=np.float64)
    pitch = float(np.arcsin(np.clip(-m[2, 0], -1.0, 1.0)))
    roll = float(np.arctan2(m[2, 1], m[2, 2]))
    yaw = float(np.arctan2(m[1, 0], m[0, 0]))
    return np.array([roll, pitch, yaw])


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles (rad) into ``[-pi, pi)``.

    Examples
    --------
    >>> float(wrap_angle(3 * np.pi / 2))
    -1.5707963267948966
    """
    a = np.asarray(angle, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def mount_rotation(tilt_deg: float) -> FloatArray:
    """Camera mount rotation ``R_QC`` for a camera pitched down by ``tilt_deg`` degrees.

    ``tilt_deg = 0`` is a forward camera (optical axis along ``x_Q``, image up along
    ``z_Q``); ``tilt_deg = 90`` is a downward camera (optical axis along ``-z_Q``, image
    up along ``x_Q``, the nose). In both, image right is the vehicle's right (``-y_Q``).

    Parameters
    ----------
    tilt_deg : float
        Downward pitch of the optical axis below the body's ``x`` axis, in ``[0, 90]``.

    Returns
    -------
    ndarray, shape (3, 3)
        The columns are the camera axes ``x_C, y_C, z_C`` expressed in Q.

    Examples
    --------
    >>> np.round(mount_rotation(90.0), 12) + 0.0  # + 0.0 turns -0. into 0.
    array([[ 0., -1.,  0.],
           [-1.,  0.,  0.],
           [ 0.,  0., -1.]])
    """
    if not (0.0 <= tilt_deg <= 90.0):
        raise InvalidInputError(
            f"camera tilt must be in [0, 90] degrees (0 = forward, 90 = down), got {tilt_deg}"
        )
    a = np.deg2rad(tilt_deg)
    z_c = np.array([np.cos(a), 0.0, -np.sin(a)])
    x_c = np.array([0.0, -1.0, 0.0])
    y_c = np.cross(z_c, x_c)
    return np.column_stack([x_c, y_c, z_c])


def _check_rotation(R: FloatArray, name: str) -> None:
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise InvalidInputError(f"{name} must be a finite 3x3 matrix, got shape {R.shape}")
    if np.linalg.norm(R.T @ R - np.eye(3)) > ROTATION_TOL or abs(np.linalg.det(R) - 1.0) > ROTATION_TOL:
        raise InvalidInputError(
            f"{name} is not a rotation (R^T R != I or det R != 1); "
            "orthonormalise it (e.g. with scipy.spatial.transform.Rotation) first"
        )


@dataclass(frozen=True, eq=False)
class Pose:
    """A rigid transform ``T_AB``: ``p_A = R @ p_B + t``.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Rotation from B to A (checked to be a rotation to ``1e-6``).
    t : array_like, shape (3,)
        Origin of B expressed in A.

    Examples
    --------
    >>> T = Pose(rot_z(np.pi / 2), np.array([1.0, 0.0, 0.0]))
    >>> np.round(T.apply(np.array([1.0, 0.0, 0.0])), 12)
    array([1., 1., 0.])
    >>> np.allclose(T.inverse().apply(T.apply(np.ones(3))), np.ones(3))
    True
    """

    R: FloatArray
    t: FloatArray

    def __post_init__(self) -> None:
        R = np.array(self.R, dtype=np.float64, copy=True)
        t = np.array(self.t, dtype=np.float64, copy=True).reshape(-1)
        _check_rotation(R, "Pose.R")
        if t.shape != (3,) or not np.all(np.isfinite(t)):
            raise InvalidInputError(f"Pose.t must be 3 finite numbers, got {self.t!r}")
        R.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "t", t)

    @classmethod
    def _trusted(cls, R: FloatArray, t: FloatArray) -> Pose:
        """Build without checks from arrays that are a rotation and a 3-vector by construction."""
        pose = object.__new__(cls)
        R = np.array(R, dtype=np.float64)
        t = np.array(t, dtype=np.float64)
        R.setflags(write=False)
        t.setflags(write=False)
        object.__setattr__(pose, "R", R)
        object.__setattr__(pose, "t", t)
        return pose

    def apply(self, points: ArrayLike) -> FloatArray:
        """Map points in B (shape ``(3,)`` or ``(N, 3)``) to A."""
        p = np.asarray(points, dtype=np.float64)
        return p @ self.R.T + self.t

    def rotate(self, vectors: ArrayLike) -> FloatArray:
        """Rotate free vectors (velocities, directions) from B to A; no translation."""
        return np.asarray(vectors, dtype=np.float64) @ self.R.T

    def inverse(self) -> Pose:
        """``T_BA``, the transform from A back to B."""
        return Pose._trusted(self.R.T, -self.R.T @ self.t)

    def compose(self, other: Pose) -> Pose:
        """``T_AB.compose(T_BC) = T_AC``."""
        return Pose._trusted(self.R @ other.R, self.R @ other.t + self.t)

    def matrix(self) -> FloatArray:
        """The 4x4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.R
        m[:3, 3] = self.t
        return m


def world_from_quad(state: ArrayLike) -> Pose:
    """``T_WQ`` for a 12-state ``[p, v, (roll, pitch, yaw), omega]``.

    Examples
    --------
    >>> T = world_from_quad(np.r_[1.0, 2.0, 3.0, np.zeros(9)])
    >>> T.t
    array([1., 2., 3.])
    """
    x = np.asarray(state, dtype=np.float64).reshape(-1)
    if x.shape != (12,) or not np.all(np.isfinite(x)):
        raise InvalidInputError(f"a quadrotor state is 12 finite numbers, got shape {x.shape}")
    return Pose._trusted(euler_to_matrix(x[6], x[7], x[8]), x[0:3])


def transform_ellipsoid(center: ArrayLike, shape: ArrayLike, pose: Pose) -> tuple[FloatArray, FloatArray]:
    """Move the ellipsoid ``{y : ||C (y - c)|| <= 1}`` through ``p_A = R p_B + t``.

    The image is ``{y : ||C R^T (y - (R c + t))|| <= 1}``: centre ``R c + t`` and shape
    ``C R^T`` — e.g. an IPC ellipsoid in the camera frame to the world frame with
    ``pose = T_WC`` (:attr:`.flight.Measurement.world_from_camera`).

    Parameters
    ----------
    center : array_like, shape (3,)
        ``c`` in frame B.
    shape : array_like, shape (3, 3)
        ``C`` in frame B.
    pose : Pose
        ``T_AB``.

    Returns
    -------
    center_a, shape_a : ndarray
        ``R c + t`` and ``C R^T``.

    Examples
    --------
    >>> T = Pose(rot_z(np.pi / 2), np.array([1.0, 0.0, 0.0]))
    >>> c, C = transform_ellipsoid([0.0, 0.0, 0.0], np.diag([1.0, 2.0, 3.0]), T)
    >>> c.tolist(), np.round(np.diag(C @ C.T), 12).tolist()
    ([1.0, 0.0, 0.0], [1.0, 4.0, 9.0])
    """
    c = np.asarray(center, dtype=np.float64).reshape(3)
    C = np.asarray(shape, dtype=np.float64).reshape(3, 3)
    return pose.apply(c), C @ pose.R.T
