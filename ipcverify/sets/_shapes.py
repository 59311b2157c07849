"""The set shapes under their former module name.

The shapes now live one per module (:mod:`ipcverify.sets._ellipsoid`, :mod:`ipcverify.sets._box`,
:mod:`ipcverify.sets._polytope`; the outer-set interface in :mod:`ipcverify.sets._outer` and
:mod:`ipcverify.sets._faces`). This module re-exports them for the library modules that still
import them from here; new code imports from the defining module (or from :mod:`ipcverify.sets`).
"""

from __future__ import annotations

from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import SINGULAR_RCOND, Ellipsoid, single_ellipsoid, unit_ball_log_volume
from ipcverify.sets._outer import OuterSet
from ipcverify.sets._polytope import Polytope

__all__ = [
    "SINGULAR_RCOND",
    "Box",
    "Ellipsoid",
    "OuterSet",
    "Polytope",
    "single_ellipsoid",
    "unit_ball_log_volume",
]
