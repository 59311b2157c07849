"""The camera pipeline: from the flight's state history to a detector's measurement.

One entry point, :func:`build_camera_stage`: a configuration and a buffer size in, a
:class:`CameraStage` out, which a :class:`~case_studies.quad_landing.sim.flight.Flight` (or a
replay of a recorded flight) asks for the :class:`Measurement` the application has at an
instant. Inside, one module per part:

* :mod:`.pinhole` — the pinhole camera, its intrinsics and mount (``[camera]``);
* :mod:`.render` — the grey-scale image of the pad on the floor (``[render]``);
* :mod:`.exposure` — one frame over its exposure time, with the rolling shutter;
* :mod:`.timing` — the camera-timing parameters and error sources (``[camera_timing]``);
* :mod:`.driver_queue` — the camera's clock, the V4L2 queue and the reader loop;
* :mod:`.timed` — the timing model's stage, :class:`TimedCamera`;
* :mod:`.framebuffer` — the previous fixed lag of ``k`` frames, :class:`FrameLagCamera`;
* :mod:`.measurement` — the :class:`Measurement`, the :class:`CameraStage` protocol and
  :func:`~.measurement.pair`, which pairs an estimate with a motion-capture state;
* :mod:`.features` — that state in the camera frame, ``x_C`` (the IPC's input);
* :mod:`.buffer` — the buffer size: :data:`MAX_BUFFER_SIZE` and :func:`check_buffer_size`;
* :mod:`.stage` — :func:`build_camera_stage`.

The detector the stage runs on every image it reads is
:mod:`case_studies.quad_landing.perception`; the pad it images is
:class:`case_studies.quad_landing.sim.marker.Pad`.
"""

from case_studies.quad_landing.sim.camera.buffer import MAX_BUFFER_SIZE, BufferSize, check_buffer_size
from case_studies.quad_landing.sim.camera.features import camera_frame_state
from case_studies.quad_landing.sim.camera.framebuffer import FrameLagCamera
from case_studies.quad_landing.sim.camera.measurement import CameraStage, Measurement
from case_studies.quad_landing.sim.camera.pinhole import Camera, CameraParams
from case_studies.quad_landing.sim.camera.render import Renderer, RenderParams
from case_studies.quad_landing.sim.camera.stage import CameraConfig, build_camera_stage
from case_studies.quad_landing.sim.camera.timed import TimedCamera
from case_studies.quad_landing.sim.camera.timing import SOURCES, CameraTimingParams

__all__ = [
    "MAX_BUFFER_SIZE",
    "SOURCES",
    "BufferSize",
    "Camera",
    "CameraConfig",
    "CameraParams",
    "CameraStage",
    "CameraTimingParams",
    "FrameLagCamera",
    "Measurement",
    "RenderParams",
    "Renderer",
    "TimedCamera",
    "build_camera_stage",
    "camera_frame_state",
    "check_buffer_size",
]
