"""The camera-timing parameters (``[camera_timing]`` of ``defaults.toml``) and the error sources.

When is an image exposed, when can the application read it, and which motion-capture
state is it paired with? :class:`CameraTimingParams` holds every number the answer needs
(their sources are in ``docs/case_study.md``, "Camera timing"; none is fitted to Table I):
the camera's free-running clock, the exposure and rolling-shutter readout, the ISP
latency and its jitter, the V4L2 driver queue's policy, the reader loop on the
Raspberry Pi 3 (the ArUco time measured here, scaled, plus overhead, jitter and stalls)
and the motion-capture stream. :mod:`.driver_queue` simulates the queue with them,
:mod:`.exposure` renders the image, :mod:`.camera_stage` puts it together.

Error sources
-------------
Each can be switched off (``disabled`` in the TOML; :meth:`CameraTimingParams.without`,
:meth:`~CameraTimingParams.only`) for the ablation of Table I:

=========  ==========================================================================
queue      the reader takes time and the ``b``-buffer queue decides which frame it reads;
           off: an infinitely fast reader that reads every frame when it is delivered,
           so the buffer size changes nothing
latency    ISP and transfer latency after readout; off: 0
jitter     delivery jitter, OS jitter and the spread of the detector's time; off: their means
stalls     rare long holds of the reader loop (heavy tail); off: none
clock      the camera's random phase and rate offset, and the motion capture's own rate,
           phase and latency; off: camera frames on the simulator's frame grid, the exact
           state at the instant the reader reads it
blur       exposure time (motion blur); off: 0
shutter    rolling-shutter readout; off: 0 (a global shutter)
noise      sensor noise in the image (``[render] noise_std``); off: 0
=========  ==========================================================================

Examples
--------
>>> p = CameraTimingParams.defaults()
>>> p.model, p.only("queue").enabled("blur"), p.without("blur").effective_exposure
('queue', False, 0.0)
>>> round(p.reader_time_ms(), 1) > 10.0          # mean reader iteration on the Pi 3 (ms)
True
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from case_studies.quad_landing.settings import DEFAULTS_PATH, ConfigError, TomlSection, check_positive

__all__ = ["SOURCES", "MODELS", "POLICIES", "CameraTimingParams"]

#: The error sources, in the order of the ablation (see the module docstring).
SOURCES: tuple[str, ...] = ("queue", "latency", "jitter", "stalls", "clock", "blur", "shutter", "noise")
#: ``"queue"``: this timing model; ``"frames"``: the previous fixed lag of ``k`` frame periods.
MODELS: tuple[str, ...] = ("queue", "frames")
#: What the driver does with a finished frame when no buffer is free (:mod:`.driver_queue`).
POLICIES: tuple[str, ...] = ("latest_slot", "drop_newest", "drop_oldest")


@dataclass(frozen=True, kw_only=True)
class CameraTimingParams(TomlSection, file=DEFAULTS_PATH, section="camera_timing"):
    """Camera, driver queue, reader loop and motion capture timing (``[camera_timing]``).

    Times in seconds unless the name says ``_ms``.

    Parameters
    ----------
    model : {"queue", "frames"}
        ``"queue"`` simulates the timing below; ``"frames"`` is the previous fixed lag of
        ``k`` frame periods (images on the frame grid, paired with the current state).
    disabled : tuple of str
        Error sources switched off (:data:`SOURCES`).
    rate_ppm_std : float
        Standard deviation of the camera clock's rate offset against the motion capture's,
        drawn per flight (ppm). The phase is uniform over a frame period per flight.
    exposure, readout : float
        Exposure time of a row; time from the first row's readout to the last's.
    isp_latency, delivery_jitter : float
        From the end of readout to a dequeueable V4L2 buffer; mean of an exponential extra
        delay per frame.
    policy : {"latest_slot", "drop_newest", "drop_oldest"}
        What the driver does with a finished frame when no buffer is free.
    detector_ms : tuple of float
        Quantiles (equally spaced, 0 % to 100 %) of the ArUco + pose time per frame measured
        on this machine (:mod:`case_studies.quad_landing.studies.reader_time`).
    convert_ms : float
        YUYV -> BGR -> grey per frame, measured on this machine.
    cpu_scale : float
        One Raspberry Pi 3 core over this machine (times are multiplied by it).
    parallel_speedup : float
        Speed-up of the detector from OpenCV's threads (measured here with two).
    overhead : float
        The rest of the reader loop per iteration on the Pi (motion-capture message,
        controller set-point, logging).
    os_jitter : float
        Mean of an exponential extra delay per iteration (scheduling on a non-real-time kernel).
    stall_rate : float
        Long holds of the reader loop per second (Poisson).
    stall_duration : (low, high)
        A hold lasts a log-uniform time in this range.
    mocap_rate, mocap_latency : float
        Motion capture sample rate (Hz, own phase) and the delay until a sample is usable.
    preroll : float
        The camera and the reader start this long before the flight (queue in steady state).
    max_step_px, max_subframes : float, int
        Exposure rendering: sub-renders are added until the pad moves at most
        ``max_step_px`` between two of them, up to ``max_subframes``.

    Examples
    --------
    >>> CameraTimingParams.defaults(policy="drop_newest").policy
    'drop_newest'
    """

    model: str
    disabled: tuple[str, ...]
    rate_ppm_std: float
    exposure: float
    readout: float
    isp_latency: float
    delivery_jitter: float
    policy: str
    detector_ms: tuple[float, ...]
    convert_ms: float
    cpu_scale: float
    parallel_speedup: float
    overhead: float
    os_jitter: float
    stall_rate: float
    stall_duration: tuple[float, float]
    mocap_rate: float
    mocap_latency: float
    preroll: float
    max_step_px: float
    max_subframes: int

    def __post_init__(self) -> None:
        if self.model not in MODELS:
            raise ConfigError(f"camera_timing.model must be one of {MODELS}, got {self.model!r}")
        if self.policy not in POLICIES:
            raise ConfigError(f"camera_timing.policy must be one of {POLICIES}, got {self.policy!r}")
        disabled = tuple(self.disabled)
        unknown = sorted(set(disabled) - set(SOURCES))
        if unknown:
            raise ConfigError(
                f"camera_timing.disabled: unknown sources {unknown}; known: {', '.join(SOURCES)}"
            )
        object.__setattr__(self, "disabled", tuple(s for s in SOURCES if s in disabled))
        for name in ("rate_ppm_std", "exposure", "readout", "isp_latency", "delivery_jitter", "overhead",
                     "os_jitter", "stall_rate", "mocap_latency", "preroll"):  # fmt: skip
            check_positive(f"camera_timing.{name}", getattr(self, name), allow_zero=True)
        for name in ("convert_ms", "cpu_scale", "parallel_speedup", "mocap_rate", "max_step_px"):
            check_positive(f"camera_timing.{name}", getattr(self, name), allow_zero=name == "convert_ms")
        check_positive("camera_timing.max_subframes", self.max_subframes, integer=True)
        q = tuple(float(v) for v in self.detector_ms)
        if len(q) < 2 or any(not math.isfinite(v) or v <= 0 for v in q) or list(q) != sorted(q):
            raise ConfigError(
                "camera_timing.detector_ms must be at least two increasing positive quantiles (ms), "
                f"got {self.detector_ms!r}"
            )
        object.__setattr__(self, "detector_ms", q)
        lo, hi = (float(v) for v in self.stall_duration)
        if not 0.0 < lo <= hi:
            raise ConfigError(f"camera_timing.stall_duration must be [low, high] with 0 < low <= high, "
                              f"got {self.stall_duration!r}")  # fmt: skip
        object.__setattr__(self, "stall_duration", (lo, hi))
        object.__setattr__(self, "max_subframes", int(self.max_subframes))

    # ------------------------------------------------------------------ sources
    def enabled(self, source: str) -> bool:
        """Whether error source ``source`` is on."""
        if source not in SOURCES:
            raise ConfigError(f"unknown error source {source!r}; known: {', '.join(SOURCES)}")
        return source not in self.disabled

    def without(self, *sources: str) -> CameraTimingParams:
        """A copy with ``sources`` switched off (and the others as they are)."""
        return dataclasses.replace(self, disabled=tuple({*self.disabled, *sources}))

    def only(self, *sources: str) -> CameraTimingParams:
        """A copy with only ``sources`` on."""
        return dataclasses.replace(self, disabled=tuple(s for s in SOURCES if s not in sources))

    # ------------------------------------------------------------------ effective values
    @property
    def effective_exposure(self) -> float:
        """Exposure time with the blur source's switch applied."""
        return self.exposure if self.enabled("blur") else 0.0

    @property
    def effective_readout(self) -> float:
        """Readout time with the shutter source's switch applied."""
        return self.readout if self.enabled("shutter") else 0.0

    def _detector_seconds(self, u: float) -> float:
        """The detector time (s on the Pi) at quantile level ``u`` in [0, 1] (linear between quantiles)."""
        q = self.detector_ms
        x = min(max(u, 0.0), 1.0) * (len(q) - 1)
        i = min(int(x), len(q) - 2)
        ms = q[i] + (x - i) * (q[i + 1] - q[i])
        return ms * 1e-3 * self.cpu_scale / self.parallel_speedup

    def _mean_detector_seconds(self) -> float:
        q = np.asarray(self.detector_ms)
        return float(np.mean(0.5 * (q[1:] + q[:-1]))) * 1e-3 * self.cpu_scale / self.parallel_speedup

    @property
    def convert_seconds(self) -> float:
        """``VideoCapture.retrieve``'s conversion on the Pi (s; 0 with the queue off)."""
        return self.convert_ms * 1e-3 * self.cpu_scale if self.enabled("queue") else 0.0

    def reader_time_ms(self) -> float:
        """Mean reader iteration on the Pi (ms): conversion, detector, overhead, jitter, stalls."""
        if not self.enabled("queue"):
            return 0.0
        mean = self.convert_seconds + self._mean_detector_seconds() + self.overhead
        if self.enabled("jitter"):
            mean += self.os_jitter
        if self.enabled("stalls"):
            lo, hi = self.stall_duration
            mean_stall = (hi - lo) / math.log(hi / lo) if hi > lo else lo
            mean += self.stall_rate * mean * mean_stall  # holds per iteration times their length
        return 1e3 * mean

    def process_sampler(self) -> Callable[[np.random.Generator], float]:
        """``rng -> seconds``: one reader iteration after the frame is converted.

        The detector's time (a measured quantile level drawn uniformly, or its mean with
        the jitter source off), the overhead, an exponential OS jitter and, with
        probability ``1 - exp(-stall_rate * time)``, a log-uniform stall.
        """
        if not self.enabled("queue"):
            return lambda rng: 0.0
        jitter, stalls = self.enabled("jitter"), self.enabled("stalls")
        mean_det = self._mean_detector_seconds()
        lo, hi = self.stall_duration
        os_jitter, rate, overhead = self.os_jitter, self.stall_rate, self.overhead

        def draw(rng: np.random.Generator) -> float:
            u, e, s, v = rng.random(4)  # always four draws: switching a source keeps the others' values
            t = (self._detector_seconds(float(u)) if jitter else mean_det) + overhead
            t += -os_jitter * math.log1p(-float(e)) if jitter else os_jitter
            if stalls and float(s) < -math.expm1(-rate * t):
                t += lo * (hi / lo) ** float(v)
            return t

        return draw
