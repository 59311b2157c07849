"""The perception contracts the landing state machine can use, each answering one measurement.

* :class:`LearnedContract` — a trained, calibrated IPC in the camera frame. Each query
  ``(x_C, yhat_C)`` goes through the library's one query path,
  :class:`ipcverify.decision.IPCQuery`: the model's float64 engine (the same evaluation the
  calibration certified), the calibration's scale, the domain-of-validity test; then
  :class:`ipcverify.decision.LandingQuery` moves the set to W with the measurement's *current*
  camera pose ``T_WC`` (:func:`.frames.transform_ellipsoid`), as in the paper, and takes the
  landing decision.
* :class:`TrivialContract` — the paper's baseline ``E(yhat, 10000 I)``: a ball of radius
  0.1 mm around the perceived position, i.e. "trust every measurement", decided by the same
  rule (:class:`ipcverify.decision.LandingRule`).

Examples
--------
>>> import numpy as np
>>> from case_studies.quad_landing import Flight, Pad, hover_state
>>> from ipcverify.sets import Box
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.05, -0.03, 1.0)), Pad((0.0, 0.0, 0.0), yaw=0.3))
>>> d = TrivialContract().decide(flight.measure(), Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05]))
>>> d.accept, d.proven, float(np.linalg.inv(d.shape)[0, 0])
(True, True, 0.0001)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from case_studies.quad_landing.sim.flight import Measurement
from case_studies.quad_landing.sim.frames import transform_ellipsoid
from ipcverify.contract import IPCModel
from ipcverify.decision import IPCQuery, LandingQuery
from ipcverify.decision._landing import LandingRule, QueryDecision
from ipcverify.errors import InvalidInputError
from ipcverify.sets import Box

__all__ = ["Contract", "LearnedContract", "TrivialContract"]


class Contract(Protocol):
    """What the landing state machine asks of a perception contract."""

    @property
    def name(self) -> str:
        """Short label (``"ipc"``, ``"baseline"``, ``"paper_raw"``, ...)."""
        ...

    def decide(self, measurement: Measurement, target: Box) -> QueryDecision:
        """The set in W for a measurement with a detection, and the landing decision against ``target``."""
        ...


def _require_detection(m: Measurement) -> tuple[np.ndarray, np.ndarray]:
    if m.yhat_c is None:
        raise InvalidInputError("a contract needs a measurement with a detection (yhat_c is None)")
    return m.x_c, m.yhat_c


@dataclass(frozen=True, eq=False)
class LearnedContract:
    """A calibrated IPC learned in the camera frame, queried per measurement through :class:`LandingQuery`.

    Parameters
    ----------
    model : IPCModel
        Trained on ``x_C`` (12) and ``yhat_C`` (3), with a calibration attached.
    name : str
        Label in results.
    uncalibrated : bool
        Fly the network's own, uncalibrated sets (the paper's protocol: its IPC flew as
        trained). They carry **no guarantee**; this must be asked for explicitly, and a
        calibrated model is refused with it (its calibration would be ignored).

    Raises
    ------
    InvalidInputError
        If the model has no calibration (its sets carry no guarantee) and ``uncalibrated``
        is not set, or the wrong dimensions.
    """

    model: IPCModel
    name: str = "ipc"
    uncalibrated: bool = False
    _queries: dict[tuple[float, ...], LandingQuery] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        if self.uncalibrated:
            if self.model.calibration is not None:
                raise InvalidInputError(
                    "uncalibrated=True flies the raw network, but this model carries a calibration; "
                    "pass the model without it (model.with_calibration(None)) or drop uncalibrated"
                )
        else:
            self.model.require_calibration()
        if (self.model.config.x_dim, self.model.config.y_dim) != (12, 3):
            raise InvalidInputError(
                f"the IPC must map x_C (12) and yhat_C (3); the model has x_dim={self.model.config.x_dim}, "
                f"y_dim={self.model.config.y_dim}"
            )

    def query(self, target: Box) -> LandingQuery:
        """The :class:`LandingQuery` of this contract for ``target`` (built once per target)."""
        key = (*target.lower.tolist(), *target.upper.tolist())
        if key not in self._queries:
            self._queries[key] = LandingQuery(IPCQuery(self.model), target)
        return self._queries[key]

    def decide(self, measurement: Measurement, target: Box) -> QueryDecision:
        """Query -> calibrated set in C -> moved to W by the current camera pose -> decision."""
        x_c, yhat_c = _require_detection(measurement)
        pose = measurement.world_from_camera
        return self.query(target).decide(x_c, yhat_c, transform=lambda c, C: transform_ellipsoid(c, C, pose))


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

    def decide(self, measurement: Measurement, target: Box) -> QueryDecision:
        """A tiny ball around the perceived pad position in W, decided by the landing rule."""
        _require_detection(measurement)
        return LandingRule(target).decide(
            np.asarray(measurement.yhat_w, dtype=np.float64), self.precision * np.eye(3)
        )
