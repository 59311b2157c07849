"""Pinhole camera: intrinsics, mount (extrinsics) and the camera pose for a quadrotor state.

The default is the paper's 320 x 240 camera at 60 fps with a wide-angle lens
(``fx = fy = 220`` px, about 72 x 57 degrees field of view) mounted looking straight
down (``tilt_deg = 90``) 5 cm below the centre of mass. A downward camera keeps the pad
in view whenever the quadrotor is above it and on the straight approach the landing
algorithm flies (the bearing to the pad does not change along the line of sight).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection, check_positive
from case_studies.quad_landing.sim.frames import Pose, mount_rotation, world_from_quad
from ipcverify.errors import InvalidInputError

__all__ = ["CameraParams", "Camera"]


@dataclass(frozen=True, kw_only=True)
class CameraParams(TomlSection, file=DEFAULTS_PATH, section="camera"):
    """Intrinsics and mount of the camera.

    Parameters
    ----------
    width, height : int
        Image size (px).
    fps : float
        Frame rate (Hz).
    fx, fy, cx, cy : float
        Pinhole intrinsics (px); pixel centres are at integer coordinates, so the
        image centre is ``((width - 1) / 2, (height - 1) / 2)``.
    tilt_deg : float
        Downward pitch of the optical axis: 0 forward, 90 straight down.
    offset : tuple of 3 floats
        Camera centre in the body frame Q (m).

    Examples
    --------
    >>> CameraParams.defaults().tilt_deg  # [camera] of defaults.toml: looking straight down
    90.0
    >>> CameraParams.defaults(fx=250.0).fx
    250.0
    """

    width: int
    height: int
    fps: float
    fx: float
    fy: float
    cx: float
    cy: float
    tilt_deg: float
    offset: tuple[float, float, float]

    def __post_init__(self) -> None:
        for name in ("width", "height"):
            value = getattr(self, name)
            if int(value) != value or value < 16:
                raise InvalidInputError(f"camera.{name} must be an integer >= 16, got {value}")
            object.__setattr__(self, name, int(value))
        for name in ("fps", "fx", "fy"):
            value = float(getattr(self, name))
            check_positive(f"camera.{name}", value)
            object.__setattr__(self, name, value)
        if not (0 <= self.cx <= self.width - 1 and 0 <= self.cy <= self.height - 1):
            raise InvalidInputError(
                f"camera principal point ({self.cx}, {self.cy}) must lie inside the "
                f"{self.width} x {self.height} image"
            )
        object.__setattr__(self, "cx", float(self.cx))
        object.__setattr__(self, "cy", float(self.cy))
        object.__setattr__(self, "tilt_deg", float(self.tilt_deg))
        mount_rotation(self.tilt_deg)  # validates the range
        offset = tuple(float(v) for v in self.offset)
        if len(offset) != 3 or not all(np.isfinite(offset)):
            raise InvalidInputError(f"camera.offset must be 3 finite numbers, got {self.offset}")
        object.__setattr__(self, "offset", offset)


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera rigidly mounted on the quadrotor.

    Parameters
    ----------
    params : CameraParams
        Intrinsics and mount.

    Examples
    --------
    >>> cam = Camera(CameraParams.defaults())  # 320 x 240, centre (159.5, 119.5)
    >>> cam.project(np.array([[0.0, 0.0, 2.0]]))  # a point on the optical axis
    array([[159.5, 119.5]])
    """

    params: CameraParams

    @cached_property
    def K(self) -> FloatArray:
        """The 3x3 intrinsic matrix."""
        p = self.params
        K = np.array([[p.fx, 0.0, p.cx], [0.0, p.fy, p.cy], [0.0, 0.0, 1.0]])
        K.setflags(write=False)
        return K

    @cached_property
    def quad_from_camera(self) -> Pose:
        """``T_QC``, the mount: camera coordinates to body coordinates."""
        return Pose(mount_rotation(self.params.tilt_deg), np.asarray(self.params.offset))

    @property
    def frame_period(self) -> float:
        """Time between frames (s)."""
        return 1.0 / self.params.fps

    def world_from_camera(self, state: ArrayLike) -> Pose:
        """``T_WC = T_WQ(state) T_QC``: camera coordinates to world coordinates."""
        return world_from_quad(state).compose(self.quad_from_camera)

    def project(self, points_c: ArrayLike) -> FloatArray:
        """Project points in C, shape ``(N, 3)`` with ``z > 0``, to pixels ``(N, 2)``."""
        pts = np.asarray(points_c, dtype=np.float64).reshape(-1, 3)
        if np.any(pts[:, 2] <= 0):
            raise InvalidInputError(
                "cannot project points at or behind the camera (z_C <= 0); "
                "check visibility with Camera.in_view first"
            )
        p = self.params
        return np.column_stack([p.fx * pts[:, 0] / pts[:, 2] + p.cx, p.fy * pts[:, 1] / pts[:, 2] + p.cy])

    def in_view(self, points_c: ArrayLike, margin_px: float = 0.0, near: float = 0.05) -> bool:
        """True if every point is at least ``near`` m in front and ``margin_px`` inside the image."""
        pts = np.asarray(points_c, dtype=np.float64).reshape(-1, 3)
        if np.any(pts[:, 2] < near):
            return False
        uv = self.project(pts)
        p = self.params
        lo = -0.5 + margin_px
        return bool(
            np.all(uv[:, 0] >= lo)
            and np.all(uv[:, 0] <= p.width - 0.5 - margin_px)
            and np.all(uv[:, 1] >= lo)
            and np.all(uv[:, 1] <= p.height - 0.5 - margin_px)
        )
