"""From pairs of trajectories (one pair per run) to rows ``x, y, yhat, run, t``.

For every run the sample starts ``t0`` lie on a grid of ``stride`` seconds from the estimate's
first stamp, while ``t0 + horizon`` is before its last stamp. Both trajectories are
interpolated at ``t0`` and ``t1 = t0 + horizon`` (:meth:`Trajectory.at`); a sample is kept only
where, for both trajectories and both times, the two stamps around the time are at most
``max_gap`` apart. Every dropped sample is counted under one reason, checked in this order:

``estimate_gap``   a bracket of the estimate is wider than ``max_gap``
``truth_outside``  ``t0`` or ``t1`` is outside the truth's stamps
``truth_gap``      a bracket of the truth is wider than ``max_gap``
``no_state``       the state topic has no value at or before ``t0``

The truth's stamps plus ``t_offset`` are taken to be on the estimate's clock.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.errors import DataError, Hint
from ipcverify.io.ingest._align import Alignment, fit_alignment
from ipcverify.io.ingest._bagio import StateSeries
from ipcverify.io.ingest._quantity import (
    QUANTITIES,
    UP_AXES,
    Quantity,
    UpAxis,
    quantity_pair,
    state_columns,
    state_features,
)
from ipcverify.io.ingest._trajectory import PosesAt, Trajectory

REASONS = ("estimate_gap", "truth_outside", "truth_gap", "no_state")
#: Where :func:`build_samples` leaves its account of the rows in ``DataFrame.attrs``.
MANIFEST_KEY = "ipcverify.io.ingest"
#: A run may have up to this many sample starts per estimated pose (or :data:`MIN_STARTS_LIMIT`):
#: far more means stamps in other units than seconds or a mistyped --stride, and would fill memory.
MAX_STARTS_PER_POSE = 1000
MIN_STARTS_LIMIT = 10**6


@dataclass(frozen=True, kw_only=True)
class IngestOptions:
    """How samples are built from trajectories.

    Parameters
    ----------
    quantity : {"displacement", "position", "pose"}
        The perceived quantity (see :mod:`ipcverify.io.ingest._quantity`).
    horizon : float
        Seconds between a sample's start and end (default 0.5).
    stride : float
        Seconds between sample starts (default 0.25).
    max_gap : float
        The widest gap between the two stamps around an interpolated time (default 0.2 s).
    t_offset : float
        Seconds added to the truth's stamps to put them on the estimate's clock.
    align : {"none", "se3", "sim3"}
        Align the estimate's world frame to the truth's (``position`` and ``pose`` only).
    align_runs : tuple of str
        The runs the alignment is fitted on (required with ``align``); keep them out of
        calibration and test.
    up : str, optional
        The world's up axis in the estimate's world frame, for the tilt columns ``x_2..x_4``:
        ``"+z"`` (EuRoC, TUM, ROS's ENU), ``"-y"`` (KITTI's camera frame) or another signed
        axis (:data:`~ipcverify.io.ingest._quantity.UP_AXES`). None: the estimate format's
        convention (``"-y"`` for KITTI poses, ``"+z"`` otherwise), filled in by the ingest
        functions so that the manifest records the axis used.

    Examples
    --------
    >>> IngestOptions(horizon=1.0).stride
    0.25
    >>> IngestOptions(align="se3")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: align='se3' needs the quantity position or pose; ...
    """

    quantity: Quantity = "displacement"
    horizon: float = 0.5
    stride: float = 0.25
    max_gap: float = 0.2
    t_offset: float = 0.0
    align: Literal["none", "se3", "sim3"] = "none"
    align_runs: tuple[str, ...] = ()
    up: UpAxis | None = None

    def __post_init__(self) -> None:
        if self.up is not None and self.up not in UP_AXES:
            raise DataError(f"unknown up axis {self.up!r}; use one of {', '.join(UP_AXES)}")
        if self.quantity not in QUANTITIES:
            raise DataError(f"unknown quantity {self.quantity!r}; use one of {', '.join(QUANTITIES)}")
        for name in ("horizon", "stride", "max_gap"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise DataError(f"--{name.replace('_', '-')} must be a positive number of seconds; got {v!r}")
        if not math.isfinite(self.t_offset):
            raise DataError(f"{option('t_offset')} must be a finite number of seconds; got {self.t_offset!r}")
        if self.align not in ("none", "se3", "sim3"):
            raise DataError(f"unknown alignment {self.align!r}; use none, se3 or sim3")
        object.__setattr__(self, "align_runs", tuple(str(r) for r in self.align_runs))
        if self.align != "none" and self.quantity == "displacement":
            raise DataError(
                f"{option('align', self.align)} needs the quantity position or pose; the displacement is "
                "measured in "
                "each trajectory's own body frame and needs no alignment"
            )
        if self.align != "none" and not self.align_runs:
            raise DataError(
                f"{option('align', self.align)}: name the runs to fit the alignment on with "
                f"{option('align_runs')}; "
                "rows of those runs depend on each other through the fit, "
                "so keep them out of calibration and test"
            )
        if self.align == "none" and self.align_runs:
            raise DataError(
                f"{option('align_runs')} is given but {option('align', 'none')}; choose "
                f"{option('align', 'se3')} "
                f"or {option('align', 'sim3')}"
            )


def with_up(options: IngestOptions, default: UpAxis) -> IngestOptions:
    """``options`` with its up axis, ``default`` where it names none (the input format's convention).

    Examples
    --------
    >>> with_up(IngestOptions(), "-y").up, with_up(IngestOptions(up="+x"), "-y").up
    ('-y', '+x')
    """
    return options if options.up is not None else dataclasses.replace(options, up=default)


def warn_camera_frame(runs: Sequence[RunData]) -> None:
    """A :class:`~ipcverify.errors.Hint` when estimates start at the identity pose and ``+z`` is taken as up.

    A visual odometry or SLAM system without gravity alignment puts its world frame at its first
    camera frame, and so starts at the identity; ``+z`` is then the first view's direction, not
    up, and the tilt columns ``x_2..x_4`` hold the heading. ``--up`` names the right axis.

    Parameters
    ----------
    runs : sequence of RunData
        The runs about to be sampled with ``up = "+z"`` chosen by default.
    """
    at_identity = [
        r.name
        for r in runs
        if len(r.estimate.t)
        and np.allclose(np.abs(r.estimate.q[0]), [0.0, 0.0, 0.0, 1.0], atol=1e-6)
        and np.allclose(r.estimate.p[0], 0.0, atol=1e-6)
    ]
    if not at_identity:
        return
    which = at_identity[0] + (f" and {len(at_identity) - 1} more" if len(at_identity) > 1 else "")
    warnings.warn(
        Hint(
            f"the estimate of run {which} starts at the identity pose, as a visual odometry or SLAM "
            "system's does when its world frame is its first camera frame; the tilt columns x_2..x_4 "
            f"then hold that frame's +z axis (a camera's viewing direction), not up: pass {option('up')} "
            "with "
            f"the axis that points up in it ({option('up', '-y')} for a level camera with y down), or "
            f"{option('up', '+z')} if it is gravity-aligned"
        ),
        stacklevel=3,
    )


@dataclass(frozen=True, eq=False)
class RunData:
    """One run: its name, truth and estimate trajectories, and optionally a state series.

    Attributes
    ----------
    name : str
        The run's name.
    truth, estimate : Trajectory
        The truth and estimate trajectories.
    state : StateSeries or None
        Numbers read from a state topic (None: none).
    """

    name: str
    truth: Trajectory
    estimate: Trajectory
    state: StateSeries | None = None


@dataclass(frozen=True, eq=False)
class _Prepared:
    run: RunData
    t0: NDArray[np.float64]  # seconds since the estimate's first stamp
    truth: tuple[PosesAt, PosesAt]
    estimate: tuple[PosesAt, PosesAt]


def _span(tr: Trajectory, offset: float = 0.0) -> str:
    a, b = tr.span
    return f"{a + offset:.6f}..{b + offset:.6f} s"


def _overlap_error(run: RunData, options: IngestOptions, hint: str) -> DataError:
    a, b = run.truth.span
    c, d = run.estimate.span
    a, b = a + options.t_offset, b + options.t_offset
    big, small = sorted((max(abs(a), abs(b)), max(abs(c), abs(d))), reverse=True)
    if big > 1e12 and big > 1e6 * small:  # seconds since 1970 are about 1.7e9; nanoseconds 1.7e18
        why = "one set of stamps looks like nanoseconds and the other like seconds: convert them to seconds"
    else:
        why = (
            f"if their clocks differ, add {option('t_offset')} (about {c - a + options.t_offset:.6g} s "
            "lines up their "
            "starts)" + hint
        )
    return DataError(
        f"run {run.name}: the truth ({a:.6f}..{b:.6f} s, with {option('t_offset', options.t_offset)}) and "
        "the "
        f"estimate ({c:.6f}..{d:.6f} s) do not overlap in time; {why}"
    )


def _too_many_starts(run: RunData, span: float, starts: int, options: IngestOptions) -> DataError:
    looks_ns = span > 1e7  # 116 days of seconds; a nanosecond clock reaches it in 0.01 s
    why = (
        f"the stamps look like nanoseconds: this {option('format')} reads seconds (a EuRoC file is "
        f"{option('format', 'euroc')})"
        if looks_ns
        else f"use a larger {option('stride')}"
    )
    return DataError(
        f"run {run.name}: the estimate spans {span:.6g} s, which at {option('stride', options.stride)} s "
        "makes "
        f"{starts:.3g} sample starts for its {len(run.estimate)} poses; {why}"
    )


def _prepare(run: RunData, options: IngestOptions, hint: str) -> _Prepared:
    e0 = float(run.estimate.t[0])
    est = run.estimate.shifted(-e0)
    truth = run.truth.shifted(options.t_offset - e0)
    if truth.span[1] <= 0.0 or truth.span[0] >= est.span[1]:
        raise _overlap_error(run, options, hint)
    starts = math.floor((est.span[1] - options.horizon) / options.stride) + 2
    if starts > max(MAX_STARTS_PER_POSE * len(run.estimate), MIN_STARTS_LIMIT):
        raise _too_many_starts(run, est.span[1], starts, options)
    k = np.arange(int(starts))
    t0 = np.asarray(options.stride * k, dtype=np.float64)
    t0 = t0[t0 + options.horizon < est.span[1]]
    if t0.shape[0] == 0:
        raise DataError(
            f"run {run.name}: the estimate spans {est.span[1]:.6g} s, "
            f"less than the horizon {options.horizon:g} s; "
            f"use a shorter {option('horizon')}"
        )
    t1 = t0 + options.horizon
    gap = options.max_gap
    return _Prepared(run, t0, (truth.at(t0, gap), truth.at(t1, gap)), (est.at(t0, gap), est.at(t1, gap)))


def _aligned(at: PosesAt, a: Alignment) -> PosesAt:
    R = a.as_rotation
    p = a.scale * R.apply(at.p).reshape(-1, 3) + a.translation
    return dataclasses.replace(at, p=p, rotation=R * at.rotation)


def _fit(prepared: Sequence[_Prepared], options: IngestOptions) -> Alignment:
    names = [p.run.name for p in prepared]
    unknown = [r for r in options.align_runs if r not in names]
    if unknown:
        raise DataError(
            f"{option('align_runs')}: no run named {', '.join(unknown)}; the runs are {', '.join(names)}"
        )
    est, tru = [], []
    for p in prepared:
        if p.run.name in options.align_runs:
            ok = p.truth[0].ok & p.estimate[0].ok
            est.append(p.estimate[0].p[ok])
            tru.append(p.truth[0].p[ok])
    kind: Literal["se3", "sim3"] = "sim3" if options.align == "sim3" else "se3"
    return fit_alignment(np.vstack(est), np.vstack(tru), kind, options.align_runs)


def _gap(p: _Prepared, reason: str, options: IngestOptions) -> tuple[str, int, float]:
    """For ``truth_gap`` / ``estimate_gap``: whose stamps, how many lie within the estimate's span,
    and the largest gap between consecutive stamps there."""
    run = p.run
    tr = run.truth.shifted(options.t_offset) if reason == "truth_gap" else run.estimate
    c, d = run.estimate.span
    inside = tr.t[(tr.t >= c) & (tr.t <= d)]
    around = tr.t[max(0, np.searchsorted(tr.t, c) - 1) : np.searchsorted(tr.t, d) + 1]
    largest = float(np.diff(around).max()) if around.shape[0] > 1 else math.inf
    return ("truth" if reason == "truth_gap" else "estimate"), int(inside.shape[0]), largest


def _warn_gaps(p: _Prepared, counts: dict[str, int], starts: int, options: IngestOptions) -> None:
    """A :class:`~ipcverify.errors.Hint` when gaps wider than ``max_gap`` drop most of a run's samples."""
    reason = max(("estimate_gap", "truth_gap"), key=lambda r: counts[r])
    if 2 * counts[reason] <= starts:
        return
    who, _, largest = _gap(p, reason, options)
    warnings.warn(
        Hint(
            f"run {p.run.name}: {counts[reason]} of {starts} samples dropped as {reason}: the {who}'s "
            f"stamps are up to {largest:.6g} s apart, above {option('max_gap', options.max_gap)} s; to keep "
            f"them, raise {option('max_gap')} above {largest:.6g} (poses are then interpolated across such "
            f"gaps), or check the {who} topic's rate and stamps"
        ),
        stacklevel=4,
    )


def _warn_frames(frame: pd.DataFrame, options: IngestOptions) -> None:
    """A :class:`~ipcverify.errors.Hint` that positions are compared in the frames as given.

    Without ``--align`` the position (or pose) quantity compares the estimate's and the truth's
    positions in their own world frames; a VIO or SLAM estimate starts at its own origin, and
    its errors would then be the frames' offset. The hint quotes the measured median error of
    every run's position so that the user, who knows the frames, can judge.
    """
    if options.quantity == "displacement" or options.align != "none" or frame.empty:
        return
    err = np.linalg.norm(
        frame[[f"y_{i}" for i in range(3)]].to_numpy() - frame[[f"yhat_{i}" for i in range(3)]].to_numpy(),
        axis=1,
    )
    medians = pd.Series(err).groupby(frame["run"].to_numpy()).median()
    run = str(medians.idxmax())
    warnings.warn(
        Hint(
            f"{option('quantity', options.quantity)} without {option('align')} compares positions in the "
            "truth's and the "
            f"estimate's world frames as they are (median position error up to {medians.max():.4g} in "
            f"run {run}); if the estimator's frame is not the truth's (a VIO or SLAM map starts at its "
            f"own origin), fit it with {option('align', 'se3')} {option('align_runs', 'RUN')} on runs you "
            "then keep "
            f"out of calibration and test, or use {option('quantity', 'displacement')}, which needs no "
            "common "
            "frame"
        ),
        stacklevel=3,
    )


def _no_rows_error(p: _Prepared, counts: dict[str, int], options: IngestOptions) -> DataError:
    run, gap = p.run, options.max_gap
    worst = max(REASONS, key=lambda r: counts[r])
    if worst in ("truth_gap", "estimate_gap"):
        who, inside, largest = _gap(p, worst, options)
        return DataError(
            f"run {run.name}: no sample kept: the {who} has {inside} stamps within the "
            f"estimate's span and its largest gap there is {largest:.6g} s, above "
            f"{option('max_gap', gap)} s; "
            f"raise {option('max_gap')}, or check the {who} topic's rate and stamps"
        )
    if worst == "no_state":
        first = (
            f"its first stamp is {p.run.state.t[0]:.6f} s"
            if p.run.state and len(p.run.state.t)
            else "it is empty"
        )
        return DataError(
            f"run {run.name}: no sample kept: the state topic has no message at or before "
            f"any sample start ({first})"
        )
    return DataError(
        f"run {run.name}: no sample kept: the truth ({_span(run.truth, options.t_offset)}) does not cover "
        f"any sample start and end {options.horizon:g} s apart within the estimate ({_span(run.estimate)}); "
        f"check {option('t_offset')} and {option('horizon')}"
    )


def _rows(p: _Prepared, options: IngestOptions, state_width: int) -> tuple[pd.DataFrame, dict[str, Any]]:
    (g0, g1), (e0, e1) = p.truth, p.estimate
    reasons = {
        "estimate_gap": ~(e0.ok & e1.ok),
        "truth_outside": ~(g0.inside & g1.inside),
        "truth_gap": ~(g0.ok & g1.ok),
    }
    x = state_features(e0, e1, options.horizon, options.up or "+z")
    state = p.run.state
    if state is not None:
        st = state.t - float(p.run.estimate.t[0])
        idx = np.searchsorted(st, p.t0, side="right") - 1
        reasons["no_state"] = idx < 0
        held = state.values[np.maximum(idx, 0)] if len(st) else np.zeros((len(p.t0), state_width))
        x = np.hstack([x, held])
    dropped = np.zeros(p.t0.shape[0], dtype=bool)
    counts = {}
    for r in REASONS:
        hit = reasons.get(r, np.zeros_like(dropped)) & ~dropped
        counts[r] = int(hit.sum())
        dropped |= hit
    keep = ~dropped
    if not keep.any():
        raise _no_rows_error(p, counts, options)
    _warn_gaps(p, counts, int(p.t0.shape[0]), options)
    y, yhat = quantity_pair(options.quantity, g0, g1, e0, e1)
    cols: dict[str, Any] = {f"x_{i}": x[keep, i] for i in range(x.shape[1])}
    cols.update({f"y_{i}": y[keep, i] for i in range(y.shape[1])})
    cols.update({f"yhat_{i}": yhat[keep, i] for i in range(yhat.shape[1])})
    cols["run"] = p.run.name
    cols["t"] = p.t0[keep]
    account = {
        "run": p.run.name,
        "rows": int(keep.sum()),
        "sample_starts": int(p.t0.shape[0]),
        "dropped": counts,
        "truth_span": list(p.run.truth.span),
        "estimate_span": list(p.run.estimate.span),
        "truth_poses": len(p.run.truth),
        "estimate_poses": len(p.run.estimate),
    }
    return pd.DataFrame(cols), account


def build_samples(runs: Sequence[RunData], options: IngestOptions, hint: str = "") -> pd.DataFrame:
    """Rows ``x_*, y_*, yhat_*, run, t`` of every run (see the module docstring).

    Parameters
    ----------
    runs : sequence of RunData
        One entry per run; names must differ.
    options : IngestOptions
    hint : str
        Appended to the no-overlap error (e.g. a bag reader's hint about ``--stamp``).

    Returns
    -------
    pandas.DataFrame
        The rows; ``frame.attrs["ipcverify.io.ingest"]`` holds the account of every run (rows
        kept, dropped by reason, spans), the options, the alignment and what the x columns mean.

    Raises
    ------
    DataError
        No time overlap (both spans are printed), no sample kept in a run (with the count of
        stamps and the largest gap), repeated run names, unknown alignment runs.

    Examples
    --------
    >>> t = np.arange(0.0, 3.0, 0.1)
    >>> p = np.column_stack([t, 0 * t, 0 * t])
    >>> tr = Trajectory(t, p, np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1)))
    >>> df = build_samples([RunData("a", tr, tr)], IngestOptions())
    >>> len(df), df[["y_0", "yhat_0", "x_0"]].iloc[0].round(12).tolist()
    (10, [0.5, 0.5, 1.0])
    """
    names = [r.name for r in runs]
    if not runs:
        raise DataError("no run to ingest")
    if len(set(names)) != len(names):
        twice = sorted({n for n in names if names.count(n) > 1})
        raise DataError(f"run name(s) {', '.join(twice)} used twice; name the runs apart ({option('runs')})")
    widths = {0 if r.state is None else r.state.values.shape[1] for r in runs}
    prepared = [_prepare(r, options, hint) for r in runs]
    alignment = None
    if options.align != "none":
        alignment = _fit(prepared, options)
        prepared = [
            dataclasses.replace(
                p, estimate=(_aligned(p.estimate[0], alignment), _aligned(p.estimate[1], alignment))
            )
            for p in prepared
        ]
    parts = [_rows(p, options, max(widths)) for p in prepared]
    frame = pd.concat([f for f, _ in parts], ignore_index=True)
    state_names = runs[0].state.fields if runs[0].state is not None else ()
    frame.attrs[MANIFEST_KEY] = {
        "quantity": options.quantity,
        "options": dataclasses.asdict(with_up(options, "+z")),
        "x_columns": {f"x_{i}": d for i, d in enumerate([*state_columns(options.up or "+z"), *state_names])},
        "runs": [a for _, a in parts],
        "rows": len(frame),
        "alignment": None if alignment is None else alignment.to_dict(),
    }
    _warn_frames(frame, options)
    return frame
