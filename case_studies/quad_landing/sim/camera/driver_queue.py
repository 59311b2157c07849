"""The camera's clock, the V4L2 driver queue and the reader loop, as a discrete-event simulation.

Nothing here draws or detects anything: the simulation decides *which* camera frame the
application's reader loop processes at each iteration, *when*, and which motion-capture
sample it pairs it with. :mod:`.camera_stage` renders only the frames that are used.

Frame ``n`` (all times on the simulator's clock, s):

* ``s_n = phase + n * period``: the first row starts its exposure. The camera runs on its
  own crystal: ``period = (1 / fps) (1 + ppm 1e-6)`` with a per-flight phase and rate offset.
* row ``r`` integrates over ``[s_n + r t_row, s_n + r t_row + exposure]``, ``t_row = readout /
  height`` (rolling shutter); ``c_n = s_n + readout + exposure`` ends the last row.
* ``ref_n = s_n + readout / 2 + exposure / 2``: mid-exposure of the centre row, the instant
  the image shows on average.
* the ISP needs a free buffer; with one at ``c_n`` the frame is *done* (dequeueable) at
  ``c_n + isp_latency + jitter`` (deliveries stay in order).

The queue has ``b`` buffers (the paper's "buffer size", OpenCV's ``CAP_PROP_BUFFERSIZE``),
each free, being filled, done, or held by the application. With none free, ``policy`` says
what happens to a finished frame: ``"latest_slot"`` (the Raspberry Pi's legacy camera
stack) keeps the newest one waiting in the GPU for the next buffer the application gives
back, dropping an older waiting one; ``"drop_newest"`` (generic videobuf2) loses it;
``"drop_oldest"`` (a ring) overwrites the oldest done buffer.

The reader is OpenCV's ``VideoCapture.read()``: ``grab`` dequeues the *oldest* done buffer
(blocking until one is done), ``retrieve`` converts it and queues the buffer back, then the
application processes the image for a random time and reads the newest motion-capture
sample. The next ``read()`` follows at once.

Motion capture samples at ``mocap_rate`` Hz on its own phase; a sample can be used
``mocap_latency`` after it was taken (sample and hold). ``mocap_rate = inf``: the exact
state at the instant it is read.

Examples
--------
>>> timing = FlightTiming(fps=60.0, height=240, buffers=2, policy="drop_newest", isp_latency=0.005)
>>> sim = DriverQueue(timing, lambda rng: 0.030, np.random.default_rng(0), t_start=-1.0)
>>> it = sim.latest(0.5)
>>> bool(it.age > 0.05)      # a slow reader and two buffers: frames two reader periods old
True
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from case_studies.quad_landing.sim.camera.timing import POLICIES
from ipcverify.errors import InvalidInputError

__all__ = ["FlightTiming", "ReaderIteration", "DriverQueue"]

_ORDER = {"done": 0, "qbuf": 1, "frame": 2, "read": 3}


@dataclass(frozen=True, kw_only=True)
class FlightTiming:
    """One flight's camera, queue and motion-capture timing (s), with its random draws made.

    ``convert`` is ``retrieve``'s conversion before the buffer goes back to the driver.

    Examples
    --------
    >>> t = FlightTiming(fps=60.0, height=240, phase=0.01, exposure=0.008, readout=0.004)
    >>> round(t.reference_time(0), 6), round(t.complete_time(0), 6)
    (0.016, 0.022)
    """

    fps: float
    height: int
    buffers: int = 1
    policy: str = "latest_slot"
    rate_ppm: float = 0.0
    phase: float = 0.0
    exposure: float = 0.0
    readout: float = 0.0
    isp_latency: float = 0.0
    delivery_jitter: float = 0.0
    delivery_delay: float = 0.0
    convert: float = 0.0
    mocap_rate: float = math.inf
    mocap_phase: float = 0.0
    mocap_latency: float = 0.0

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise InvalidInputError(f"policy must be one of {POLICIES}, got {self.policy!r}")
        if isinstance(self.buffers, bool) or int(self.buffers) != self.buffers or self.buffers < 1:
            raise InvalidInputError(f"the driver queue needs at least one buffer, got {self.buffers!r}")
        for name in ("exposure", "readout", "isp_latency", "delivery_jitter", "delivery_delay", "convert",
                     "mocap_latency"):  # fmt: skip
            if not getattr(self, name) >= 0:
                raise InvalidInputError(f"{name} must be >= 0 s, got {getattr(self, name)!r}")
        if not (self.fps > 0 and self.mocap_rate > 0):
            raise InvalidInputError("fps and mocap_rate must be > 0")

    @property
    def period(self) -> float:
        """Camera frame period on the simulator's clock (s)."""
        return (1.0 / self.fps) * (1.0 + self.rate_ppm * 1e-6)

    @property
    def row_time(self) -> float:
        """Rolling-shutter delay between consecutive rows (s)."""
        return self.readout / self.height

    def exposure_start(self, n: int) -> float:
        """``s_n``: the first row of frame ``n`` starts its exposure."""
        return self.phase + n * self.period

    def reference_time(self, n: int) -> float:
        """``ref_n``: mid-exposure of the centre row of frame ``n``."""
        return self.exposure_start(n) + 0.5 * (self.readout + self.exposure)

    def complete_time(self, n: int) -> float:
        """``c_n``: the last row of frame ``n`` is read out."""
        return self.exposure_start(n) + self.readout + self.exposure

    def mocap_sample(self, t: float) -> float:
        """Time of the newest motion-capture sample usable at ``t`` (sample and hold)."""
        if math.isinf(self.mocap_rate):
            return t
        j = math.floor((t - self.mocap_latency - self.mocap_phase) * self.mocap_rate)
        return self.mocap_phase + j / self.mocap_rate


