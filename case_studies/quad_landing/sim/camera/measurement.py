"""A camera measurement paired with a motion-capture state, and the camera stage that makes it.

A :class:`CameraStage` turns the flight's state history into measurements: which image
the application reads at a given instant, how it looks, what the detector makes of it,
and which state it is paired with. Two stages exist: the previous fixed lag of ``k``
frames (:class:`.framebuffer.FrameLagCamera`) and the camera-timing model
(:class:`.timed.TimedCamera`); :func:`.stage.build_camera_stage` picks one
from the configuration. Both build their result with :func:`pair`.

Examples
--------
>>> from case_studies.quad_landing import Flight, hover_state
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.05, -0.03, 1.2)))  # off centre: see docs/case_study.md (IPPE)
>>> m = flight.measure()
>>> m.detected, bool(m.capture_time <= m.time)
(True, True)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.sim.camera.buffer import check_buffer_size
from case_studies.quad_landing.sim.camera.features import camera_frame_state
from case_studies.quad_landing.sim.camera.pinhole import Camera
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.marker import Pad

if TYPE_CHECKING:
    from case_studies.quad_landing.perception.aruco import ArucoPerception
    from case_studies.quad_landing.sim.camera.render import Renderer
    from case_studies.quad_landing.sim.history import StateHistory

__all__ = ["Measurement", "CameraStage", "StageParts", "pair"]


@dataclass(frozen=True, eq=False)
class Measurement:
    """One camera measurement paired with a motion-capture state.

    Attributes
    ----------
    time : float
        When the paired state was taken (s).
    capture_time : float
        The instant the image shows: mid-exposure of its centre row (s).
    state : ndarray, shape (12,)
        The paired world-frame state (the motion-capture state).
    x_c : ndarray, shape (12,)
        That state in the camera frame (see :mod:`.features`).
    y_c : ndarray, shape (3,)
        True pad centre in the camera frame of that state (m).
    yhat_c : ndarray, shape (3,) or None
        Perceived pad centre from the image, or None without a detection.
    world_from_camera : Pose
        ``T_WC`` at the paired state: ``y_W = R y_C + t``.
    pad_in_view : bool
        Whether the marker was entirely inside the image that was used.
    """

    time: float
    capture_time: float
    state: FloatArray
    x_c: FloatArray
    y_c: FloatArray
    yhat_c: FloatArray | None
    world_from_camera: Pose
    pad_in_view: bool

    @property
    def detected(self) -> bool:
        """True if the marker was detected."""
        return self.yhat_c is not None

    @property
    def age(self) -> float:
        """How much older the image is than the state it is paired with (s)."""
        return self.time - self.capture_time

    @property
    def y_w(self) -> FloatArray:
        """True pad centre in W."""
        return self.world_from_camera.apply(self.y_c)

    @property
    def yhat_w(self) -> FloatArray | None:
        """Perceived pad centre moved to W with the paired camera pose, or None."""
        return None if self.yhat_c is None else self.world_from_camera.apply(self.yhat_c)


class CameraStage(Protocol):
    """What a flight (or a replay of a recorded flight) asks of its camera.

    Attributes
    ----------
    camera : Camera
        The camera the stage images with.
    renderer : Renderer
        Its renderer (sensor noise switched by the noise source).
    perception : ArucoPerception
        The detector every image read goes through.
    """

    camera: Camera
    renderer: Renderer
    perception: ArucoPerception

    @property
    def buffer_size(self) -> int:
        """The camera buffer size this stage models."""
        ...

    def begin(self, history: StateHistory, pad: Pad, seed: int) -> None:
        """Start a flight: its state history (filled as it flies), its pad and its sensor seed."""
        ...

    def measure(self, now: float) -> Measurement:
        """The measurement the application has at simulator time ``now``."""
        ...

    def image(self) -> NDArray[np.uint8]:
        """The image of the last measurement."""
        ...


class StageParts:
    """What both camera stages hold: the camera, renderer and detector, and the flight being measured.

    :class:`.framebuffer.FrameLagCamera` and :class:`.timed.TimedCamera` derive from it; a
    flight's history, pad and sensor seed are set by their ``begin``.

    Parameters
    ----------
    buffer_size : int
        The camera buffer size the stage models (:func:`.buffer.check_buffer_size`): ``k``
        frames of lag, or the timing model's V4L2 buffers.
    camera, renderer, perception
        The simulator's camera, renderer (its noise already switched by the noise source)
        and detector.
    ground_z : float
        Floor height in W (m).
    """

    def __init__(
        self,
        buffer_size: int,
        camera: Camera,
        renderer: Renderer,
        perception: ArucoPerception,
        ground_z: float,
    ) -> None:
        self._buffer_size = check_buffer_size(buffer_size)
        self.camera, self.renderer, self.perception, self.ground_z = camera, renderer, perception, ground_z
        self._history: StateHistory | None = None
        self._pad: Pad | None = None
        self._seed = 0

    @property
    def buffer_size(self) -> int:
        """The camera buffer size this stage models."""
        return self._buffer_size


def pair(
    state: FloatArray,
    time: float,
    capture_time: float,
    yhat_c: FloatArray | None,
    shown: Pose,
    *,
    camera: Camera,
    renderer: Renderer,
    pad: Pad,
    ground_z: float,
) -> Measurement:
    """A :class:`Measurement` of the paired ``state``; ``shown`` is ``T_CW`` of the image's instant."""
    x_c, T_WC = camera_frame_state(state, camera, ground_z)
    corners = renderer.marker_corners_camera(shown, pad)
    return Measurement(
        time=float(time),
        capture_time=float(capture_time),
        state=state,
        x_c=x_c,
        y_c=T_WC.inverse().apply(pad.position),
        yhat_c=yhat_c,
        world_from_camera=T_WC,
        pad_in_view=camera.in_view(corners),
    )
