"""The threshold of a grouped calibration: the group statistics and their order statistic (or risk control).

Split from :class:`~ipcverify.calibration.GroupedCalibration` (the record and its guarantee):
:func:`group_threshold` checks the scores and groups, refuses too few groups
(:func:`too_few_groups` says what to do) and computes the threshold for the guarantee asked
for. Proofs: ``proofs/group_calibration.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.calibration._bounds import CalibrationMode, count_text, min_calibration_size, smallest_epsilon
from ipcverify.calibration._group_counts import GuaranteeKind, check_guarantee, group_layout, one_per_group
from ipcverify.calibration._risk_control import risk_control_threshold
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


def too_few_groups(
    G: int, column: str, epsilon: float, delta: float, mode: CalibrationMode, what: str
) -> str:
    """Why ``G`` groups are too few, and what to do (the message of a :class:`SampleSizeError`)."""
    need = min_calibration_size(epsilon, delta, mode)
    text = (
        f"{G} groups of column {column!r} are too few for a {mode} {what} calibration at "
        f"epsilon={epsilon:g}, delta={delta:g}: at least {count_text(need)} groups are needed. The groups "
        "(flights, runs), not the rows, are the exchangeable units, so more rows per group do not help; "
        f"collect more independent groups, or raise --epsilon (with {G} groups the smallest is "
        f"{smallest_epsilon(G, delta, mode):g}"
    )
    if mode == "pac":
        marginal = min_calibration_size(epsilon, delta, "marginal")
        return (
            text + f" at this delta) or --delta, or use --mode marginal (needs {count_text(marginal)} groups)"
        )
    return text + ")"


@dataclass(frozen=True, kw_only=True, eq=False)
class GroupThreshold:
    """The threshold of the group statistics, and the scores and group sizes it came from.

    Attributes
    ----------
    k_groups : int or None
        Order statistic among the group statistics (None for risk control).
    order_statistic, scale : float
        The selected score ``t`` and the stored scale (``t * (1 + SCALE_MARGIN)``, at least ``MIN_SCALE``).
    risk : float or None
        Risk control only: ``mean_g V_g(t)``.
    used : ndarray
        The scores that entered the threshold (all rows, or one per group).
    sizes : ndarray of int
        Rows per group.
    """

    k_groups: int | None
    order_statistic: float
    scale: float
    risk: float | None
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
) -> GroupThreshold:
    """The threshold of the group statistics (:meth:`GroupedCalibration.fit` documents the arguments)."""
    check_mode(mode)
    check_eps_delta(epsilon, delta)
    check_guarantee(guarantee)
    check_seed(seed)
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
    if G < min_calibration_size(epsilon, delta, mode):
        raise SampleSizeError(too_few_groups(G, column, epsilon, delta, mode, f"{guarantee}-level"))
    order, starts, sizes = group_layout(codes, G)
    k_groups: int | None = None
    risk: float | None = None
    used = s
    if guarantee == "trajectory":
        t = threshold_scores(np.maximum.reduceat(s[order], starts), epsilon, delta, mode)
        k_groups, stat, scale = t.k, t.order_statistic, t.scale
    elif mode == "pac":
        used = s[one_per_group(codes, G, int(seed))]
        t = threshold_scores(used, epsilon, delta, mode)
        k_groups, stat, scale = t.k, t.order_statistic, t.scale
    else:
        stat, risk = risk_control_threshold(s, codes, epsilon)
        scale = max(stat * (1.0 + SCALE_MARGIN), MIN_SCALE)
    return GroupThreshold(
        k_groups=k_groups, order_statistic=stat, scale=scale, risk=risk, used=used, sizes=sizes
    )
