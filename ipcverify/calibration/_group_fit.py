"""The threshold of a grouped calibration: the group statistics and their order statistic (or a mean bound).

Split from :class:`~ipcverify.calibration.GroupedCalibration` (the record and its guarantee):
:func:`group_threshold` checks the scores and groups, refuses too few groups
(:func:`too_few_groups` says what to do, with :func:`runs_needed` and :func:`smallest_run_rate`)
and computes the threshold for the guarantee asked for. Proofs: ``proofs/group_calibration.md``
and ``proofs/run_claims.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify._wording._spelling import Remedy, option
from ipcverify.calibration._bounds import CalibrationMode, count_text, min_calibration_size
from ipcverify.calibration._group_counts import GuaranteeKind, check_guarantee, group_layout
from ipcverify.calibration._risk_control import risk_control_threshold
from ipcverify.calibration._run_fit import expected_share_threshold, run_quantiles
from ipcverify.calibration._share_bound import run_floor, runs_for_share, smallest_share_epsilon
from ipcverify.calibration._threshold import (
    MIN_SCALE,
    SCALE_MARGIN,
    check_eps_delta,
    check_mode,
    check_seed,
    threshold_scores,
)
from ipcverify.data._split import group_codes
from ipcverify.errors import InvalidInputError, SampleSizeError

#: How each guarantee's threshold is chosen (``mode``-dependent for the expected share).
METHOD_OF: dict[tuple[str, str], str] = {
    ("trajectory", "pac"): "group-max",
    ("trajectory", "marginal"): "group-max",
    ("expected-share", "pac"): "share-bound",
    ("expected-share", "marginal"): "risk-control",
    ("share-of-runs", "pac"): "run-quantile",
    ("share-of-runs", "marginal"): "run-quantile",
}


def round_up(value: float, digits: int = 3) -> float:
    """``value`` rounded up to ``digits`` significant digits (a rate a message may name and get back).

    Examples
    --------
    >>> round_up(0.211294), round_up(0.0994), round_up(1.0)
    (0.212, 0.0994, 1.0)
    """
    if value <= 0 or value >= 1:
        return float(min(max(value, 0.0), 1.0))
    scale = 10 ** (digits - 1 - math.floor(math.log10(value)))
    return min(1.0, math.ceil(value * scale - 1e-9) / scale)


def runs_needed(guarantee: GuaranteeKind, mode: CalibrationMode, epsilon: float, delta: float,
                gamma: float | None = None) -> int:  # fmt: skip
    """The fewest runs for which ``guarantee`` can be calibrated at all (with no violation in any run).

    Parameters
    ----------
    guarantee : {"expected-share", "share-of-runs", "trajectory"}
        The claim.
    mode : {"pac", "marginal"}
        Its mode.
    epsilon, delta : float
        The target and the confidence parameter.
    gamma : float, optional
        The share of runs (``"share-of-runs"``): it, not ``epsilon``, sets the number of runs.

    Examples
    --------
    >>> runs_needed("expected-share", "pac", 0.1, 0.01), runs_needed("trajectory", "pac", 0.1, 0.01)
    (46, 44)
    """
    if guarantee == "share-of-runs":
        if gamma is None:
            raise InvalidInputError(
                "a share-of-runs claim needs gamma, the share of runs that may exceed epsilon"
            )
        return min_calibration_size(gamma, delta, mode)
    if guarantee == "expected-share" and mode == "pac":
        return runs_for_share(epsilon, delta)
    return min_calibration_size(epsilon, delta, mode)


def smallest_run_rate(guarantee: GuaranteeKind, mode: CalibrationMode, n_runs: int, delta: float) -> float:
    """The smallest rate ``n_runs`` runs can certify: epsilon, or gamma for the share of runs.

    Rounded up to 3 significant digits and checked against :func:`runs_needed`, so that the value
    a message names is accepted when it is given back.

    Examples
    --------
    >>> smallest_run_rate("expected-share", "pac", 20, 0.01), smallest_run_rate("trajectory", "pac", 20, 0.01)
    (0.212, 0.206)
    """
    if guarantee == "expected-share" and mode == "pac":
        exact = smallest_share_epsilon(n_runs, delta)
    elif mode == "marginal":
        exact = 1.0 / (n_runs + 1)
    else:
        exact = run_floor(n_runs, delta)
    value = round_up(exact)

    def needed(rate: float) -> int:
        if guarantee == "share-of-runs":
            return runs_needed(guarantee, mode, 0.5, delta, gamma=rate)
        return runs_needed(guarantee, mode, rate, delta)

    while value < 1.0 and needed(value) > n_runs:
        value = round_up(value * (1 + 1e-3))
    return value


def too_few_groups(
    G: int,
    column: str,
    epsilon: float,
    delta: float,
    mode: CalibrationMode,
    guarantee: GuaranteeKind,
    gamma: float | None = None,
) -> str:
    """Why ``G`` groups are too few, and what to do (the message of a :class:`SampleSizeError`)."""
    need = runs_needed(guarantee, mode, epsilon, delta, gamma)
    rate = "gamma" if guarantee == "share-of-runs" else "epsilon"
    target = f"gamma={gamma:g}, " if guarantee == "share-of-runs" else ""
    smallest = smallest_run_rate(guarantee, mode, G, delta)
    text = (
        f"{G} groups of column {column!r} are too few for a {mode} {guarantee} claim at "
        f"{target}epsilon={epsilon:g}, delta={delta:g}: at least {count_text(need)} groups are needed. "
        "The groups "
        "(flights, runs), not the rows, are the exchangeable units, so more rows per group do not help "
        f"(from {G} groups no claim about a new group goes below {run_floor(G, delta):.3g} at this delta); "
        f"collect more independent groups, or raise {option(rate)} (with {G} groups the smallest is "
        f"{smallest:g}"
    )
    if mode == "pac":
        marginal = runs_needed(guarantee, "marginal", epsilon, delta, gamma)
        return (
            text + f" at this delta) or {option('delta')}, or use {option('mode', 'marginal')} "
            f"(needs {count_text(marginal)} groups)"
        )
    return text + ")"


@dataclass(frozen=True, kw_only=True, eq=False)
class GroupThreshold:
    """The threshold of the group statistics, and the scores and group sizes it came from.

    Attributes
    ----------
    method : str
        How it was chosen (:data:`METHOD_OF`).
    k_groups : int or None
        Order statistic among the group statistics (None for the expected share).
    order_statistic, scale : float
        The selected score ``t`` and the stored scale (``t * (1 + SCALE_MARGIN)``, at least ``MIN_SCALE``).
    risk : float or None
        Expected share only: ``mean_g V_g(t)`` over the calibration groups.
    bound : float or None
        Expected share, PAC only: the upper confidence bound of those shares (at most ``epsilon``).
    used : ndarray
        The scores that entered the threshold (every row's).
    sizes : ndarray of int
        Rows per group.
    """

    method: str
    k_groups: int | None
    order_statistic: float
    scale: float
    risk: float | None
    bound: float | None
    used: NDArray[np.float64]
    sizes: NDArray[np.intp]


def group_threshold(
    scores: ArrayLike,
    groups: ArrayLike,
    epsilon: float,
    delta: float,
    mode: CalibrationMode,
    *,
    guarantee: GuaranteeKind,
    column: str,
    seed: int,
    gamma: float | None = None,
) -> GroupThreshold:
    """The threshold of the group statistics (:meth:`GroupedCalibration.fit` documents the arguments)."""
    check_mode(mode)
    check_eps_delta(epsilon, delta)
    guarantee = check_guarantee(guarantee)
    check_seed(seed)
    if guarantee == "share-of-runs":
        if gamma is None:
            raise InvalidInputError(
                "a share-of-runs claim needs gamma, the share of new runs that may have more than epsilon "
                "of their rows outside (e.g. gamma=0.25)"
            )
        check_eps_delta(gamma, delta)
    elif gamma is not None:
        raise InvalidInputError(f"gamma goes with the share-of-runs claim only, not with {guarantee!r}")
    s = np.asarray(scores, dtype=np.float64).ravel()
    if s.size == 0 or not np.isfinite(s).all() or (s < 0).any():
        raise InvalidInputError("calibration scores must be a non-empty array of finite values >= 0")
    codes, labels = group_codes(groups, f"group column {column!r}")
    if len(codes) != len(s):
        raise InvalidInputError(
            f"{len(s)} calibration scores but {len(codes)} labels in group column {column!r}; "
            "give one group label per calibration row"
        )
    G = len(labels)
    if G < runs_needed(guarantee, mode, epsilon, delta, gamma):
        rate = "gamma" if guarantee == "share-of-runs" else "epsilon"
        smallest = smallest_run_rate(guarantee, mode, G, delta)
        raise SampleSizeError(
            too_few_groups(G, column, epsilon, delta, mode, guarantee, gamma),
            remedies=(Remedy(rate, smallest),) if smallest < 1.0 else (),
        )
    order, starts, sizes = group_layout(codes, G)
    method = METHOD_OF[(guarantee, mode)]
    k_groups: int | None = None
    risk: float | None = None
    bound: float | None = None
    if method == "group-max":
        t = threshold_scores(np.maximum.reduceat(s[order], starts), epsilon, delta, mode)
        k_groups, stat, scale = t.k, t.order_statistic, t.scale
    elif method == "run-quantile":
        t = threshold_scores(run_quantiles(s, codes, G, epsilon), float(gamma), delta, mode)  # type: ignore[arg-type]
        k_groups, stat, scale = t.k, t.order_statistic, t.scale
    elif method == "share-bound":
        fit = expected_share_threshold(s, codes, G, epsilon, delta)
        if fit.threshold is None:  # unreachable: G runs suffice for the largest score (checked above)
            raise SampleSizeError(too_few_groups(G, column, epsilon, delta, mode, guarantee, gamma))
        stat, risk, bound = fit.threshold, fit.mean_share, fit.upper_bound
        scale = max(stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
    else:
        stat, risk = risk_control_threshold(s, codes, epsilon)
        scale = max(stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
    return GroupThreshold(
        method=method,
        k_groups=k_groups,
        order_statistic=stat,
        scale=scale,
        risk=risk,
        bound=bound,
        used=s,
        sizes=sizes,
    )
