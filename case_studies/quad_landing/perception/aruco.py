"""ArUco perception: detect the pad's marker and estimate its position ``yhat_C``.

Detection uses ``cv2.aruco.ArucoDetector`` (OpenCV >= 4.8 API) and pose uses
``cv2.solvePnP(..., flags=cv2.SOLVEPNP_IPPE_SQUARE)`` on the four corners; the
translation vector is the marker centre in the camera frame, ``yhat_C``.

Corner refinement matters: OpenCV's default (no refinement, the case study's default:
what the paper's OpenCV calls ran), contour corners and plain sub-pixel refinement sit
slightly inside the black border, so the marker looks smaller and the range comes out too
long by 0.5-3 % (comparable to the lag error this case study is about). AprilTag refinement
(``CORNER_REFINE_APRILTAG``) fits lines to the edges and is unbiased; raising
``aprilTagMinWhiteBlackDiff`` from its default 5 to 30 skips low-contrast clusters and
makes it about 15x faster with the same accuracy. Its corners come out about half a
pixel right and down of OpenCV's pixel-centre convention, which is corrected
(:attr:`DetectorParams.april_tag_corner_shift_px`). ``python -m case_studies.quad_landing
bias`` measures all this (numbers in docs/case_study.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import cv2
import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.perception.marker import MarkerParams, aruco_dictionary
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection
from ipcverify.errors import InvalidInputError

__all__ = ["DetectorParams", "ArucoPerception", "Intrinsics", "REFINEMENTS"]


#: Corner refinement names accepted by :class:`DetectorParams` and their OpenCV flags.
REFINEMENTS: dict[str, int] = {
    "none": cv2.aruco.CORNER_REFINE_NONE,
    "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
    "contour": cv2.aruco.CORNER_REFINE_CONTOUR,
    "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG,
}


@dataclass(frozen=True, kw_only=True)
class DetectorParams(TomlSection, file=DEFAULTS_PATH, section="detector"):
    """ArUco detector settings.

    Parameters
    ----------
    corner_refinement : {"apriltag", "subpix", "contour", "none"}
        Corner refinement method: "none" is OpenCV's default (ranges read long), "apriltag" the unbiased one.
    april_tag_min_white_black_diff : int
        ``aprilTagMinWhiteBlackDiff`` (grey levels); larger is faster but misses
        low-contrast markers.
    min_marker_perimeter_rate : float
        ``minMarkerPerimeterRate``: smallest marker perimeter as a fraction of the
        larger image side.
    april_tag_corner_shift_px : float
        Subtracted from both coordinates of AprilTag-refined corners. They come out
        about half a pixel down-right of OpenCV's pixel-centre convention (measured on
        noise-free renders, where the true corners are known: +0.41..+0.46 px), which
        shifts ``yhat_C`` sideways by 0.2 % of the range; 0.5 removes it.

    Examples
    --------
    >>> DetectorParams.defaults().corner_refinement  # OpenCV's default
    'none'
    """

    corner_refinement: str
    april_tag_min_white_black_diff: int
    min_marker_perimeter_rate: float
    april_tag_corner_shift_px: float

    def __post_init__(self) -> None:
        if self.corner_refinement not in REFINEMENTS:
            raise InvalidInputError(
                f"detector.corner_refinement must be one of {sorted(REFINEMENTS)}, "
                f"got {self.corner_refinement!r}"
            )
        diff = self.april_tag_min_white_black_diff
        if int(diff) != diff or not 0 <= diff <= 255:
            raise InvalidInputError(
                f"detector.april_tag_min_white_black_diff must be an integer in [0, 255], got {diff}"
            )
        shift = self.april_tag_corner_shift_px
        if not (np.isfinite(shift) and abs(shift) <= 1.0):
            raise InvalidInputError(f"detector.april_tag_corner_shift_px must be in [-1, 1] px, got {shift}")
        rate = self.min_marker_perimeter_rate
        if not (np.isfinite(rate) and 0 < rate < 4):
            raise InvalidInputError(f"detector.min_marker_perimeter_rate must be in (0, 4), got {rate}")


class Intrinsics(Protocol):
    """What the detector needs of a camera: its intrinsic matrix ``K`` (3 x 3, no distortion).

    The simulator's :class:`~case_studies.quad_landing.sim.camera.Camera` is one; the
    detector does not depend on the simulator.
    """

    @property
    def K(self) -> FloatArray:
        """The intrinsic matrix, shape (3, 3)."""
        ...


@dataclass(eq=False)
class ArucoPerception:
    """The perception module: image in, pad position in the camera frame out.

    Parameters
    ----------
    camera : Intrinsics
        The camera whose intrinsics ``solvePnP`` uses (no distortion).
    marker : MarkerParams
        Which marker to look for and its size.
    params : DetectorParams
        Detector settings.

    Examples
    --------
    >>> from case_studies.quad_landing.sim.camera import Camera
    >>> from case_studies.quad_landing.sim.config import load_config
    >>> cfg = load_config()
    >>> perception = ArucoPerception(Camera(cfg.camera), cfg.marker, cfg.detector)
    >>> perception.estimate(np.full((240, 320), 128, np.uint8)) is None  # nothing there
    True
    """

    camera: Intrinsics
    marker: MarkerParams
    params: DetectorParams
    _detector: cv2.aruco.ArucoDetector = field(init=False, repr=False)

    def __post_init__(self) -> None:
        p = cv2.aruco.DetectorParameters()
        p.cornerRefinementMethod = REFINEMENTS[self.params.corner_refinement]
        p.aprilTagMinWhiteBlackDiff = int(self.params.april_tag_min_white_black_diff)
        p.minMarkerPerimeterRate = float(self.params.min_marker_perimeter_rate)
        self._detector = cv2.aruco.ArucoDetector(aruco_dictionary(self.marker.dictionary), p)

    def detect(self, image: NDArray[np.uint8]) -> FloatArray | None:
        """Image corners (4, 2) of the pad's marker, in ArUco order, or None if not found."""
        corners, ids, _ = self._detector.detectMarkers(image)
        if ids is None:
            return None
        for c, i in zip(corners, ids.ravel(), strict=True):
            if int(i) == int(self.marker.marker_id):
                out = np.asarray(c, dtype=np.float64).reshape(4, 2)
                if self.params.corner_refinement == "apriltag":
                    out -= self.params.april_tag_corner_shift_px
                return out
        return None

    def pose_from_corners(self, corners: FloatArray) -> tuple[FloatArray, FloatArray] | None:
        """``(R_CM, t_CM)`` from four image corners with ``SOLVEPNP_IPPE_SQUARE``, or None."""
        ok, rvec, tvec = cv2.solvePnP(
            self.marker.object_points(), corners, self.camera.K, None,
            flags=cv2.SOLVEPNP_IPPE_SQUARE,
        )  # fmt: skip
        t = np.asarray(tvec, dtype=np.float64).reshape(3)
        if not ok or not np.all(np.isfinite(t)) or t[2] <= 0:
            return None
        R, _ = cv2.Rodrigues(rvec)
        return np.asarray(R, dtype=np.float64), t

    def estimate(self, image: NDArray[np.uint8]) -> FloatArray | None:
        """``yhat_C``, the marker centre in the camera frame (m), or None if not detected."""
        corners = self.detect(image)
        if corners is None:
            return None
        pose = self.pose_from_corners(corners)
        return None if pose is None else pose[1]
