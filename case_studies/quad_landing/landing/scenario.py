"""Random landing scenarios: a pad somewhere on the floor, the vehicle arriving in transit.

A run starts with the vehicle level at a random point 1.6–2.2 m (horizontally) from a
random pad, its camera 1.5–2.1 m above the pad, already flying at transit speed toward
a *prior guess* of the pad position (within 0.3 m of it, as from GPS or a map), at
constant height. The pad is not in view at the start; the landing state machine runs
the detector on every frame and takes its first measurement at the first detection —
while the vehicle is still moving, which is when the camera lag hurts (the design
choice is explained in ``docs/reproduce.md``). The vehicle's heading is random and
constant; with ``aligned_margin_deg > 0`` the pad's yaw is drawn so that its edges stay
that many degrees away from the image axes (OpenCV's AprilTag refinement reads the
range ~1 % short when they are within ~2 degrees, ``docs/case_study.md``).

Scenario ``i`` of a campaign seeded ``s`` depends only on ``(s, i)`` (:func:`scenario_rng`),
so the learned IPC and the baseline fly exactly the same scenarios.

Examples
--------
>>> from case_studies.quad_landing.sim.config import load_config
>>> sc = draw_scenario(0, seed=1, params=ScenarioParams.defaults(), config=load_config())
>>> bool(1.6 <= sc.start_distance <= 2.2), bool(np.linalg.norm(sc.start[3:6]) >= 1.0)
(True, True)
>>> sc.reference(0.0).position.tolist() == sc.start[:3].tolist()
True
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.settings import (
    REPRODUCE_PATH,
    ConfigError,
    Range,
    TomlSection,
    check_positive,
    check_range,
)
from case_studies.quad_landing.sim.config import SimConfig
from case_studies.quad_landing.sim.frames import wrap_angle
from case_studies.quad_landing.sim.lqr import Reference
from case_studies.quad_landing.sim.marker import Pad
from ipcverify.errors import InvalidInputError

__all__ = [
    "ScenarioParams",
    "Scenario",
    "draw_scenario",
    "scenario_rng",
    "camera_offset_z",
    "stopping_reference",
    "SCENARIO_STREAM",
]


@dataclass(frozen=True, kw_only=True)
class ScenarioParams(TomlSection, file=REPRODUCE_PATH, section="scenario"):
    """How a landing run starts: a random pad, the vehicle arriving toward a prior guess of it.

    Parameters
    ----------
    pad_region : float
        Pad centre ``x, y`` uniform in ``[-r, r]`` (m).
    start_distance, start_height : (low, high)
        Horizontal distance from the pad and camera height above it at the start (m).
    transit_speed : (low, high)
        Speed of the transit toward the prior guess (m/s).
    prior_radius : float
        The prior guess of the pad lies uniformly within this radius of it (m).
    aligned_margin_deg : float
        The pad's edges are kept at least this many degrees from the image axes (0 turns
        it off): OpenCV's AprilTag refinement reads the range ~1 % short within ~2 degrees.
    deceleration : float
        Past the prior guess the transit brakes smoothly at up to this (m/s^2).

    Examples
    --------
    >>> ScenarioParams.defaults().transit_speed  # [scenario] of reproduce.toml
    (1.2, 1.8)
    """

    pad_region: float
    start_distance: Range
    start_height: Range
    transit_speed: Range
    prior_radius: float
    aligned_margin_deg: float
    deceleration: float

    def __post_init__(self) -> None:
        check_positive("scenario.pad_region", self.pad_region)
        check_positive("scenario.deceleration", self.deceleration)
        check_positive("scenario.prior_radius", self.prior_radius, allow_zero=True)
        for name in ("start_distance", "start_height", "transit_speed"):
            object.__setattr__(self, name, check_range(f"scenario.{name}", getattr(self, name), 0.0))
        if self.start_height[0] < 0.8:
            raise ConfigError("scenario.start_height must start at >= 0.8 m (the IPC's height range)")
        if not 0.0 <= self.aligned_margin_deg < 45.0:
            raise ConfigError(
                f"scenario.aligned_margin_deg must lie in [0, 45), got {self.aligned_margin_deg}"
            )


#: Separates the random streams of scenarios from those of exploration paths.
SCENARIO_STREAM = 61
#: Keep start and search points this far inside the workspace (m).
WORKSPACE_MARGIN = 0.25


def scenario_rng(seed: int, index: int, stream: int = SCENARIO_STREAM) -> np.random.Generator:
    """The generator of scenario ``index`` of a campaign seeded ``seed`` (independent of all else)."""
    return np.random.default_rng([int(seed), int(index), int(stream)])


def camera_offset_z(config: SimConfig) -> float:
    """Height of the centre of mass above the camera for a level vehicle (m), e.g. 0.05."""
    return -float(config.camera.offset[2])


@dataclass(frozen=True, eq=False)
class Scenario:
    """One landing scenario.

    Attributes
    ----------
    index, noise_seed : int
        Scenario index and the seed of its sensor noise.
    pad : Pad
        The true pad (unknown to the vehicle).
    start : ndarray, shape (12,)
        Start state: level, heading ``yaw``, moving at the transit velocity.
    search_point : ndarray, shape (3,)
        Where the transit heads: the prior guess of the pad at the start height (m).
    yaw : float
        The vehicle's (constant) heading (rad).
    deceleration : float
        The transit passes the search point and then brakes smoothly at up to this (m/s^2).
    """

    index: int
    noise_seed: int
    pad: Pad
    start: FloatArray
    search_point: FloatArray
    yaw: float
    deceleration: float

    def __post_init__(self) -> None:
        for name, shape in (("start", (12,)), ("search_point", (3,))):
            a = np.array(getattr(self, name), dtype=np.float64).reshape(-1)
            if a.shape != shape or not np.isfinite(a).all():
                raise InvalidInputError(f"scenario {name} must be {shape[0]} finite numbers")
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    @property
    def velocity(self) -> FloatArray:
        """The transit velocity (m/s)."""
        return self.start[3:6].copy()

    @property
    def start_distance(self) -> float:
        """Horizontal distance from the start to the pad (m)."""
        return float(np.linalg.norm(self.start[:2] - self.pad.position[:2]))

    @property
    def transit_time(self) -> float:
        """Time for the transit reference to reach the search point (s)."""
        speed = float(np.linalg.norm(self.start[3:6]))
        dist = float(np.linalg.norm(self.search_point - self.start[:3]))
        return dist / speed if speed > 0 else 0.0

    def reference(self, t: float) -> Reference:
        """The transit reference at flight time ``t``: straight at constant speed through the
        search point, then a smooth stop (:func:`stopping_reference`)."""
        t_s = self.transit_time
        if t < t_s:
            return Reference(self.start[:3] + t * self.start[3:6], self.start[3:6], self.yaw)
        at_search = Reference(self.search_point, self.start[3:6], self.yaw)
        return stopping_reference(at_search, t_s, self.deceleration)(t)

    def to_dict(self) -> dict[str, object]:
        """Plain data (for summaries)."""
        return {
            "index": self.index,
            "pad": self.pad.position.tolist(),
            "pad_yaw": self.pad.yaw,
            "start": self.start[:3].tolist(),
            "velocity": self.start[3:6].tolist(),
            "search_point": self.search_point.tolist(),
            "yaw": self.yaw,
        }


def stopping_reference(reference: Reference, t0: float, deceleration: float) -> Callable[[float], Reference]:
    """From ``reference`` at time ``t0``, brake smoothly along its velocity to a stop.

    The speed follows ``v0 (1 + cos(pi s / T)) / 2`` over ``T = pi v0 / (2 a)``, so the
    braking acceleration rises from 0 to at most ``a = deceleration`` and back; the
    reference carries acceleration and jerk as feedforward, so the vehicle tilts back
    smoothly instead of answering a step.

    Examples
    --------
    >>> ref = stopping_reference(Reference((0.0, 0.0, 1.0), (1.0, 0.0, 0.0)), 2.0, 0.5)
    >>> np.round(ref(8.0).position, 6).tolist(), ref(8.0).velocity.tolist()
    ([1.570796, 0.0, 1.0], [0.0, 0.0, 0.0])
    """
    if not (np.isfinite(deceleration) and deceleration > 0):
        raise InvalidInputError(f"deceleration must be > 0, got {deceleration!r}")
    p0, v0, yaw = reference.position.copy(), reference.velocity.copy(), reference.yaw
    speed = float(np.linalg.norm(v0))
    unit = v0 / speed if speed > 0 else np.zeros(3)
    period = np.pi * speed / (2.0 * deceleration)

    def ref(t: float) -> Reference:
        s = min(max(t - t0, 0.0), period)
        if period == 0.0 or t - t0 >= period:
            return Reference(p0 + 0.5 * speed * period * unit, np.zeros(3), yaw)
        w = np.pi / period
        dist = 0.5 * speed * (s + np.sin(w * s) / w)
        vel = 0.5 * speed * (1.0 + np.cos(w * s))
        acc = -0.5 * speed * w * np.sin(w * s)
        jerk = -0.5 * speed * w * w * np.cos(w * s)
        return Reference(p0 + dist * unit, vel * unit, yaw, acc * unit, jerk * unit)

    return ref


def _inside(p: ArrayLike, config: SimConfig, margin: float) -> bool:
    q = np.asarray(p)
    lo = np.asarray(config.sim.workspace_min) + margin
    hi = np.asarray(config.sim.workspace_max) - margin
    return bool(np.all(q[:2] >= lo[:2]) and np.all(q[:2] <= hi[:2]) and lo[2] <= q[2] <= hi[2] + margin)


def draw_scenario(
    index: int,
    *,
    seed: int,
    params: ScenarioParams,
    config: SimConfig,
    stream: int = SCENARIO_STREAM,
) -> Scenario:
    """Draw scenario ``index`` of a campaign seeded ``seed``.

    Parameters
    ----------
    index, seed : int
        Which scenario; it depends on nothing else.
    params : ScenarioParams
        Ranges of the pad, start and transit.
    config : SimConfig
        The simulator (workspace, floor height, camera mount).
    stream : int
        Random stream (approach flights use their own).

    Raises
    ------
    InvalidInputError
        If the ranges do not fit in the workspace.
    """
    rng = scenario_rng(seed, index, stream)
    r = params.pad_region
    lo_ws, hi_ws = np.asarray(config.sim.workspace_min), np.asarray(config.sim.workspace_max)
    r_fit = float(min(r, *(hi_ws[:2] - WORKSPACE_MARGIN), *(-(lo_ws[:2] + WORKSPACE_MARGIN))))
    if r_fit <= 0:
        raise InvalidInputError("the workspace is too small for the pad region")
    pad_xy = rng.uniform(-r_fit, r_fit, 2)
    ground = config.sim.ground_z
    yaw = float(rng.uniform(-np.pi, np.pi))
    m = np.deg2rad(params.aligned_margin_deg)
    pad_yaw = float(wrap_angle(yaw + rng.integers(4) * np.pi / 2 + rng.uniform(m, np.pi / 2 - m)))
    pad = Pad(np.array([pad_xy[0], pad_xy[1], ground]), pad_yaw)
    z = ground + float(rng.uniform(*params.start_height)) + camera_offset_z(config)
    dist = float(rng.uniform(*params.start_distance))
    speed = float(rng.uniform(*params.transit_speed))
    angle = float(rng.uniform(0, 2 * np.pi))
    prior = params.prior_radius * np.sqrt(rng.random()) * np.array([np.cos(angle), np.sin(angle)])
    search = np.array([pad_xy[0] + prior[0], pad_xy[1] + prior[1], z])
    for _ in range(200):
        bearing = rng.uniform(0, 2 * np.pi)
        start = np.array([pad_xy[0] + dist * np.cos(bearing), pad_xy[1] + dist * np.sin(bearing), z])
        if _inside(start, config, WORKSPACE_MARGIN) and _inside(search, config, 0.0):
            break
    else:
        raise InvalidInputError(
            f"scenario {index}: no start point {dist:.2f} m from the pad fits in the workspace; "
            "reduce scenario.start_distance or scenario.pad_region"
        )
    heading = search - start
    heading[2] = 0.0
    velocity = speed * heading / max(float(np.linalg.norm(heading)), 1e-9)
    state = np.zeros(12)
    state[:3], state[3:6], state[8] = start, velocity, yaw
    return Scenario(
        index=int(index),
        noise_seed=int(rng.integers(2**31)),
        pad=pad,
        start=state,
        search_point=search,
        yaw=yaw,
        deceleration=params.deceleration,
    )
