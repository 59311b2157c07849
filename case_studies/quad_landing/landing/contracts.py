"""The perception contracts the landing state machine can use, as world-frame ellipsoids.

* :class:`LearnedContract` — a trained, calibrated IPC in the camera frame. Each query
  ``(x_C, yhat_C)`` goes through the model's float64 engine (the same evaluation the
  calibration certified), is scaled by the calibration, and is moved to W with the
  measurement's *current* camera pose ``T_WC`` (:func:`.frames.transform_ellipsoid`),
  as in the paper.
* :class:`TrivialContract` — the paper's baseline ``E(yhat, 10000 I)``: a ball of radius
  0.1 mm around the perceived position, i.e. "trust every measurement".

Examples
--------
>>> import numpy as np
>>> from case_studies.quad_landing import Flight, Pad, hover_state
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.0, 0.0, 1.0)), Pad((0.0, 0.0, 0.0), yaw=0.3))
>>> e = TrivialContract().world_ellipsoid(flight.measure())
>>> float(e.half_widths()[0, 0])
0.0001
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from case_studies.quad_landing.sim.flight import Measurement
from case_studies.quad_landing.sim.frames import transform_ellipsoid
from ipcverify.errors import InvalidInputError
from ipcverify.model import IPCModel
from ipcverify.sets import Ellipsoid

__all__ = ["Contract", "LearnedContract", "TrivialContract"]


class Contract(Protocol):
    """What the landing state machine asks of a perception contract."""

    @property
    def name(self) -> str:
        """Short label (``"ipc"``, ``"baseline"``)."""
        ...

    def world_ellipsoid(self, measurement: Measurement) -> Ellipsoid:
        """The contract's set for a measurement with a detection, in W (a batch of one)."""
        ...


def _require_detection(m: Measurement) -> tuple[np.ndarray, np.ndarray]:
    if m.yhat_c is None:
        raise InvalidInputError("a contract needs a measurement with a detection (yhat_c is None)")
    return m.x_c, m.yhat_c


@dataclass(frozen=True, eq=False)
class LearnedContract:
    """A calibrated IPC learned in the camera frame, queried per measurement.

    Parameters
    ----------
    model : IPCModel
        Trained on ``x_C`` (12) and ``yhat_C`` (3), with a calibration attached.
    name : str
        Label in results.

    Raises
    ------
    InvalidInputError
        If the model has no calibration (its sets carry no guarantee) or the wrong dimensions.
    """

    model: IPCModel
    name: str = "ipc"

    def __post_init__(self) -> None:
        if self.model.calibration is None:
            raise InvalidInputError(
                "the landing needs a calibrated IPC (its raw sets carry no guarantee); "
                "calibrate it with ipcverify.calibrate.calibrate first"
            )
        if (self.model.config.x_dim, self.model.config.y_dim) != (12, 3):
            raise InvalidInputError(
                f"the IPC must map x_C (12) and yhat_C (3); the model has x_dim={self.model.config.x_dim}, "
                f"y_dim={self.model.config.y_dim}"
            )

    def camera_ellipsoid(self, x_c: np.ndarray, yhat_c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Calibrated centre and shape in C for one query (float64 engine, then ``C / s``)."""
        c, C = self.model.engine.single(np.asarray(x_c, np.float64), np.asarray(yhat_c, np.float64))
        assert self.model.calibration is not None
        s = float(self.model.calibration.scale_for(x_c[None, :], yhat_c[None, :])[0])
        return c, C / s

    def world_ellipsoid(self, measurement: Measurement) -> Ellipsoid:
        """The calibrated set moved to W with the measurement's current camera pose."""
        c, C = self.camera_ellipsoid(*_require_detection(measurement))
        cw, Cw = transform_ellipsoid(c, C, measurement.world_from_camera)
        return Ellipsoid(cw, Cw)


@dataclass(frozen=True)
class TrivialContract:
    """The paper's baseline ``E(yhat, precision * I)`` (default ``10000 I``: radius 0.1 mm).

    Examples
    --------
    >>> TrivialContract().precision
    10000.0
    """

    precision: float = 1e4
    name: str = "baseline"

    def __post_init__(self) -> None:
        if not (np.isfinite(self.precision) and self.precision > 0):
            raise InvalidInputError(f"precision must be a positive number, got {self.precision!r}")

    def world_ellipsoid(self, measurement: Measurement) -> Ellipsoid:
        """A tiny ball around the perceived pad position in W."""
        _require_detection(measurement)
        return Ellipsoid(measurement.yhat_w, self.precision * np.eye(3))
