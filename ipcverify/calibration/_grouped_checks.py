"""Consistency checks of a stored :class:`~ipcverify.calibration.GroupedCalibration` record.

A model file is data: a record read back must be one that :meth:`GroupedCalibration.fit` could
have made (its method fits its claim, its groups, sizes and counts agree, its statistics are in
range), or it is refused with a message that says to recalibrate.
"""

from __future__ import annotations

import math
from typing import Protocol

from ipcverify.calibration._bounds import CalibrationMode, min_calibration_size
from ipcverify.calibration._group_counts import GuaranteeKind
from ipcverify.calibration._group_fit import METHOD_OF, runs_needed
from ipcverify.calibration._threshold import ScoreThreshold, check_eps_delta
from ipcverify.errors import InvalidInputError


class GroupedCalibration(Protocol):
    """The fields of a grouped calibration record that the checks read."""

    @property
    def guarantee_kind(self) -> GuaranteeKind: ...  # noqa: D102
    @property
    def mode(self) -> CalibrationMode: ...  # noqa: D102
    @property
    def method(self) -> str: ...  # noqa: D102
    @property
    def epsilon(self) -> float: ...  # noqa: D102
    @property
    def delta(self) -> float: ...  # noqa: D102
    @property
    def gamma(self) -> float | None: ...  # noqa: D102
    @property
    def n_groups(self) -> int: ...  # noqa: D102
    @property
    def k_groups(self) -> int | None: ...  # noqa: D102
    @property
    def n_rows(self) -> int: ...  # noqa: D102
    @property
    def n_used(self) -> int: ...  # noqa: D102
    @property
    def n_inside(self) -> int: ...  # noqa: D102
    @property
    def size_min(self) -> int: ...  # noqa: D102
    @property
    def size_median(self) -> float: ...  # noqa: D102
    @property
    def size_max(self) -> int: ...  # noqa: D102
    @property
    def risk(self) -> float | None: ...  # noqa: D102
    @property
    def bound(self) -> float | None: ...  # noqa: D102
    @property
    def scale(self) -> float: ...  # noqa: D102
    @property
    def order_statistic(self) -> float: ...  # noqa: D102
    @property
    def group_threshold(self) -> ScoreThreshold | None: ...  # noqa: D102


#: Relative slack when a stored record is re-checked (its mean share and bound are rounded floats).
RISK_RTOL = 1e-9


def check_record(cal: GroupedCalibration) -> None:
    """Refuse an inconsistent grouped calibration record (see the module docstring)."""
    method = cal.method
    expected = {METHOD_OF[(cal.guarantee_kind, cal.mode)]}
    if (cal.guarantee_kind, cal.mode) == ("expected-share", "pac"):
        expected.add("one-per-group")  # records written before the share bound
    if method not in expected:
        raise InvalidInputError(
            f"grouped calibration record: method {method!r} does not fit a {cal.mode} "
            f"{cal.guarantee_kind} claim; the record is inconsistent -- recalibrate"
        )
    G = cal.n_groups
    need = (
        min_calibration_size(cal.epsilon, cal.delta, cal.mode)
        if method == "one-per-group"
        else runs_needed(cal.guarantee_kind, cal.mode, cal.epsilon, cal.delta, cal.gamma)
    )
    if not (isinstance(G, int) and G >= need):
        raise InvalidInputError(
            f"grouped calibration record: n_groups={G!r} is below the minimum for {cal.mode} at "
            f"epsilon={cal.epsilon:g}, delta={cal.delta:g}; the record is inconsistent -- recalibrate"
        )
    if not (1 <= cal.size_min <= cal.size_median <= cal.size_max) or not (
        G * cal.size_min <= cal.n_rows <= G * cal.size_max
    ):
        raise InvalidInputError("grouped calibration record: group sizes disagree with n_rows and n_groups")
    expect_used = G if method == "one-per-group" else cal.n_rows
    if cal.n_used != expect_used or not (1 <= cal.n_inside <= cal.n_used):
        raise InvalidInputError(
            f"grouped calibration record: n_used={cal.n_used}, n_inside={cal.n_inside} are "
            f"inconsistent with method {method!r} ({expect_used} rows used)"
        )
    _check_statistics(cal)
    if not (math.isfinite(cal.scale) and cal.scale > 0 and cal.scale >= cal.order_statistic >= 0):
        raise InvalidInputError(
            f"scale must be finite, > 0 and >= the order statistic >= 0; got scale={cal.scale!r}, "
            f"order statistic={cal.order_statistic!r}"
        )


def _check_statistics(cal: GroupedCalibration) -> None:
    """The method's own numbers: a share and its bound, or an order statistic (and gamma)."""
    G, r, method = cal.n_groups, cal.risk, cal.method
    if (method == "run-quantile") != (cal.gamma is not None):
        raise InvalidInputError("grouped calibration record: gamma goes with a share-of-runs claim only")
    if cal.gamma is not None:
        check_eps_delta(cal.gamma, cal.delta)
    if method in ("risk-control", "share-bound"):
        if cal.k_groups is not None or r is None or not 0.0 <= r <= 1.0:
            raise InvalidInputError(
                f"grouped calibration record: a {method} record needs the groups' mean share, no "
                "order statistic; the record is inconsistent -- recalibrate"
            )
        if method == "risk-control" and (G * r + 1) / (G + 1) > cal.epsilon * (1 + RISK_RTOL):
            raise InvalidInputError(
                f"grouped calibration record: risk {r!r} breaks (G * risk + 1) / (G + 1) <= epsilon "
                f"for G={G}, epsilon={cal.epsilon:g}; the record is inconsistent -- recalibrate"
            )
        b = cal.bound
        if (method == "share-bound") != (b is not None) or (
            b is not None and not (r <= b * (1 + RISK_RTOL) and b <= cal.epsilon * (1 + RISK_RTOL))
        ):
            raise InvalidInputError(
                f"grouped calibration record: bound {b!r} must lie between the mean share {r!r} and "
                f"epsilon={cal.epsilon:g}; the record is inconsistent -- recalibrate"
            )
    elif r is not None or cal.bound is not None or cal.group_threshold is None:
        raise InvalidInputError(
            "grouped calibration record: an order-statistic method needs k_groups, no share"
        )
