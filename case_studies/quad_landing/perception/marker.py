"""The ArUco marker on the pad: its dictionary, id and size, and its corners in the marker frame.

Marker frame M: origin at the marker centre, ``x`` right and ``y`` up in the marker
image, ``z`` out of the pad (up in W for a pad on the floor). Its corners, in the order
ArUco reports them, are ``(-s/2, s/2), (s/2, s/2), (s/2, -s/2), (-s/2, -s/2)``.
The detector (:mod:`.aruco`) looks for it; the simulator draws it
(:mod:`case_studies.quad_landing.sim.camera.render`) on the pad it places in the world
(:class:`case_studies.quad_landing.sim.marker.Pad`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import DEFAULTS_PATH, TomlSection
from ipcverify.errors import InvalidInputError

__all__ = ["MarkerParams", "aruco_dictionary", "MARKER_CELLS"]


#: Cells along one side of a 4x4 ArUco marker including its one-cell black border.
MARKER_CELLS = 6


def aruco_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The predefined ArUco dictionary called ``name`` (e.g. ``"DICT_4X4_50"``).

    Examples
    --------
    >>> aruco_dictionary("DICT_4X4_50").markerSize
    4
    """
    if not name.startswith("DICT_4X4_") or not hasattr(cv2.aruco, name):
        raise InvalidInputError(
            f"marker.dictionary must name a 4x4 ArUco dictionary such as DICT_4X4_50, got {name!r}"
        )
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, name))


@dataclass(frozen=True, kw_only=True)
class MarkerParams(TomlSection, file=DEFAULTS_PATH, section="marker"):
    """The ArUco marker on the pad.

    Parameters
    ----------
    dictionary : str
        A 4x4 ArUco dictionary name (``DICT_4X4_50``).
    marker_id : int
        Marker id in that dictionary.
    side : float
        Side of the black marker square (m).
    margin_cells : int
        White quiet zone around the marker, in marker cells (``side / 6`` each).

    Examples
    --------
    >>> round(MarkerParams.defaults(side=0.3).pad_side, 3)
    0.4
    """

    dictionary: str
    marker_id: int
    side: float
    margin_cells: int

    def __post_init__(self) -> None:
        d = aruco_dictionary(self.dictionary)
        n = d.bytesList.shape[0]
        if int(self.marker_id) != self.marker_id or not 0 <= self.marker_id < n:
            raise InvalidInputError(
                f"marker.marker_id must be an integer in [0, {n}) for {self.dictionary}, got {self.marker_id}"
            )
        if not (np.isfinite(self.side) and 0 < self.side <= 2.0):
            raise InvalidInputError(f"marker.side must be in (0, 2] m, got {self.side}")
        if int(self.margin_cells) != self.margin_cells or not 1 <= self.margin_cells <= 4:
            raise InvalidInputError(
                f"marker.margin_cells must be an integer in [1, 4] (the white quiet zone "
                f"ArUco needs), got {self.margin_cells}"
            )

    @property
    def cells(self) -> int:
        """Cells along one side of the pad texture (marker plus quiet zone)."""
        return MARKER_CELLS + 2 * int(self.margin_cells)

    @property
    def pad_side(self) -> float:
        """Side of the white pad square (m)."""
        return self.side * self.cells / MARKER_CELLS

    def pad_outline(self) -> FloatArray:
        """Corners of the white pad square in M, shape (4, 3), texture order."""
        h = self.pad_side / 2.0
        return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])

    def object_points(self) -> FloatArray:
        """Marker corners in M, shape (4, 3), in ArUco / ``SOLVEPNP_IPPE_SQUARE`` order."""
        h = self.side / 2.0
        return np.array([[-h, h, 0.0], [h, h, 0.0], [h, -h, 0.0], [-h, -h, 0.0]])
