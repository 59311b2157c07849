"""What a number of runs can support, and how many runs a target needs, before any data is scored.

When the runs of a log (flights, drives) are its only independent units, no distribution-free
claim about a new run goes below ``1 - delta^(1/G)`` from ``G`` runs (:func:`run_floor`), however
many rows each run holds. :func:`plan_runs` says, for each run-level claim, the smallest rate ``G``
runs can certify and the runs a target needs (with no violation at all; tight sets need more).
``ipcverify plan`` prints it; ``calibrate`` puts it in its refusals and its output.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ipcverify.calibration._bounds import CalibrationMode
from ipcverify.calibration._group_counts import GUARANTEES, GuaranteeKind
from ipcverify.calibration._group_fit import runs_needed, smallest_run_rate
from ipcverify.calibration._share_bound import run_floor
from ipcverify.calibration._threshold import check_eps_delta, check_mode
from ipcverify.errors import InvalidInputError

#: What each claim's rate is the share of, for a table.
RATE_OF: dict[GuaranteeKind, str] = {
    "expected-share": "epsilon: expected share of a new run's rows outside",
    "share-of-runs": "gamma: share of new runs with more than epsilon of their rows outside",
    "trajectory": "epsilon: probability that a new run leaves its sets anywhere",
}


@dataclass(frozen=True, kw_only=True)
class ClaimPlan:
    """One claim's line of a :class:`RunPlan`.

    Attributes
    ----------
    guarantee : {"expected-share", "share-of-runs", "trajectory"}
        The claim.
    rate : str
        Which rate bounds it (``epsilon`` or ``gamma``) and what it is the share of.
    smallest : float or None
        The smallest rate the plan's runs can certify (rounded up to 3 digits; None without a
        number of runs).
    runs_needed : int or None
        The fewest runs for the target (None without one).
    """

    guarantee: GuaranteeKind
    rate: str
    smallest: float | None
    runs_needed: int | None

    def to_dict(self) -> dict[str, Any]:
        """Plain data."""
        return {
            "guarantee": self.guarantee,
            "rate": self.rate,
            "smallest": self.smallest,
            "runs_needed": self.runs_needed,
        }


@dataclass(frozen=True, kw_only=True)
class RunPlan:
    """What ``n_runs`` runs can certify at ``delta``, and the runs a target ``(epsilon, gamma)`` needs.

    Attributes
    ----------
    n_runs : int or None
        The runs at hand (None: plan a target only).
    delta : float
        One minus the confidence.
    epsilon, gamma : float or None
        The target share of a run's rows outside, and of runs above it (share of runs).
    mode : {"pac", "marginal"}
        PAC (the floor applies) or marginal claims.
    floor : float or None
        ``1 - delta^(1/n_runs)``: no PAC claim about a new run goes below it.
    claims : tuple of ClaimPlan
        One line per run-level claim.

    Examples
    --------
    >>> plan = plan_runs(20, 0.01, epsilon=0.1)
    >>> round(plan.floor, 4), [(c.guarantee, c.smallest, c.runs_needed) for c in plan.claims][0]
    (0.2057, ('expected-share', 0.212, 46))
    """

    n_runs: int | None
    delta: float
    epsilon: float | None
    gamma: float | None
    mode: CalibrationMode
    floor: float | None
    claims: tuple[ClaimPlan, ...]

    def claim(self, guarantee: GuaranteeKind) -> ClaimPlan:
        """The line of one claim."""
        for c in self.claims:
            if c.guarantee == guarantee:
                return c
        raise InvalidInputError(f"no plan for guarantee {guarantee!r}")

    def sentence(self) -> str:
        """The plan in one or two sentences."""
        parts = []
        if self.n_runs is not None:
            share = self.claim("expected-share").smallest
            parts.append(
                f"From {self.n_runs} independent runs at delta={self.delta:g}, no {self.mode} claim about a "
                "new "
                f"run goes below {self.floor:.3g}; the smallest expected share of a new run's rows outside "
                f"that can be certified is {share:g}"
                if self.mode == "pac"
                else f"From {self.n_runs} exchangeable runs, the smallest marginal expected share is "
                f"{share:g}"
            )
        if self.epsilon is not None:
            need = self.claim("expected-share").runs_needed
            parts.append(f"an expected share of {self.epsilon:g} needs at least {need} runs")
        return "; ".join(parts) + "."

    def to_dict(self) -> dict[str, Any]:
        """Plain data, with the sentence."""
        return {
            "n_runs": self.n_runs,
            "delta": self.delta,
            "epsilon": self.epsilon,
            "gamma": self.gamma,
            "mode": self.mode,
            "floor": self.floor,
            "claims": [c.to_dict() for c in self.claims],
            "statement": self.sentence(),
        }


def plan_runs(
    n_runs: int | None,
    delta: float,
    *,
    epsilon: float | None = None,
    gamma: float | None = None,
    mode: CalibrationMode = "pac",
) -> RunPlan:
    """What ``n_runs`` runs can certify, and how many runs the target ``(epsilon, gamma)`` needs.

    Parameters
    ----------
    n_runs : int or None
        The independent runs at hand (None: only the target's needs).
    delta : float
        One minus the confidence.
    epsilon : float, optional
        The target share of a run's rows outside (expected share, share of runs) or the
        probability of any violation (trajectory).
    gamma : float, optional
        The target share of runs with more than ``epsilon`` outside (share of runs; default
        ``epsilon``).
    mode : {"pac", "marginal"}
        The claims' mode.

    Raises
    ------
    InvalidInputError
        If neither ``n_runs`` nor ``epsilon`` is given, or a rate lies outside ``(0, 1)``.

    Examples
    --------
    >>> plan_runs(None, 0.01, epsilon=0.227).claim("expected-share").runs_needed
    19
    """
    check_mode(mode)
    if n_runs is None and epsilon is None:
        raise InvalidInputError("a plan needs the number of runs, a target epsilon, or both")
    if n_runs is not None and (isinstance(n_runs, bool) or int(n_runs) != n_runs or n_runs < 1):
        raise InvalidInputError(f"the number of runs must be a positive integer; got {n_runs!r}")
    check_eps_delta(0.5 if epsilon is None else epsilon, delta)
    if gamma is not None:
        check_eps_delta(gamma, delta)
    claims = []
    for g in GUARANTEES:
        target_gamma = (gamma if gamma is not None else epsilon) if g == "share-of-runs" else None
        need = None if epsilon is None else runs_needed(g, mode, epsilon, delta, target_gamma)
        smallest = None if n_runs is None else smallest_run_rate(g, mode, int(n_runs), delta)
        claims.append(ClaimPlan(guarantee=g, rate=RATE_OF[g], smallest=smallest, runs_needed=need))
    return RunPlan(
        n_runs=None if n_runs is None else int(n_runs),
        delta=float(delta),
        epsilon=epsilon,
        gamma=gamma,
        mode=mode,
        floor=None if n_runs is None or mode != "pac" else run_floor(int(n_runs), delta),
        claims=tuple(claims),
    )
