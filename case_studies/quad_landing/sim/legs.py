"""Flying a leg to a waypoint frame by frame, with a hook per frame (for measuring on the way).

:meth:`.flight.Flight.fly_to` flies to a waypoint in one call; the landing state machine and
the approach flights need to act between frames (run the detector, record a measurement),
so :func:`fly_leg` steps :meth:`.flight.Flight.step` itself and calls ``on_frame`` after every
frame. A leg is *settled* when the vehicle has stayed within the settle tolerances of the
waypoint for ``settle.hold_time``; it can then dwell there for ``dwell`` more seconds.

Examples
--------
>>> from case_studies.quad_landing import Flight, hover_state
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.3, 0.0, 1.5)))
>>> leg = fly_leg(flight, (0.0, 0.0, 1.2), yaw=0.0, timeout=10.0)
>>> leg.settled, bool(leg.elapsed < 5.0)
(True, True)
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.lqr import Reference, SettleParams, is_settled
from ipcverify.errors import InvalidInputError

__all__ = ["LegResult", "fly_leg", "clamp_to_workspace", "is_settled"]


@dataclass(frozen=True)
class LegResult:
    """Outcome of :func:`fly_leg`: settled or not, time flown (s), distance left (m, Euclidean)."""

    settled: bool
    elapsed: float
    position_error: float


def clamp_to_workspace(point: ArrayLike, flight: Flight) -> FloatArray:
    """``point`` moved into the simulator's workspace box (coordinate-wise).

    Examples
    --------
    >>> from case_studies.quad_landing import Flight
    >>> clamp_to_workspace((4.0, 0.0, -0.2), Flight(buffer_size=1)).tolist()
    [3.0, 0.0, 0.0]
    """
    p = np.asarray(point, dtype=np.float64).reshape(3)
    lo = np.asarray(flight.config.sim.workspace_min)
    hi = np.asarray(flight.config.sim.workspace_max)
    return np.minimum(np.maximum(p, lo), hi)


def fly_leg(
    flight: Flight,
    target: ArrayLike,
    *,
    yaw: float,
    timeout: float,
    settle: SettleParams | None = None,
    dwell: float = 0.0,
    on_frame: Callable[[], None] | None = None,
) -> LegResult:
    """Fly to ``target`` (held still, heading ``yaw``) until settled plus ``dwell`` s, or ``timeout`` s.

    Parameters
    ----------
    flight : Flight
        The simulator, motors on.
    target : array_like, shape (3,)
        Waypoint in W, inside the workspace.
    yaw : float
        Heading to hold (rad).
    timeout : float
        Give up after this many seconds (``settled`` is then False).
    settle : SettleParams, optional
        Settle criterion; ``flight.config.settle`` if None.
    dwell : float
        Seconds to stay after settling (the leg still counts as settled).
    on_frame : callable, optional
        Called after every frame (e.g. to take a measurement).

    Raises
    ------
    InvalidInputError
        If the target is not 3 finite numbers inside the workspace or the motors are off.
    """
    p = np.asarray(target, dtype=np.float64).reshape(-1)
    if p.shape != (3,) or not np.isfinite(p).all():
        raise InvalidInputError(f"leg target must be 3 finite numbers, got {target!r}")
    if not np.allclose(clamp_to_workspace(p, flight), p, rtol=0.0, atol=1e-9):
        raise InvalidInputError(f"leg target {np.round(p, 3).tolist()} is outside the workspace")
    if not flight.motors_on:
        raise InvalidInputError("the motors are off; reset() the flight to fly again")
    if not (np.isfinite(timeout) and timeout > 0 and np.isfinite(dwell) and dwell >= 0):
        raise InvalidInputError(f"need timeout > 0 and dwell >= 0, got {timeout!r} and {dwell!r}")
    crit = flight.config.settle if settle is None else settle
    ref = Reference(p, np.zeros(3), float(yaw))
    fps = flight.config.camera.fps
    start, held, settled_at = flight.time, 0.0, None
    while flight.time - start < timeout - 1e-9:
        flight.step(ref)
        if on_frame is not None:
            on_frame()
        if settled_at is None:
            held = held + 1.0 / fps if is_settled(flight.state, p, yaw, crit) else 0.0
            if held >= crit.hold_time - 1e-9:
                settled_at = flight.time
        if settled_at is not None and flight.time - settled_at >= dwell - 1e-9:
            break
    err = float(np.linalg.norm(flight.state[:3] - p))
    return LegResult(settled_at is not None, flight.time - start, err)
