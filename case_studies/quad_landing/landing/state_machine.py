"""The paper's landing state machine, with an exact accept test and a verified turn-off.

States (paper, Fig. "state machine"), preceded by a search:

* **Searching** — fly the scenario's transit (:mod:`.scenario`) and run the detector on
  every frame; the first detection is the first measurement (taken in motion).
* **Measuring** — ask the contract (:meth:`.contracts.Contract.decide`): the learned IPC
  answers through the library's one query path, :class:`ipcverify.decision.IPCQuery` (wrapped
  by :class:`ipcverify.decision.LandingQuery`), with the set moved to W by the current camera
  pose. Accept iff the answer is PROVEN in exact
  arithmetic (:func:`ipcverify.decision.landing_decision`): ``P - y in G_tau`` for every ``y``
  in the ellipsoid, where ``P = [c_x, c_y, z_max]`` and ``G_tau`` is ``G`` (``[landing]
  target_lower/upper`` of ``reproduce.toml``, the paper's ``[-0.05, 0.05]^2 x [0, 0.05]``)
  shrunk by the tracking tolerance ``tau`` (:func:`decision_target`). A query outside the
  IPC's domain of validity is answered OUTSIDE_DOMAIN and treated like a missed detection.
* **New Waypoint** — the paper's point: where the segment from the current position to
  the ellipsoid's centre leaves the ellipsoid. It is then moved vertically so that the
  camera is between ``measure_height`` and ``max_height`` above the centre (the IPC's data
  cover those heights, and the pad must fit in the image), and clamped into the
  workspace. Without a detection (or with an OUTSIDE_DOMAIN answer) the vehicle climbs
  ``climb`` m instead. Fly there,
  settle (``settle`` of the simulator config), measure again.
* **Landing** — fly horizontally above ``P``, then down to ``P + tau e_z``; cut the motors
  only once settled there and ``p - P`` lies in the cut box ``K = G - G_tau``
  (:func:`cut_box`: ``[-tau, tau]^2 x [0, 2 tau]``, checked in exact rational arithmetic),
  so that ``p - y = (p - P) + (P - y) in K + G_tau = G``; otherwise abort. A target
  ``P + tau e_z`` below the pad's surface (a pad perceived too low) drives the vehicle into
  the pad: the run is **unsafe** (:func:`into_pad`), whatever the cut test says.

A run that reaches ``max_measurements`` without accepting, finds no pad during the
transit, or cannot settle at ``P_turnoff`` is **aborted** (the motors stay on): never
counted as safe. A landed run is **safe** iff the position at the motor-off command
lies in ``{y} + G`` (``proofs/landing_safety.md``); the rest position after the fall is
recorded too. A run that flies into the pad is **unsafe**; its position at contact is
recorded as the cut position.

Examples
--------
>>> from case_studies.quad_landing.sim.config import load_config
>>> from case_studies.quad_landing.landing.contracts import TrivialContract
>>> from case_studies.quad_landing.landing.scenario import ScenarioParams
>>> from case_studies.quad_landing.landing.scenario import draw_scenario
>>> cfg = load_config()
>>> sc = draw_scenario(0, seed=0, params=ScenarioParams.defaults(), config=cfg)
>>> run = run_landing(sc, TrivialContract(), sim_config=cfg, params=LandingParams.defaults(buffer_size=1))
>>> run.outcome.name, run.n_queries   # the baseline trusts its first measurement
('UNSAFE', 1)
>>> run.reason   # OpenCV's default detector reads the range long: the pad is perceived too low
"flew into the pad: the turn-off target lies below the pad's surface (motors on at contact)"
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.landing.contracts import Contract
from case_studies.quad_landing.landing.runs import INTO_PAD_REASON, LandingRun, Outcome, QueryRecord
from case_studies.quad_landing.landing.scenario import Scenario, camera_offset_z
from case_studies.quad_landing.settings import REPRODUCE_PATH, ConfigError, TomlSection, check_positive
from case_studies.quad_landing.sim.camera import BufferSize, check_buffer_size
from case_studies.quad_landing.sim.config import SimConfig
from case_studies.quad_landing.sim.flight import Flight, Measurement
from case_studies.quad_landing.sim.legs import clamp_to_workspace, fly_leg
from case_studies.quad_landing.sim.lqr import SettleParams
from ipcverify.decision import check_landing
from ipcverify.decision._landing import QueryDecision
from ipcverify.decision.containment import Status
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets import Box, Ellipsoid
from ipcverify.sets._exact import ExactVector, exact_vector

__all__ = [
    "LandingParams",
    "decision_target",
    "cut_box",
    "cut_allowed",
    "new_waypoint",
    "in_target",
    "into_pad",
    "run_landing",
]


@dataclass(frozen=True, kw_only=True)
class LandingParams(TomlSection, file=REPRODUCE_PATH, section="landing"):
    """The landing state machine (see :mod:`.state_machine`).

    Parameters
    ----------
    target_lower, target_upper : 3 floats
        The target region ``G`` (m): the run is safe iff ``p - y`` lies in it when the motors are
        cut (the paper's ``[-0.05, 0.05]^2 x [0, 0.05]``); :attr:`target` is it as a box.
    buffer_size : int
        Camera buffer size of the landing runs (frames of lag).
    tracking_tolerance : float
        ``tau`` (m): a measurement is accepted only if the ellipsoid fits ``G`` shrunk by
        ``tau`` on every side, and the motors are cut only within ``tau`` (inf-norm) of the
        turn-off point (``proofs/landing_safety.md``).
    max_measurements : int
        Cap ``M`` on IPC queries per run; a run that reaches it without accepting aborts.
    measure_height, max_height : float
        A New Waypoint keeps the camera between these heights above the pad estimate (m).
    climb : float
        With no detection at a waypoint, climb this much and look again (m).
    search_timeout, leg_timeout, settle_timeout : float
        Seconds allowed for the transit to produce a detection, for a waypoint, and for
        settling within ``tau`` of the turn-off point; running out aborts the run.
    trajectory_every : int
        Keep every n-th frame of the trajectory (figures).

    Examples
    --------
    >>> LandingParams.defaults().tracking_tolerance  # [landing] of reproduce.toml
    0.005
    """

    target_lower: tuple[float, float, float]
    target_upper: tuple[float, float, float]
    buffer_size: BufferSize
    tracking_tolerance: float
    max_measurements: int
    measure_height: float
    max_height: float
    climb: float
    search_timeout: float
    leg_timeout: float
    settle_timeout: float
    trajectory_every: int

    def __post_init__(self) -> None:
        lo, up = (tuple(float(v) for v in getattr(self, f"target_{s}")) for s in ("lower", "upper"))
        ok = (
            len(lo) == 3
            and len(up) == 3
            and all(a <= 0.0 <= b and a < b for a, b in zip(lo, up, strict=True))
        )
        if not ok:
            raise ConfigError(
                "landing.target_lower/upper must be 3 numbers each with lower <= 0 <= upper and lower < "
                f"upper (the target G around the pad); got {self.target_lower} and {self.target_upper}"
            )
        object.__setattr__(self, "target_lower", lo)
        object.__setattr__(self, "target_upper", up)
        size = check_buffer_size(self.buffer_size, name="landing.buffer_size", error=ConfigError)
        object.__setattr__(self, "buffer_size", size)
        half = min(up[i] - lo[i] for i in range(3)) / 2.0
        if not 0.0 < self.tracking_tolerance < half:
            raise ConfigError(
                f"landing.tracking_tolerance must lie in (0, {half:g}) m: G is shrunk by tau on each side; "
                f"got {self.tracking_tolerance!r}"
            )
        check_positive("landing.max_measurements", self.max_measurements, integer=True)
        object.__setattr__(self, "max_measurements", int(self.max_measurements))
        for name in (
            "measure_height",
            "max_height",
            "climb",
            "search_timeout",
            "leg_timeout",
            "settle_timeout",
        ):
            check_positive(f"landing.{name}", getattr(self, name))
        check_positive("landing.trajectory_every", self.trajectory_every, integer=True)
        if self.measure_height >= self.max_height:
            raise ConfigError(
                f"landing.measure_height ({self.measure_height}) must be below landing.max_height "
                f"({self.max_height})"
            )

    @property
    def target(self) -> Box:
        """The target region ``G`` as a box."""
        return Box(np.asarray(self.target_lower), np.asarray(self.target_upper))


#: The final settle asks for this share of ``tau`` (Euclidean), so the exact cut test passes.
SETTLE_SHARE = 0.9


def decision_target(tau: float, target: Box) -> Box:
    """``G_tau``, the box the accept test proves ``P - y`` lies in (``P`` the turn-off point).

    ``[G.lower + (tau, tau, 0), G.upper - (tau, tau, 2 tau)]``: ``G`` shrunk by ``tau`` on
    every side and shifted down by ``tau`` in ``z``, because :func:`ipcverify.decision.landing_decision`
    puts ``P`` at the ellipsoid's top (``P_z - y_z >= 0``); the vehicle is sent to
    ``P + tau e_z`` instead.

    Examples
    --------
    >>> decision_target(0.005, LandingParams.defaults().target).upper.round(6).tolist()
    [0.045, 0.045, 0.04]
    """
    width = target.upper - target.lower
    if not (np.isfinite(tau) and 0.0 < tau and 2.0 * tau < width[:2].min() and 2.0 * tau < width[2]):
        raise InvalidInputError(
            f"tau must be > 0 and leave G_tau non-empty (tau < {width[2] / 2:g} m for this G); got {tau!r}"
        )
    shift = np.array([tau, tau, 0.0])
    return Box(target.lower + shift, target.upper - np.array([tau, tau, 2.0 * tau]))


def cut_box(tau: float, target: Box) -> tuple[ExactVector, ExactVector]:
    """``K = [G.lower - G_tau.lower, G.upper - G_tau.upper]`` in exact rationals.

    For boxes, ``K + G_tau = G`` exactly, so ``p - P in K`` and ``P - y in G_tau`` give
    ``p - y in G`` (``proofs/landing_safety.md``). About ``[-tau, tau]^2 x [0, 2 tau]``.

    Examples
    --------
    >>> lo, hi = cut_box(0.005, LandingParams.defaults().target)
    >>> [round(float(v), 6) for v in lo + hi]
    [-0.005, -0.005, 0.0, 0.005, 0.005, 0.01]
    """
    g_tau = decision_target(tau, target)
    lower = [a - b for a, b in zip(exact_vector(target.lower), exact_vector(g_tau.lower), strict=True)]
    upper = [a - b for a, b in zip(exact_vector(target.upper), exact_vector(g_tau.upper), strict=True)]
    return lower, upper


def cut_allowed(position: FloatArray, turnoff: FloatArray, tau: float, target: Box) -> bool:
    """Exact test of ``position - turnoff in K`` (:func:`cut_box`): may the motors be cut here?

    Examples
    --------
    >>> P, G = np.array([1.0, 2.0, 0.03]), LandingParams.defaults().target
    >>> cut_allowed(P + [0.004, -0.005, 0.009], P, 0.005, G), cut_allowed(P - [0, 0, 1e-9], P, 0.005, G)
    (True, False)
    """
    lower, upper = cut_box(tau, target)
    d = [a - b for a, b in zip(exact_vector(position), exact_vector(turnoff), strict=True)]
    return all(lo <= v <= hi for lo, v, hi in zip(lower, d, upper, strict=True))


def into_pad(turnoff: FloatArray, tau: float, pad: FloatArray) -> bool:
    """Whether flying to ``P + tau e_z`` drives the vehicle into the pad: its height is below ``y_z``.

    ``p - y`` in ``G`` needs ``p_z >= y_z``: the vehicle's reference point never goes below the
    pad's surface (the paper's New Waypoint rule exists "to avoid hitting the landing pad").
    A turn-off target below it is a collision, counted UNSAFE whatever the exact cut test
    says (``proofs/landing_safety.md``, Corollary 1: it needs ``y`` outside the accepted set).

    Examples
    --------
    >>> pad = np.zeros(3)
    >>> into_pad(np.array([0.0, 0.0, -0.004]), 0.005, pad), into_pad(np.array([0.0, 0.0, -0.006]), 0.005, pad)
    (False, True)
    """
    return bool(turnoff[2] + tau < pad[2])


def in_target(offset: FloatArray, target: Box) -> bool:
    """Whether ``p - y`` lies in the closed box ``G``.

    Examples
    --------
    >>> G = LandingParams.defaults().target
    >>> in_target(np.array([0.05, -0.02, 0.0]), G), in_target(np.array([0.0, 0.0, -0.001]), G)
    (True, False)
    """
    return bool(np.all(offset >= target.lower) and np.all(offset <= target.upper))


def new_waypoint(
    position: FloatArray,
    ellipsoid: Ellipsoid,
    *,
    flight: Flight,
    params: LandingParams,
) -> FloatArray:
    """The New Waypoint: the paper's segment/surface point, moved to a measuring height.

    ``s = c + (p - c) / ||C (p - c)||`` is where the segment from ``p`` to the centre ``c``
    leaves ``E(c, C)`` (``s = p`` if ``p`` is inside). Its height is then clipped so that
    the camera of a level vehicle is ``measure_height`` to ``max_height`` above ``c``,
    and the point is clamped into the workspace.

    Examples
    --------
    >>> from case_studies.quad_landing import Flight
    >>> e = Ellipsoid(np.zeros(3), np.eye(3) * 10.0)          # radius 0.1 m around the origin
    >>> flight, params = Flight(buffer_size=1), LandingParams.defaults()
    >>> new_waypoint(np.array([0.0, 0.0, 2.0]), e, flight=flight, params=params).round(3)
    array([0.  , 0.  , 0.75])
    """
    c, C = ellipsoid.centers[0], ellipsoid.shapes[0]
    g = float(np.linalg.norm(C @ (position - c)))
    s = c + (position - c) / g if g > 1.0 else position.copy()
    lift = camera_offset_z(flight.config)
    s[2] = min(max(s[2], c[2] + params.measure_height + lift), c[2] + params.max_height + lift)
    return clamp_to_workspace(s, flight)


class _Logger:
    """Keeps every n-th position of the flight."""

    def __init__(self, flight: Flight, every: int) -> None:
        self.flight, self.every, self.frame = flight, every, 0
        self.points: list[FloatArray] = [flight.state[:3]]

    def __call__(self) -> None:
        self.frame += 1
        if self.frame % self.every == 0:
            self.points.append(self.flight.state[:3])


def _record(m: Measurement, contract: Contract, target: Box) -> tuple[QueryRecord, QueryDecision | None]:
    if m.yhat_c is None:
        return QueryRecord(time=m.time, position=m.state[:3], velocity=m.state[3:6], detected=False), None
    decision = contract.decide(m, target)
    c, C = decision.center, decision.shape
    try:
        e = Ellipsoid(c, C)
        half, inside = e.half_widths()[0], bool(e.contains(m.y_w)[0])
    except SetError:  # a degenerate set (an OUTSIDE_DOMAIN answer): nothing to measure
        half, inside = None, None
    rec = QueryRecord(
        time=m.time,
        position=m.state[:3],
        velocity=m.state[3:6],
        detected=True,
        accepted=decision.accept,
        center=np.array(c, copy=True),
        shape=np.array(C, copy=True),
        half_widths=half,
        truth_inside=inside,
        x_c=m.x_c.copy(),
        yhat_c=m.yhat_c.copy(),
        in_domain=decision.in_domain,
    )
    return rec, decision


def run_landing(
    scenario: Scenario,
    contract: Contract,
    *,
    sim_config: SimConfig,
    params: LandingParams,
    flight: Flight | None = None,
) -> LandingRun:
    """Fly one landing run of ``scenario`` with ``contract``.

    Parameters
    ----------
    scenario : Scenario
        The pad, the start and the transit (:func:`.scenario.draw_scenario`).
    contract : Contract
        :class:`.contracts.LearnedContract` or :class:`.contracts.TrivialContract`.
    sim_config : SimConfig
        The simulator.
    params : LandingParams
        The state machine's settings (buffer size, ``tau``, cap, heights, timeouts).
    flight : Flight, optional
        A simulator to reuse (its config and buffer size must match); built if None.

    Returns
    -------
    LandingRun
    """
    t0 = time.perf_counter()
    if flight is None or flight.buffer_size != params.buffer_size or flight.config is not sim_config:
        flight = Flight(sim_config, buffer_size=params.buffer_size)
    flight.reset(scenario.start, scenario.pad, seed=scenario.noise_seed)
    tau = params.tracking_tolerance
    G = params.target
    target = decision_target(tau, G)
    log = _Logger(flight, params.trajectory_every)
    queries: list[QueryRecord] = []

    def finish(
        outcome: Outcome,
        reason: str,
        turnoff: FloatArray | None = None,
        cut: FloatArray | None = None,
        rest: FloatArray | None = None,
        verified: bool | None = None,
    ) -> LandingRun:
        return LandingRun(
            scenario=scenario,
            contract=contract.name,
            outcome=outcome,
            reason=reason,
            queries=tuple(queries),
            turnoff=turnoff,
            cut_position=cut,
            rest_position=rest,
            certificate_verified=verified,
            trajectory=np.array(log.points),
            flight_time=flight.time,
            wall_time=time.perf_counter() - t0,
        )

    # Searching: the transit, with the detector on every frame.
    m: Measurement | None = None
    while flight.time < params.search_timeout - 1e-9:
        flight.step(scenario.reference)
        log()
        candidate = flight.measure()
        if candidate.detected:
            m = candidate
            break
    if m is None:
        return finish(Outcome.ABORTED, f"no detection within {params.search_timeout:g} s of transit")

    # Measuring / New Waypoint.
    accepted = None
    while True:
        rec, result = _record(m, contract, target)
        queries.append(rec)
        if result is not None and result.accept:
            accepted = result
            break
        if len(queries) >= params.max_measurements:
            return finish(Outcome.ABORTED, f"cap of {params.max_measurements} measurements reached")
        here = flight.state[:3]
        if result is None or not result.in_domain:
            lift = camera_offset_z(flight.config)
            top = flight.config.sim.ground_z + params.max_height + lift
            waypoint = clamp_to_workspace(
                np.array([here[0], here[1], min(here[2] + params.climb, top)]), flight
            )
        else:
            waypoint = new_waypoint(
                here, Ellipsoid(result.center, result.shape), flight=flight, params=params
            )
        fly_leg(flight, waypoint, yaw=scenario.yaw, timeout=params.leg_timeout, on_frame=log)
        m = flight.measure()

    # Landing: over P, then down to P + tau e_z; cut only when p - P is in K (exact).
    decision = accepted
    turnoff = decision.turnoff.copy()
    verified = decision.proof is not None and check_landing(decision.proof).status is Status.PROVEN
    # A target below the pad's surface drives the vehicle into the pad (the simulator's
    # judgement, like in_target: the machine does not know y); see into_pad.
    collides = into_pad(turnoff, tau, scenario.pad.position)
    goal = clamp_to_workspace(turnoff + np.array([0.0, 0.0, tau]), flight)
    here = flight.state[:3]
    above = clamp_to_workspace(np.array([goal[0], goal[1], max(here[2], goal[2])]), flight)
    fly_leg(flight, above, yaw=scenario.yaw, timeout=params.leg_timeout, on_frame=log)
    crit = flight.config.settle
    fine = SettleParams(
        position_tolerance=SETTLE_SHARE * tau,
        velocity_tolerance=crit.velocity_tolerance,
        yaw_tolerance=crit.yaw_tolerance,
        hold_time=crit.hold_time,
    )
    leg = fly_leg(
        flight,
        goal,
        yaw=scenario.yaw,
        timeout=params.leg_timeout + params.settle_timeout,
        settle=fine,
        on_frame=log,
    )
    cut = flight.state[:3]
    if collides:
        return finish(Outcome.UNSAFE, INTO_PAD_REASON, turnoff, cut, cut.copy(), verified)
    if not (leg.settled and cut_allowed(cut, turnoff, tau, G)):
        return finish(
            Outcome.ABORTED,
            f"could not settle within tau = {tau:g} m of P + tau e_z",
            turnoff,
            verified=verified,
        )
    rest = flight.cut_motors().position
    log.points.append(rest)
    safe = in_target(cut - scenario.pad.position, G)
    reason = "motors cut inside {y} + G" if safe else "motors cut outside {y} + G"
    return finish(Outcome.SAFE if safe else Outcome.UNSAFE, reason, turnoff, cut, rest, verified)
