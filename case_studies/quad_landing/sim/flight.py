"""The closed-loop simulator: quadrotor, LQR, a camera with its timing, ArUco.

:class:`Flight` is the library entry point for anything that flies: data collection
(:mod:`.collect`) and a landing state machine. Time advances in whole camera frames of
the simulator's clock; each frame runs ``physics_rate / fps`` RK4 steps of the CasADi
model with the LQR evaluated at every step and appends the state to the flight's
:class:`.history.StateHistory`. A :meth:`Flight.measure` asks the camera stage
(:func:`.camera.build_camera_stage`, chosen by ``[camera_timing]``) for the image the
application has now — with the timing model, the frame the reader loop last processed,
exposed on the camera's own clock — and the motion-capture state paired with it.

Examples
--------
>>> from case_studies.quad_landing.sim.dynamics import hover_state
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.3, 0.0, 1.5)))
>>> flight.fly_to((0.0, 0.0, 1.2)).settled
True
>>> m = flight.measure()
>>> m.detected, bool(np.linalg.norm(m.yhat_w - m.y_w) < 0.02)
(True, True)
>>> flight.fly_to((0.0, 0.0, 0.1)).settled and flight.cut_motors().landed
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import casadi as ca
import numpy as np
from numpy.typing import ArrayLike, NDArray

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.perception.aruco import ArucoPerception
from case_studies.quad_landing.sim.camera import Camera, Measurement, Renderer, build_camera_stage
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.dynamics import rk4_step
from case_studies.quad_landing.sim.frames import Pose
from case_studies.quad_landing.sim.history import StateHistory
from case_studies.quad_landing.sim.lqr import HoverLqr, Reference, SettleParams, is_settled
from case_studies.quad_landing.sim.marker import Pad
from case_studies.quad_landing.sim.paths import ExplorationPath
from ipcverify.errors import InvalidInputError

__all__ = ["Flight", "Measurement", "FlyResult", "LandingResult"]  # Measurement: from .measurement

ReferenceLike = Reference | Callable[[float], Reference] | None


class _BufferedFunction:
    """Call a CasADi ``Function`` of dense vectors through its buffer API (no DM copies)."""

    def __init__(self, fn: ca.Function) -> None:
        self._buf, self._eval = fn.buffer()
        self._args = [np.zeros(fn.size1_in(i)) for i in range(fn.n_in())]
        self._res = [np.zeros(fn.size1_out(i)) for i in range(fn.n_out())]
        # CasADi's type stub lists a byte size that its Python binding does not accept (it takes
        # the size from the buffer): hence the ignores
        for i, a in enumerate(self._args):
            self._buf.set_arg(i, a.data)  # type: ignore[call-arg]
        for i, r in enumerate(self._res):
            self._buf.set_res(i, r.data)  # type: ignore[call-arg]

    def __call__(self, *args: FloatArray) -> FloatArray:
        for dst, src in zip(self._args, args, strict=True):
            dst[:] = src
        self._eval()
        return self._res[0].copy()


@dataclass(frozen=True)
class FlyResult:
    """Outcome of :meth:`Flight.fly_to`: settled or not, and the time taken (s)."""

    settled: bool
    elapsed: float
    position_error: float


@dataclass(frozen=True)
class LandingResult:
    """Outcome of :meth:`Flight.cut_motors`: touchdown position in W and time to fall (s)."""

    landed: bool
    position: FloatArray
    elapsed: float


class Flight:
    """A simulated quadrotor flight with a camera over a landing pad.

    Parameters
    ----------
    config : SimConfig, optional
        Defaults from ``defaults.toml`` when omitted.
    buffer_size : int
        Camera buffer size: the number of V4L2 buffers of the timing model (or ``k``
        frames of lag with ``[camera_timing] model = "frames"``; 0 is an ideal camera). The
        flight's only source of it: data collection passes ``[collect] buffer_size`` (or
        its ``buffer_size`` argument), a landing run ``[landing] buffer_size``.
    seed : int
        Seeds the sensor noise and the camera's timing draws.

    Notes
    -----
    Call :meth:`reset` before flying. Use :meth:`fly_to` / :meth:`hold` /
    :meth:`step` to move, :meth:`measure` to take a lagged measurement,
    :meth:`cut_motors` to turn the motors off and fall to the floor.
    """

    def __init__(self, config: SimConfig | None = None, *, buffer_size: int, seed: int = 0) -> None:
        self.config = load_config() if config is None else config
        self.camera_stage = build_camera_stage(self.config, buffer_size)
        self.camera: Camera = self.camera_stage.camera
        self.renderer: Renderer = self.camera_stage.renderer
        self.perception: ArucoPerception = self.camera_stage.perception
        self.history = StateHistory()
        self.controller = HoverLqr.design(self.config.quad, self.config.lqr)
        self.dt = 1.0 / self.config.sim.physics_rate
        self.step_function = rk4_step(self.config.quad, self.dt)
        self._step = _BufferedFunction(self.step_function)
        self._rng = np.random.default_rng(seed)
        self._sensor_seed = 0
        self.pad: Pad = self.config.pad
        self._state: FloatArray | None = None
        self._time = 0.0
        self._reference: Reference | None = None
        self.motors_on = True

    # ------------------------------------------------------------------ state
    @property
    def buffer_size(self) -> int:
        """The camera buffer size."""
        return self.camera_stage.buffer_size

    @property
    def sensor_seed(self) -> int:
        """This flight's sensor seed (noise and camera timing), drawn at :meth:`reset`."""
        return self._sensor_seed

    @property
    def state(self) -> FloatArray:
        """A copy of the current 12-state in W."""
        return self._require_state().copy()

    @property
    def time(self) -> float:
        """Simulated time since :meth:`reset` (s)."""
        return self._time

    @property
    def on_ground(self) -> bool:
        """True if the quadrotor rests on the floor."""
        x = self._require_state()
        return bool(x[2] <= self.config.sim.ground_z + 1e-9 and not np.any(x[3:6]))

    def _require_state(self) -> FloatArray:
        if self._state is None:
            raise InvalidInputError("call Flight.reset(state) before flying or measuring")
        return self._state

    def reset(self, state: ArrayLike, pad: Pad | None = None, *, seed: int | None = None) -> None:
        """Start a flight at ``state`` (12,) with the pad at ``pad`` (unchanged if None).

        The state history starts with ``state`` at ``t = 0`` (before it, the vehicle is taken
        to have been moving with the start velocity), the camera starts its flight, motors
        are on and the reference is to hold the start position and heading. ``seed``
        re-seeds the sensor noise and the camera's timing draws.
        """
        x = np.array(state, dtype=np.float64).reshape(-1)
        if x.shape != (12,) or not np.all(np.isfinite(x)):
            raise InvalidInputError(f"start state must be 12 finite numbers, got shape {x.shape}")
        self._check_in_workspace(x[:3], "start position")
        if pad is not None:
            if not isinstance(pad, Pad):
                raise InvalidInputError(f"pad must be a Pad, got {type(pad).__name__}")
            self._check_in_workspace(pad.position, "pad position")
            self.pad = pad
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        self._state = x
        self._time = 0.0
        self.motors_on = True
        self._reference = Reference(x[:3], np.zeros(3), float(x[8]))
        self.history = StateHistory()
        self.history.append(0.0, x)
        self._sensor_seed = int(self._rng.integers(2**31))
        self.camera_stage.begin(self.history, self.pad, self._sensor_seed)

    def _check_in_workspace(self, p: FloatArray, what: str) -> None:
        lo = np.asarray(self.config.sim.workspace_min)
        hi = np.asarray(self.config.sim.workspace_max)
        if np.any(p < lo - 1e-9) or np.any(p > hi + 1e-9):
            raise InvalidInputError(
                f"{what} {np.round(p, 3).tolist()} is outside the workspace "
                f"{list(lo)}..{list(hi)}; choose a point inside it"
            )

    # ------------------------------------------------------------------ camera
    def camera_pose(self, state: ArrayLike | None = None) -> Pose:
        """``T_WC`` at ``state`` (default: the current state)."""
        return self.camera.world_from_camera(self._require_state() if state is None else state)

    def pad_in_view(self, state: ArrayLike | None = None, margin_px: float = 0.0) -> bool:
        """True if the whole white pad would be inside the image at ``state`` (default: now).

        A geometric check (no rendering, no detection, no lag), e.g. to choose a
        waypoint from which a measurement will see the pad.
        """
        x = self._require_state() if state is None else np.asarray(state, dtype=np.float64)
        outline = self.renderer.pad_corners_camera(self.camera_pose(x).inverse(), self.pad)
        return self.camera.in_view(outline, margin_px=margin_px)

    def latest_image(self) -> NDArray[np.uint8]:
        """An image of the current state (no lag, no motion blur) with this flight's sensor noise."""
        return self.renderer.render(self.camera_pose().inverse(), self.pad, self._sensor_seed)

    # ------------------------------------------------------------------ motion
    def _advance(self, p_ref: FloatArray, v_ref: FloatArray, ff: FloatArray, yaw_ref: FloatArray) -> None:
        """One camera frame: ``substeps`` physics steps with per-step references, then capture.

        Row ``i`` of each array is the reference of physics step ``i``; ``ff`` rows are
        ``[acceleration, jerk, yaw_rate]`` (see :meth:`HoverLqr.thrusts`).
        """
        x = self._require_state()
        ground = self.config.sim.ground_z
        for i in range(self.config.substeps):
            if self.motors_on:
                u = self.controller.thrusts(x, p_ref[i], v_ref[i], ff[i], float(yaw_ref[i]))
            else:
                u = self.controller.motors_off()
            x = self._step(x, u)
            if x[2] < ground:  # touchdown: the floor stops the vehicle
                x[2] = ground
                x[3:8] = 0.0
                x[9:12] = 0.0
            self._time += self.dt
        if not np.isfinite(x).all():
            raise FloatingPointError(
                f"simulation diverged at t = {self._time:.3f} s; check the configuration"
            )
        self._state = x
        self.history.append(self._time, x)

    def step(self, reference: ReferenceLike = None) -> None:
        """Advance one camera frame, tracking ``reference`` (a Reference or ``t -> Reference``).

        ``None`` keeps the last reference; after :meth:`cut_motors` the motors stay off.
        """
        self._require_state()
        n = self.config.substeps
        if callable(reference) and not isinstance(reference, Reference):
            refs = [reference(self._time + i * self.dt) for i in range(n)]
            self._reference = refs[-1]
        else:
            if reference is not None:
                self._reference = reference
            assert self._reference is not None
            refs = [self._reference] * n
        self._advance(
            np.array([r.position for r in refs]),
            np.array([r.velocity for r in refs]),
            np.array([np.r_[r.acceleration, r.jerk, r.yaw_rate] for r in refs]),
            np.array([r.yaw for r in refs]),
        )

    def follow(self, path: ExplorationPath, duration: float | None = None) -> Iterator[int]:
        """Track ``path`` from its time 0 for ``duration`` s (its own by default).

        A generator: it advances one camera frame per iteration and yields the frame
        number (1, 2, ...), so the caller can :meth:`measure` in between. Path time
        starts at the current flight time.

        Examples
        --------
        >>> from case_studies.quad_landing.sim.paths import ExplorationPath
        >>> from case_studies.quad_landing.sim.dynamics import hover_state
        >>> path = ExplorationPath(name="still", center=(0, 0, 1.5), amplitude=(0, 0, 0),
        ...                        omega=(1, 1, 1), phase=(0, 0, 0), duration=0.5)
        >>> flight = Flight(buffer_size=1)
        >>> flight.reset(hover_state((0, 0, 1.5)))
        >>> sum(1 for _ in flight.follow(path))  # 0.5 s at 60 fps
        30
        """
        self._require_state()
        length = path.duration if duration is None else duration
        n_frames = int(round(length * self.config.camera.fps))
        n = self.config.substeps
        t = np.arange(n_frames * n) * self.dt  # path time at every physics step
        r = path.sample(t)
        ff = np.column_stack([r.acceleration, r.jerk, r.yaw_rate])
        for k in range(n_frames):
            sl = slice(k * n, (k + 1) * n)
            self._advance(r.position[sl], r.velocity[sl], ff[sl], r.yaw[sl])
            yield k + 1
        if n_frames:
            self._reference = path.reference(float(t[-1]))

    def fly_to(
        self,
        position: ArrayLike,
        yaw: float | None = None,
        *,
        max_time: float = 20.0,
        settle: SettleParams | None = None,
    ) -> FlyResult:
        """Fly to a waypoint and stop there; returns once settled or after ``max_time`` s.

        Parameters
        ----------
        position : array_like, shape (3,)
            Waypoint in W (must be inside the workspace).
        yaw : float, optional
            Heading at the waypoint (rad); keeps the current reference heading if None.
        max_time : float
            Give up after this many seconds (the result then has ``settled=False``).
        settle : SettleParams, optional
            Settle criterion; ``config.settle`` if None.
        """
        self._require_state()
        if not self.motors_on:
            raise InvalidInputError("the motors are off; reset() the flight to fly again")
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise InvalidInputError(f"waypoint must be 3 finite numbers, got {position!r}")
        self._check_in_workspace(p, "waypoint")
        if not (np.isfinite(max_time) and max_time > 0):
            raise InvalidInputError(f"max_time must be > 0 s, got {max_time}")
        crit = self.config.settle if settle is None else settle
        assert self._reference is not None
        ref = Reference(p, np.zeros(3), self._reference.yaw if yaw is None else yaw)
        start, held = self._time, 0.0
        while self._time - start < max_time - 1e-9:
            self.step(ref)
            settled = is_settled(self._require_state(), ref.position, ref.yaw, crit)
            held = held + 1.0 / self.config.camera.fps if settled else 0.0
            if held >= crit.hold_time - 1e-9:
                break
        err = float(np.linalg.norm(self._require_state()[:3] - p))
        return FlyResult(held >= crit.hold_time - 1e-9, self._time - start, err)

    def hold(self, duration: float) -> None:
        """Keep tracking the current reference for ``duration`` seconds."""
        n = int(round(duration * self.config.camera.fps))
        for _ in range(max(n, 0)):
            self.step()

    def cut_motors(self, max_time: float = 5.0) -> LandingResult:
        """Turn the motors off and fall until the vehicle rests on the floor."""
        self._require_state()
        self.motors_on = False
        start = self._time
        while not self.on_ground and self._time - start < max_time:
            self.step()
        return LandingResult(self.on_ground, self._require_state()[:3].copy(), self._time - start)

    # ------------------------------------------------------------------ perception
    def measure(self) -> Measurement:
        """The measurement the application has now: the camera stage's image, detected, paired.

        With the timing model the paired state is the motion-capture sample the reader loop
        read; with the fixed lag it is the current state.
        """
        self._require_state()
        return self.camera_stage.measure(self._time)
