"""What a landing run produced: its :class:`Outcome`, its queries and its trajectory.

:func:`case_studies.quad_landing.landing.state_machine.run_landing` returns a
:class:`LandingRun`; campaigns, the certified-bound checks and the figures read them.

Examples
--------
>>> Outcome.ABORTED.advice
'no landing (cap, no detection or no settle): the motors stay on; not safe'
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np

from case_studies.quad_landing.arrays import FloatArray
from case_studies.quad_landing.landing.scenario import Scenario

__all__ = ["INTO_PAD_REASON", "Outcome", "QueryRecord", "LandingRun"]


#: Why a run that drove the vehicle into the pad is unsafe (``state_machine.into_pad``).
INTO_PAD_REASON = "flew into the pad: the turn-off target lies below the pad's surface (motors on at contact)"


class Outcome(Enum):
    """How a landing run ended; ``advice`` says what it means."""

    SAFE = "safe"
    UNSAFE = "unsafe"
    ABORTED = "aborted"

    @property
    def advice(self) -> str:
        """One sentence on the outcome."""
        return {
            Outcome.SAFE: "the motors were cut inside {y} + G",
            Outcome.UNSAFE: "the motors were cut outside {y} + G, or the vehicle flew into the pad: "
            "a safety violation",
            Outcome.ABORTED: "no landing (cap, no detection or no settle): the motors stay on; not safe",
        }[self]


@dataclass(frozen=True, eq=False)
class QueryRecord:
    """One Measuring step.

    Attributes
    ----------
    time : float
        Flight time (s).
    position, velocity : ndarray (3,)
        Vehicle position and velocity in W at the measurement.
    detected : bool
        Whether the marker was detected (no contract query otherwise).
    accepted : bool
        Whether the set fits ``G_tau`` (PROVEN).
    center, shape : ndarray or None
        The contract's set in W.
    half_widths : ndarray or None
        Half the set's axis-aligned extents in W (m).
    truth_inside : bool or None
        Whether the true pad lies in the set (evaluation only; the machine never sees it).
    x_c, yhat_c : ndarray or None
        The query, for the coverage check.
    in_domain : bool
        Whether the query lay inside the contract's domain of validity (False: answered
        OUTSIDE_DOMAIN, never accepted).
    """

    time: float
    position: FloatArray
    velocity: FloatArray
    detected: bool
    accepted: bool = False
    center: FloatArray | None = None
    shape: FloatArray | None = None
    half_widths: FloatArray | None = None
    truth_inside: bool | None = None
    x_c: FloatArray | None = None
    yhat_c: FloatArray | None = None
    in_domain: bool = True

    def to_dict(self) -> dict[str, Any]:
        """Plain data (the query vectors are left out)."""

        def lst(a: FloatArray | None) -> Any:
            return None if a is None else np.asarray(a).tolist()

        return {
            "time": self.time,
            "position": lst(self.position),
            "speed": float(np.linalg.norm(self.velocity)),
            "detected": self.detected,
            "accepted": self.accepted,
            "center": lst(self.center),
            "half_widths": lst(self.half_widths),
            "truth_inside": self.truth_inside,
            "in_domain": self.in_domain,
        }


@dataclass(frozen=True, eq=False)
class LandingRun:
    """The result of :func:`run_landing`.

    Attributes
    ----------
    scenario : Scenario
    contract : str
        The contract's name.
    outcome : Outcome
    reason : str
        Why the run ended that way.
    queries : tuple of QueryRecord
        Every Measuring step, in order.
    turnoff : ndarray (3,) or None
        The accepted ``P_turnoff`` (None if nothing was accepted).
    cut_position, rest_position : ndarray (3,) or None
        Position at the motor-off command, and after falling to the floor.
    certificate_verified : bool or None
        The accepted decision re-verified exactly (:func:`ipcverify.decision.check_landing`).
    trajectory : ndarray (T, 3)
        Positions every ``trajectory_every`` frames.
    flight_time, wall_time : float
        Simulated and real seconds.
    """

    scenario: Scenario
    contract: str
    outcome: Outcome
    reason: str
    queries: tuple[QueryRecord, ...]
    turnoff: FloatArray | None
    cut_position: FloatArray | None
    rest_position: FloatArray | None
    certificate_verified: bool | None
    trajectory: FloatArray
    flight_time: float
    wall_time: float = field(default=0.0)

    def __post_init__(self) -> None:
        if (self.outcome is Outcome.ABORTED) != (self.cut_position is None):
            raise ValueError("a run has a cut position exactly when it landed (was not aborted)")

    @property
    def n_queries(self) -> int:
        """Measuring steps taken (detections or not)."""
        return len(self.queries)

    @property
    def pad(self) -> FloatArray:
        """True pad position."""
        return self.scenario.pad.position

    @property
    def hit_pad(self) -> bool:
        """Whether the run drove the vehicle into the pad (an UNSAFE run with its own reason)."""
        return self.outcome is Outcome.UNSAFE and self.reason == INTO_PAD_REASON

    @property
    def offset(self) -> FloatArray | None:
        """``cut_position - y`` (None if aborted)."""
        return None if self.cut_position is None else self.cut_position - self.pad

    def to_dict(self, trajectory: bool = False) -> dict[str, Any]:
        """Plain data for ``summary.json`` (the trajectory only if asked)."""

        def lst(a: FloatArray | None) -> Any:
            return None if a is None else np.asarray(a).tolist()

        out: dict[str, Any] = {
            "scenario": self.scenario.to_dict(),
            "contract": self.contract,
            "outcome": self.outcome.value,
            "reason": self.reason,
            "n_queries": self.n_queries,
            "turnoff": lst(self.turnoff),
            "cut_position": lst(self.cut_position),
            "rest_position": lst(self.rest_position),
            "offset": lst(self.offset),
            "certificate_verified": self.certificate_verified,
            "flight_time": self.flight_time,
            "wall_time": self.wall_time,
            "queries": [q.to_dict() for q in self.queries],
        }
        if trajectory:
            out["trajectory"] = self.trajectory.tolist()
        return out
