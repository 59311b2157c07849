"""The camera package's entry point: a camera stage built from a configuration.

:func:`build_camera_stage` builds the camera, the renderer (its sensor noise switched by the
noise source) and the detector from a configuration, and puts them behind the stage the
``[camera_timing]`` model asks for: the timing model (:class:`.timed.TimedCamera`) or the
previous fixed lag of ``k`` frames (:class:`.framebuffer.FrameLagCamera`, also for buffer
size 0, the ideal camera). A :class:`~case_studies.quad_landing.sim.flight.Flight` and a
replay of a recorded flight (:mod:`case_studies.quad_landing.data.recording`) both measure
through it.

Examples
--------
>>> from case_studies.quad_landing.sim.config import load_config
>>> cfg = load_config()
>>> type(build_camera_stage(cfg, 2)).__name__, type(build_camera_stage(cfg, 0)).__name__
('TimedCamera', 'FrameLagCamera')
"""

from __future__ import annotations

from typing import Protocol

from case_studies.quad_landing.perception.aruco import ArucoPerception, DetectorParams
from case_studies.quad_landing.perception.marker import MarkerParams
from case_studies.quad_landing.sim.camera.buffer import check_buffer_size
from case_studies.quad_landing.sim.camera.framebuffer import FrameLagCamera
from case_studies.quad_landing.sim.camera.measurement import CameraStage
from case_studies.quad_landing.sim.camera.pinhole import Camera, CameraParams
from case_studies.quad_landing.sim.camera.render import Renderer, RenderParams
from case_studies.quad_landing.sim.camera.timed import TimedCamera
from case_studies.quad_landing.sim.camera.timing import CameraTimingParams

__all__ = ["CameraConfig", "build_camera_stage"]


class _Ground(Protocol):
    @property
    def ground_z(self) -> float: ...


class CameraConfig(Protocol):
    """The sections of a configuration a camera stage is built from.

    :class:`~case_studies.quad_landing.sim.config.SimConfig` is one; the camera package does
    not import it (the configuration imports the camera's sections).
    """

    @property
    def camera(self) -> CameraParams:
        """``[camera]``."""
        ...

    @property
    def marker(self) -> MarkerParams:
        """``[marker]``."""
        ...

    @property
    def sensor_render(self) -> RenderParams:
        """``[render]`` as the camera uses it (noise switched by the noise source)."""
        ...

    @property
    def detector(self) -> DetectorParams:
        """``[detector]``."""
        ...

    @property
    def camera_timing(self) -> CameraTimingParams:
        """``[camera_timing]``."""
        ...

    @property
    def sim(self) -> _Ground:
        """``[sim]`` (its ``ground_z``)."""
        ...


def build_camera_stage(config: CameraConfig, buffer_size: int) -> CameraStage:
    """A camera stage with its own camera, renderer and detector, as ``config`` says.

    Parameters
    ----------
    config : CameraConfig
        The configuration (a :class:`~case_studies.quad_landing.sim.config.SimConfig`).
    buffer_size : int
        The camera buffer size (:func:`.buffer.check_buffer_size`): V4L2 buffers of the timing
        model, or ``k`` frames of lag with ``[camera_timing] model = "frames"``; 0 is an ideal
        camera whatever the model.

    Returns
    -------
    CameraStage
        The stage; its ``camera``, ``renderer`` and ``perception`` are the parts it built.

    Examples
    --------
    >>> from case_studies.quad_landing.sim.config import load_config
    >>> build_camera_stage(load_config(), 3).buffer_size
    3
    """
    b = check_buffer_size(buffer_size)
    camera = Camera(config.camera)
    renderer = Renderer(camera, config.marker, config.sensor_render)
    perception = ArucoPerception(camera, config.marker, config.detector)
    ground_z = config.sim.ground_z
    if config.camera_timing.model == "frames" or b == 0:
        return FrameLagCamera(b, camera, renderer, perception, ground_z)
    return TimedCamera(config.camera_timing, b, camera, renderer, perception, ground_z)
