"""The previous camera model: a fixed lag of ``k`` frame periods (``[camera_timing] model = "frames"``).

The camera captures a frame at every tick of the simulator's 60 Hz clock, rendered from
the state at that tick; a buffer of ``k`` frames makes the frame the application reads at
a tick the one captured ``k`` ticks earlier, paired with the *current* state. Before the
flight the buffer is full of the start state's frame. ``k = 0`` is an ideal camera (the
current state's frame), used as a no-lag reference whatever the model.

This is the model the case study started with; the camera-timing model
(:class:`.timed.TimedCamera`) replaced it as the default.

Examples
--------
>>> from case_studies.quad_landing import Flight, hover_state, load_config
>>> cfg = load_config(overrides={"camera_timing": {"model": "frames"}})
>>> flight = Flight(cfg, buffer_size=2, seed=0)
>>> flight.reset(hover_state((0.0, 0.0, 1.2)))
>>> for _ in range(5):
...     flight.step()
>>> m = flight.measure()
>>> round(m.time - m.capture_time, 6) == round(2 / 60, 6)
True
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.sim.camera.measurement import Measurement, StageParts, pair
from case_studies.quad_landing.sim.history import StateHistory
from case_studies.quad_landing.sim.marker import Pad
from ipcverify.errors import InvalidInputError

__all__ = ["FrameLagCamera", "noise_key"]


def noise_key(seed: int, frame: int) -> int:
    """The sensor-noise key of camera frame ``frame`` of a flight seeded ``seed`` (>= 0).

    Examples
    --------
    >>> noise_key(7, -3) == noise_key(7, -3), noise_key(7, 1) != noise_key(7, 2)
    (True, True)
    """
    return (int(seed) * 7919 + int(frame)) % (2**31)


class FrameLagCamera(StageParts):
    """The ``k``-frame lag (see the module docstring).

    Parameters
    ----------
    buffer_size : int
        ``k``, frames of lag (0: no lag).
    camera, renderer, perception, ground_z
        As for :class:`.measurement.StageParts`.
    """

    #: The last measurement: its tick, time, result and image (None before the first).
    _cache: tuple[int, float, Measurement, NDArray[np.uint8]] | None = None

    def begin(self, history: StateHistory, pad: Pad, seed: int) -> None:
        """Start a flight (the buffer holds the start state's frame)."""
        self._history, self._pad, self._seed, self._cache = history, pad, int(seed), None

    def _tick_image(self, tick: int, t: float) -> NDArray[np.uint8]:
        history, pad = self._require()
        T_CW = self.camera.world_from_camera(history.state_at(t)).inverse()
        return self.renderer.render(T_CW, pad, noise_key(self._seed, max(tick, 0)))

    def _require(self) -> tuple[StateHistory, Pad]:
        if self._history is None or self._pad is None:
            raise InvalidInputError("call Flight.reset(state) before measuring")
        return self._history, self._pad

    def measure(self, now: float) -> Measurement:
        """The frame captured ``k`` ticks before ``now``, paired with the state at ``now``."""
        history, pad = self._require()
        fps = self.camera.params.fps
        tick = int(round(now * fps)) - self.buffer_size
        if self._cache is not None and self._cache[0] == tick and self._cache[1] == now:
            return self._cache[2]
        t_cap = now - self.buffer_size / fps if tick >= 0 else history.start
        image = self._tick_image(tick, t_cap)
        shown = self.camera.world_from_camera(history.state_at(t_cap)).inverse()
        m = pair(history.state_at(now), now, t_cap, self.perception.estimate(image), shown,
                 camera=self.camera, renderer=self.renderer, pad=pad, ground_z=self.ground_z)  # fmt: skip
        self._cache = (tick, now, m, image)
        return m

    def image(self) -> NDArray[np.uint8]:
        """The image of the last measurement."""
        if self._cache is None:
            raise InvalidInputError("no measurement yet: call measure() first")
        return self._cache[3]
