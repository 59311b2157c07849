"""Test flights like the paper's manual ones: a pilot model flying smoothly around the pad.

The paper tested its IPC at each buffer size on about 300 measurements taken while the
authors "manually control[led] the quadcopter to fly in the workspace". A pilot flying a
position-holding quadrotor with sticks commands slowly varying velocities and keeps the
target under the vehicle. The model (``[pilot]`` of ``reproduce.toml``, every value an
assumption about a careful indoor pilot):

* horizontal velocity command per axis: an Ornstein--Uhlenbeck process (time constant
  ``tau``, stationary standard deviation ``speed_std``), low-passed once more (``smooth``)
  so the acceleration is continuous, plus a pull ``centering * (pad - p)`` that keeps the
  pad under the camera;
* height: an Ornstein--Uhlenbeck climb rate (``climb_std``) pulled to a per-flight height
  drawn in ``height``, held inside ``[min_height, max_height]``;
* heading: an Ornstein--Uhlenbeck yaw rate (``yaw_rate_std``, ``yaw_tau``).

The reference carries velocity and acceleration as feed-forward, so the LQR flies it
smoothly. A flight lasts ``warmup + duration`` seconds and is measured every
``sample_every`` camera frames after the warm-up. Flight ``i`` of seed ``s`` depends only
on ``(s, i)``: every buffer size (and every camera variant) is tested on the same flights.

Examples
--------
>>> from case_studies.quad_landing import Flight
>>> rec = record_pilot(Flight(buffer_size=1), 0, seed=2, params=PilotParams.defaults(duration=2.0))
>>> len(rec.sample_times), bool(rec.flight_time >= 3.0)
(10, True)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.data.recording import FlightRecording, recording_of
from case_studies.quad_landing.landing.scenario import camera_offset_z
from case_studies.quad_landing.settings import REPRODUCE_PATH, Range, TomlSection, check_positive, check_range
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.lqr import Reference
from case_studies.quad_landing.sim.marker import Pad

__all__ = ["PilotParams", "PILOT_STREAM", "pilot_reference", "record_pilot"]


#: Random stream of pilot flights (separate from paths, approach flights and scenarios).
PILOT_STREAM = 97
#: Time step of the precomputed pilot reference (s): the physics rate.
REFERENCE_DT = 1.0 / 240.0


@dataclass(frozen=True, kw_only=True)
class PilotParams(TomlSection, file=REPRODUCE_PATH, section="pilot"):
    """The pilot model of the test flights (``[pilot]``; see :mod:`.pilot`).

    Parameters
    ----------
    duration, warmup : float
        Seconds measured, and flown before the first measurement.
    sample_every : int
        Camera frames between measurements.
    speed_std, tau, smooth, centering : float
        Velocity command: stationary std per axis (m/s), time constant (s), extra low-pass (s),
        pull toward the column above the pad (1/s).
    climb_std : float
        Climb-rate std (m/s).
    height : (low, high)
        Camera height above the pad, drawn per flight (m).
    min_height, max_height : float
        The camera height is held in this range (m).
    yaw_rate_std, yaw_tau : float
        Yaw-rate std (rad/s) and time constant (s).
    start_offset : float
        Std of the start's horizontal offset from the pad (m).

    Examples
    --------
    >>> PilotParams.defaults().sample_every  # [pilot] of reproduce.toml
    12
    """

    duration: float
    warmup: float
    sample_every: int
    speed_std: float
    tau: float
    smooth: float
    centering: float
    climb_std: float
    height: Range
    min_height: float
    max_height: float
    yaw_rate_std: float
    yaw_tau: float
    start_offset: float

    def __post_init__(self) -> None:
        for name in ("duration", "tau", "smooth", "yaw_tau", "min_height", "max_height"):
            check_positive(f"pilot.{name}", getattr(self, name))
        for name in ("warmup", "speed_std", "centering", "climb_std", "yaw_rate_std", "start_offset"):
            check_positive(f"pilot.{name}", getattr(self, name), allow_zero=True)
        check_positive("pilot.sample_every", self.sample_every, integer=True)
        object.__setattr__(self, "sample_every", int(self.sample_every))
        object.__setattr__(self, "height", check_range("pilot.height", self.height, self.min_height))


def pilot_reference(
    rng: np.random.Generator, pad: Pad, params: PilotParams, lift: float
) -> tuple[Callable[[float], Reference], FloatArray]:
    """A pilot's reference ``t -> Reference`` over the flight, and its start state.

    ``lift`` is the height of the body above the camera (the camera hangs below the centre
    of mass), so the heights of ``params`` are the camera's.
    """
    p, dt = params, REFERENCE_DT
    n = int(np.ceil((p.warmup + p.duration + 1.0) / dt)) + 1
    pad_xy = pad.position[:2]
    h0 = float(rng.uniform(*p.height))
    pos, vel = np.zeros((n, 3)), np.zeros((n, 3))
    yaw, yaw_rate = np.zeros(n), np.zeros(n)
    start = rng.normal(0.0, p.start_offset, 2)
    pos[0] = [pad_xy[0] + start[0], pad_xy[1] + start[1], pad.position[2] + h0 + lift]
    yaw[0] = rng.uniform(-np.pi, np.pi)
    cmd = rng.normal(0.0, p.speed_std, 2)
    smooth_v, vz, yr = cmd.copy(), 0.0, rng.normal(0.0, p.yaw_rate_std)
    a_h, a_y = np.exp(-dt / p.tau), np.exp(-dt / p.yaw_tau)
    b_h, b_y = p.speed_std * np.sqrt(1 - a_h**2), p.yaw_rate_std * np.sqrt(1 - a_y**2)
    b_z = p.climb_std * np.sqrt(1 - a_h**2)
    a_s = dt / (p.smooth + dt)
    for k in range(1, n):
        cmd = a_h * cmd + b_h * rng.normal(size=2)
        smooth_v = smooth_v + a_s * (cmd + p.centering * (pad_xy - pos[k - 1, :2]) - smooth_v)
        h = pos[k - 1, 2] - pad.position[2] - lift
        vz = a_h * vz + b_z * rng.normal() + 0.3 * (h0 - h) * dt / p.tau
        if (h <= p.min_height and vz < 0) or (h >= p.max_height and vz > 0):
            vz = 0.0
        yr = a_y * yr + b_y * rng.normal()
        vel[k, :2], vel[k, 2] = smooth_v, vz
        pos[k] = pos[k - 1] + vel[k] * dt
        yaw[k], yaw_rate[k] = yaw[k - 1] + yr * dt, yr
    kernel = np.ones(9) / 9.0  # light smoothing of the finite-difference acceleration
    raw: FloatArray = np.asarray(np.gradient(vel, dt, axis=0))
    acc = np.column_stack([np.convolve(raw[:, i], kernel, mode="same") for i in range(3)])

    def ref(t: float) -> Reference:
        k = int(min(max(round(t / dt), 0), n - 1))
        return Reference(pos[k], vel[k], float(yaw[k]), acc[k], np.zeros(3), float(yaw_rate[k]))

    x0 = np.zeros(12)
    x0[0:3], x0[3:6], x0[8] = pos[0], vel[0], yaw[0]
    return ref, x0


def record_pilot(flight: Flight, index: int, *, seed: int, params: PilotParams) -> FlightRecording:
    """Fly pilot flight ``index`` over the flight's pad and keep it with its sampling instants."""
    rng = np.random.default_rng([int(seed), int(index), PILOT_STREAM])
    ref, x0 = pilot_reference(rng, flight.pad, params, camera_offset_z(flight.config))
    flight.reset(x0, seed=int(rng.integers(2**31)))
    fps = flight.config.camera.fps
    warm = int(round(params.warmup * fps))
    times: list[float] = []
    for frame in range(1, warm + int(round(params.duration * fps)) + 1):
        flight.step(ref)
        if frame > warm and (frame - warm) % params.sample_every == 0:
            times.append(flight.time)
    return recording_of(flight, index=index, sample_times=times)
