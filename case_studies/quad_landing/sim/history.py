"""The flight's state history: the state at any instant, for a camera that is not on the frame grid.

The simulator advances in whole camera frames of its own clock. A free-running camera
exposes its rows at other instants, and the motion-capture sample paired with an image
is taken at yet another; :class:`StateHistory` keeps the state of every simulated frame
and interpolates between them:

* position: cubic Hermite with the velocities at both ends;
* Euler angles: cubic Hermite with the Euler-angle rates ``W(eta) omega`` at both ends
  (the yaw is unwrapped first);
* velocity and body rates: linear.

Between frames 1/60 s apart the interpolation error is far below the detector's
(sub-millimetre) accuracy. Before the first entry (a flight's start at ``t = 0``) the
start state is moved back along its velocity: frames exposed before the flight began
show a vehicle that was already flying.

Examples
--------
>>> h = StateHistory()
>>> x0 = np.zeros(12); x0[3] = 1.0                    # moving at 1 m/s along x
>>> h.append(0.0, x0)
>>> x1 = x0.copy(); x1[0] = 0.1
>>> h.append(0.1, x1)
>>> round(float(h.state_at(0.05)[0]), 6), round(float(h.state_at(-0.2)[0]), 6)
(0.05, -0.2)
"""

from __future__ import annotations

import bisect

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.sim.frames import wrap_angle
from ipcverify.errors import InvalidInputError

__all__ = ["StateHistory", "euler_rates"]


def euler_rates(x: FloatArray) -> FloatArray:
    """``d/dt (roll, pitch, yaw)`` for ZYX Euler angles ``x[6:9]`` and body rates ``x[9:12]``.

    Examples
    --------
    >>> x = np.zeros(12); x[11] = 0.5                  # level, yawing at 0.5 rad/s
    >>> euler_rates(x).tolist()
    [0.0, 0.0, 0.5]
    """
    phi, theta = x[6], x[7]
    p, q, r = x[9], x[10], x[11]
    sp, cp, ct, tt = np.sin(phi), np.cos(phi), np.cos(theta), np.tan(theta)
    return np.array([p + q * sp * tt + r * cp * tt, q * cp - r * sp, (q * sp + r * cp) / ct])


def _hermite(
    y0: FloatArray, d0: FloatArray, y1: FloatArray, d1: FloatArray, h: float, s: float
) -> FloatArray:
    s2, s3 = s * s, s * s * s
    return (
        (2 * s3 - 3 * s2 + 1) * y0 + (s3 - 2 * s2 + s) * h * d0 + (-2 * s3 + 3 * s2) * y1 + (s3 - s2) * h * d1
    )


class StateHistory:
    """States at increasing times, interpolated at any instant (see the module docstring)."""

    def __init__(self) -> None:
        self._times: list[float] = []
        self._states: list[FloatArray] = []

    def __len__(self) -> int:
        return len(self._times)

    def clear(self) -> None:
        """Forget every state (a new flight)."""
        self._times.clear()
        self._states.clear()

    def append(self, time: float, state: ArrayLike) -> None:
        """Add the state at ``time`` (later than the last one)."""
        t = float(time)
        if self._times and not t > self._times[-1]:
            raise InvalidInputError(f"history times must increase: {t} after {self._times[-1]}")
        self._times.append(t)
        self._states.append(np.array(state, dtype=np.float64).reshape(12))

    @property
    def start(self) -> float:
        """Time of the first state."""
        if not self._times:
            raise InvalidInputError("the state history is empty; append the start state first")
        return self._times[0]

    @property
    def end(self) -> float:
        """Time of the last state."""
        if not self._times:
            raise InvalidInputError("the state history is empty; append the start state first")
        return self._times[-1]

    def copy(self) -> StateHistory:
        """An independent copy (the states are not shared)."""
        out = StateHistory()
        out._times = list(self._times)
        out._states = [x.copy() for x in self._states]
        return out

    def state_at(self, t: float) -> FloatArray:
        """The state at time ``t`` (a copy); after the last entry, the last state."""
        ts = self._times
        if not ts:
            raise InvalidInputError("the state history is empty; append the start state first")
        if t <= ts[0]:
            x = self._states[0].copy()
            x[0:3] += x[3:6] * (t - ts[0])  # before the start: moving with the start velocity
            return x
        if t >= ts[-1]:
            return self._states[-1].copy()
        i = bisect.bisect_right(ts, t) - 1
        t0, t1 = ts[i], ts[i + 1]
        x0, x1 = self._states[i], self._states[i + 1]
        h = t1 - t0
        s = (t - t0) / h
        x = (1.0 - s) * x0 + s * x1
        x[0:3] = _hermite(x0[0:3], x0[3:6], x1[0:3], x1[3:6], h, s)
        e1 = x0[6:9] + wrap_angle(x1[6:9] - x0[6:9])
        x[6:9] = _hermite(x0[6:9], euler_rates(x0), e1, euler_rates(x1), h, s)
        x[8] = float(wrap_angle(x[8]))
        return x