@dataclass(frozen=True)
class ReaderIteration:
    """One pass of the reader loop.

    Attributes
    ----------
    index : int
        Iteration number.
    frame : int
        Camera frame it processed.
    t_ref : float
        That frame's reference instant (centre row, mid-exposure).
    t_dequeue : float
        When ``grab`` returned the frame.
    t_done : float
        When processing finished and the motion-capture sample was read.
    t_state : float
        When that sample was taken: the state paired with the image.
    queued : int
        Done buffers left in the queue right after the dequeue.
    waited : float
        How long ``grab`` blocked (0 if a frame was waiting).
    """

    index: int
    frame: int
    t_ref: float
    t_dequeue: float
    t_done: float
    t_state: float
    queued: int
    waited: float

    @property
    def age(self) -> float:
        """``t_state - t_ref``: how much older the image is than the state paired with it."""
        return self.t_state - self.t_ref


@dataclass(eq=False)
class DriverQueue:
    """The event simulation of camera, queue, reader and motion capture from ``t_start`` on.

    Parameters
    ----------
    timing : FlightTiming
        The flight's timing.
    process_time : callable
        ``rng -> seconds``: one reader iteration after the conversion.
    rng : numpy.random.Generator
        Draws the reader's processing times.
    jitter_rng : numpy.random.Generator, optional
        Draws the delivery jitter (``rng`` if None); separate streams keep one source's draws
        unchanged when another is switched off.
    t_start : float
        When the camera starts streaming and the reader starts its loop.
    """

    timing: FlightTiming
    process_time: Callable[[np.random.Generator], float]
    rng: np.random.Generator
    jitter_rng: np.random.Generator | None = None
    t_start: float = -1.0
    dropped: int = field(init=False, default=0)
    _events: list[tuple[float, int, str, int]] = field(init=False, repr=False)
    _seq: int = field(init=False, default=0)
    _free: int = field(init=False, default=0)
    _done: deque[int] = field(init=False, repr=False)
    _slot: int | None = field(init=False, default=None)
    _last_done: float = field(init=False, default=-math.inf)
    _waiting_since: float | None = field(init=False, default=None)
    _next_frame: int = field(init=False, default=0)
    _finished: list[ReaderIteration] = field(init=False, repr=False)
    _pending: ReaderIteration | None = field(init=False, default=None)
    _count: int = field(init=False, default=0)

    def __post_init__(self) -> None:
        tm = self.timing
        self._events, self._done, self._finished = [], deque(), []
        self._free = int(tm.buffers)
        self._next_frame = math.ceil((self.t_start - tm.phase) / tm.period)
        self._push(tm.complete_time(self._next_frame), "frame", self._next_frame)
        self._next_frame += 1
        self._push(self.t_start, "read", 0)

    # ------------------------------------------------------------------ events
    def _push(self, t: float, kind: str, arg: int) -> None:
        heapq.heappush(self._events, (t, _ORDER[kind] * 10**12 + self._seq, kind, arg))
        self._seq += 1

    def _deliver(self, t_claim: float, n: int) -> None:
        """Frame ``n`` got a buffer at ``t_claim``: done after the ISP (in order)."""
        tm = self.timing
        rng = self.rng if self.jitter_rng is None else self.jitter_rng
        jitter = float(rng.exponential(tm.delivery_jitter)) if tm.delivery_jitter > 0 else 0.0
        t = max(t_claim + tm.isp_latency + tm.delivery_delay + jitter, self._last_done)
        self._last_done = t
        self._free -= 1
        self._push(t, "done", n)

    def _dequeue(self, t: float) -> None:
        tm = self.timing
        n = self._done.popleft()
        waited = 0.0 if self._waiting_since is None else t - self._waiting_since
        self._waiting_since = None
        self._push(t + tm.convert, "qbuf", 0)
        t_done = t + tm.convert + float(self.process_time(self.rng))
        self._pending = ReaderIteration(
            index=self._count,
            frame=n,
            t_ref=tm.reference_time(n),
            t_dequeue=t,
            t_done=t_done,
            t_state=min(tm.mocap_sample(t_done), t_done),
            queued=len(self._done),
            waited=waited,
        )
        self._count += 1
        self._push(t_done, "read", 0)

    def _frame_complete(self, t: float, n: int) -> None:
        tm = self.timing
        self._push(tm.complete_time(self._next_frame), "frame", self._next_frame)
        self._next_frame += 1
        if self._free > 0:
            self._deliver(t, n)
        elif tm.policy == "latest_slot":
            self.dropped += self._slot is not None
            self._slot = n
        elif tm.policy == "drop_oldest" and self._done:
            self._done.popleft()  # its buffer is overwritten with the new frame
            self.dropped += 1
            self._free += 1
            self._deliver(t, n)
        else:
            self.dropped += 1

    def _step(self) -> None:
        t, _, kind, arg = heapq.heappop(self._events)
        if kind == "frame":
            self._frame_complete(t, arg)
        elif kind == "done":
            self._done.append(arg)
            if self._waiting_since is not None:
                self._dequeue(t)
        elif kind == "qbuf":
            self._free += 1
            if self._slot is not None:
                n, self._slot = self._slot, None
                self._deliver(t, n)
        else:  # "read": the previous iteration is finished, grab the next frame
            if self._pending is not None:
                self._finished.append(self._pending)
                self._pending = None
            if self._done:
                self._dequeue(t)
            else:
                self._waiting_since = t

    # ------------------------------------------------------------------ queries
    def run_until(self, t: float) -> None:
        """Process every event up to time ``t``."""
        while self._events and self._events[0][0] <= t:
            self._step()

    def iterations(self, t: float) -> list[ReaderIteration]:
        """All iterations (still kept) whose processing finished by ``t``."""
        self.run_until(t)
        out = list(self._finished)
        if self._pending is not None and self._pending.t_done <= t:
            out.append(self._pending)
        return out

    def latest(self, t: float) -> ReaderIteration | None:
        """The newest iteration finished by ``t`` (what a measurement at ``t`` uses)."""
        self.run_until(t)
        if self._pending is not None and self._pending.t_done <= t:
            return self._pending
        return self._finished[-1] if self._finished else None

    def forget_before(self, t: float) -> None:
        """Drop finished iterations that ended before ``t``, keeping the newest."""
        k = 0
        while k < len(self._finished) - 1 and self._finished[k].t_done < t:
            k += 1
        del self._finished[:k]
