"""The camera stage with the timing model: which image is read, how it looks, what it is paired with.

:class:`TimedCamera` puts together the free-running camera clock and the V4L2 queue
(:mod:`.driver_queue`), the exposure and rolling shutter (:mod:`.exposure`) and the
motion-capture sample and hold, with the parameters of :mod:`.timing`. At a measurement
instant it returns the *newest reader iteration finished by then*: the image of the frame
that iteration dequeued — rendered over that frame's exposure from the state history —
run through the detector and paired with the motion-capture state the reader read. The
age of the image follows from the queue, not from a fixed number of frames.

Each flight draws its own camera phase and rate offset, motion-capture phase, reader
processing times and delivery jitter from its seed, on separate random streams: flights
with the same seed share them whatever the buffer size, and switching an error source off
leaves the draws of the others unchanged.

:func:`.stage.build_camera_stage` picks this stage or the previous fixed lag
(:class:`.framebuffer.FrameLagCamera`, also used for buffer size 0, the ideal camera).

Examples
--------
>>> from case_studies.quad_landing import Flight, hover_state
>>> flight = Flight(buffer_size=1, seed=0)               # the timing model is the default
>>> flight.reset(hover_state((0.05, -0.03, 1.2)))  # off centre: see docs/case_study.md (IPPE)
>>> flight.hold(0.5)
>>> m = flight.measure()
>>> bool(0.0 < m.age < 0.1), m.detected
(True, True)
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.perception.aruco import ArucoPerception
from case_studies.quad_landing.sim.camera.driver_queue import DriverQueue, FlightTiming, ReaderIteration
from case_studies.quad_landing.sim.camera.exposure import render_exposed
from case_studies.quad_landing.sim.camera.framebuffer import noise_key
from case_studies.quad_landing.sim.camera.measurement import Measurement, StageParts, pair
from case_studies.quad_landing.sim.camera.pinhole import Camera
from case_studies.quad_landing.sim.camera.render import Renderer
from case_studies.quad_landing.sim.camera.timing import CameraTimingParams
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.history import StateHistory
from case_studies.quad_landing.sim.marker import Pad
from ipcverify.errors import InvalidInputError

__all__ = [
    "TimedCamera",
    "flight_timing",
    "STREAMS",
    "OUT_OF_VIEW_PX",
]

#: Random streams of a flight's seed: camera and motion-capture clocks, reader, delivery jitter.
STREAMS = {"clock": 101, "reader": 102, "delivery": 103}
#: A marker more than this many pixels outside the image is not drawn (it cannot be detected).
OUT_OF_VIEW_PX = 10.0


def flight_timing(
    params: CameraTimingParams, buffers: int, fps: float, height: int, rng: np.random.Generator
) -> FlightTiming:
    """One flight's :class:`.driver_queue.FlightTiming`: draws the clocks, applies the source switches.

    With the clock source off, frame ``n``'s reference instant is the simulator's ``n / fps``
    and the state is the exact one at the instant it is read.

    Examples
    --------
    >>> p = CameraTimingParams.defaults()
    >>> t = flight_timing(p.without("clock"), 1, 60.0, 240, np.random.default_rng(0))
    >>> round(t.reference_time(3), 9) == round(3 / 60, 9), math.isinf(t.mocap_rate)
    (True, True)
    """
    period = 1.0 / fps
    phase, ppm, mocap_phase = rng.uniform(0.0, period), rng.normal(0.0, 1.0), rng.uniform(0.0, 1.0)
    exposure, readout = params.effective_exposure, params.effective_readout
    clock, jitter = params.enabled("clock"), params.enabled("jitter")
    return FlightTiming(
        fps=fps,
        height=height,
        buffers=buffers,
        policy=params.policy,
        rate_ppm=float(ppm) * params.rate_ppm_std if clock else 0.0,
        phase=float(phase) if clock else -0.5 * (exposure + readout),
        exposure=exposure,
        readout=readout,
        isp_latency=params.isp_latency if params.enabled("latency") else 0.0,
        delivery_jitter=params.delivery_jitter if jitter else 0.0,
        delivery_delay=0.0 if jitter else params.delivery_jitter,
        convert=params.convert_seconds,
        mocap_rate=params.mocap_rate if clock else math.inf,
        mocap_phase=float(mocap_phase) / params.mocap_rate if clock else 0.0,
        mocap_latency=params.mocap_latency if clock else 0.0,
    )


class TimedCamera(StageParts):
    """The camera-timing model's stage (see the module docstring).

    Parameters
    ----------
    params : CameraTimingParams
        ``[camera_timing]``.
    buffer_size : int
        V4L2 buffers (the paper's buffer size), at least 1.
    camera, renderer, perception, ground_z
        As for :class:`.measurement.StageParts`.
    """

    def __init__(
        self,
        params: CameraTimingParams,
        buffer_size: int,
        camera: Camera,
        renderer: Renderer,
        perception: ArucoPerception,
        ground_z: float,
    ) -> None:
        super().__init__(buffer_size, camera, renderer, perception, ground_z)
        if self.buffer_size < 1:
            raise InvalidInputError("the timed camera needs a buffer size >= 1 (0 is the ideal camera)")
        self.params = params
        self._queue: DriverQueue | None = None
        self._cache: (
            tuple[int, Measurement, NDArray[np.uint8] | None, Callable[[], NDArray[np.uint8]]] | None
        ) = None
        self.last_iteration: ReaderIteration | None = None

    @property
    def timing(self) -> FlightTiming:
        """This flight's timing (after :meth:`begin`)."""
        return self._require_queue().timing

    def begin(self, history: StateHistory, pad: Pad, seed: int) -> None:
        """Start a flight: draw its clocks and start the camera and reader ``preroll`` s before it."""
        self._history, self._pad, self._seed, self._cache = history, pad, int(seed), None
        p, cam = self.params, self.camera.params
        streams = {name: np.random.default_rng([int(seed), s]) for name, s in STREAMS.items()}
        timing = flight_timing(p, self.buffer_size, cam.fps, cam.height, streams["clock"])
        self._queue = DriverQueue(timing, p.process_sampler(), streams["reader"], streams["delivery"],
                                  t_start=history.start - p.preroll)  # fmt: skip
        self.last_iteration = None

    def _require_queue(self) -> DriverQueue:
        if self._queue is None:
            raise InvalidInputError("call Flight.reset(state) before measuring")
        return self._queue

    def pose_at(self, t: float) -> Pose:
        """``T_CW`` at simulator time ``t`` (from the state history)."""
        if self._history is None:
            raise InvalidInputError("call Flight.reset(state) before measuring")
        return self.camera.world_from_camera(self._history.state_at(t)).inverse()

    def iteration(self, now: float) -> ReaderIteration:
        """The newest reader iteration finished by ``now``."""
        it = self._require_queue().latest(now)
        if it is None:
            raise InvalidInputError(
                f"no reader iteration finished by t = {now:.3f} s; camera_timing.preroll is too short"
            )
        return it

    def measure(self, now: float) -> Measurement:
        """The newest reader output by ``now`` (see the module docstring); cached per iteration.

        A frame whose marker lies more than :data:`OUT_OF_VIEW_PX` outside the image at its
        reference instant is not drawn: ArUco rejects markers within 3 px of the border, so it
        cannot be detected (the image is drawn if :meth:`image` asks for it).
        """
        queue = self._require_queue()
        it = self.iteration(now)
        self.last_iteration = it
        if self._cache is not None and self._cache[0] == it.index:
            return self._cache[1]
        if self._history is None or self._pad is None:
            raise InvalidInputError("call Flight.reset(state) before measuring")
        tm, p, pad = queue.timing, self.params, self._pad
        shown = self.pose_at(it.t_ref)

        def draw() -> NDArray[np.uint8]:
            return render_exposed(
                self.renderer, self.pose_at, pad, tm.exposure_start(it.frame), tm.exposure, tm.readout,
                noise_key(self._seed, it.frame), max_step_px=p.max_step_px, max_subframes=p.max_subframes,
            )  # fmt: skip

        corners = self.renderer.marker_corners_camera(shown, pad)
        visible = self.camera.in_view(corners, margin_px=-OUT_OF_VIEW_PX)
        image = draw() if visible else None
        yhat = self.perception.estimate(image) if image is not None else None
        m = pair(self._history.state_at(it.t_state), it.t_state, it.t_ref, yhat, shown, camera=self.camera,
                 renderer=self.renderer, pad=pad, ground_z=self.ground_z)  # fmt: skip
        self._cache = (it.index, m, image, draw)
        queue.forget_before(now - 1.0)
        return m

    def image(self) -> NDArray[np.uint8]:
        """The image of the last measurement (drawn now if it was skipped as out of view)."""
        if self._cache is None:
            raise InvalidInputError("no measurement yet: call measure() first")
        index, m, image, draw = self._cache
        if image is None:
            image = draw()
            self._cache = (index, m, image, draw)
        return image
