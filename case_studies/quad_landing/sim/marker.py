"""The landing pad: the ArUco marker on a white square, and where it lies in the world.

Marker frame M: origin at the marker centre, ``x`` right and ``y`` up in the marker
image, ``z`` out of the pad (up in W for a pad on the floor). Its corners, in the order
ArUco reports them, are ``(-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2)``.
The marker itself is :class:`case_studies.quad_landing.perception.marker.MarkerParams`;
the camera image of the pad is drawn by :mod:`case_studies.quad_landing.sim.camera.render`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection
from case_studies.quad_landing.sim.frames import Pose, rot_z
from ipcverify.errors import InvalidInputError

__all__ = ["Pad"]


@dataclass(frozen=True)
class Pad(TomlSection, file=DEFAULTS_PATH, section="pad"):
    """Where the pad lies: centre position in W (m) and heading ``yaw`` (rad) about ``z_W``.

    Examples
    --------
    >>> Pad((0.5, -0.2, 0.0), yaw=0.0).world_from_marker().t
    array([ 0.5, -0.2,  0. ])
    >>> Pad.defaults().yaw  # [pad] of defaults.toml
    0.3
    """

    position: FloatArray
    yaw: float

    def __post_init__(self) -> None:
        p = np.array(self.position, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidInputError(f"pad position must be 3 finite numbers, got {self.position}")
        if not np.isfinite(self.yaw):
            raise InvalidInputError(f"pad yaw must be finite, got {self.yaw}")
        p.setflags(write=False)
        object.__setattr__(self, "position", p)
        object.__setattr__(self, "yaw", float(self.yaw))

    def to_table(self) -> dict[str, Any]:
        """Plain data in the layout of the ``[pad]`` table."""
        return {"position": self.position.tolist(), "yaw": self.yaw}

    def world_from_marker(self) -> Pose:
        """``T_WM``: the pad lies flat, marker ``z`` up."""
        return Pose._trusted(rot_z(self.yaw), self.position)
