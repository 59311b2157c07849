"""Checks that a dataset can carry a contract, and hints about how its rows are related.

* :func:`check_informative` -- data made mostly of repeated rows are refused (training and
  calibration); a constant column is refused for training and is a warning for calibration.
* :func:`input_ranges` / :func:`warn_outside_training` -- the ranges of the training inputs are
  stored in the model at training; calibration inputs mostly outside them are a warning.
* :func:`warn_correlated_rows` -- a file with a ``run``, ``flight``, ``sequence`` or ``group``
  column used row by row gets a :class:`~ipcverify.errors.Hint` about correlated rows.

Warnings are Python warnings (:class:`~ipcverify.errors.DataWarning`,
:class:`~ipcverify.errors.Hint`); the CLI prints each on one line.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from scipy import stats

from ipcverify._wording._spelling import command, option, options
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import DataError, DataWarning, Hint

#: Column names (case-insensitive, also with ``_id``) that usually name a group of correlated rows.
GROUP_NAMES = ("run", "flight", "sequence", "group", "episode", "trajectory", "session", "segment", "block")
#: Data with fewer distinct rows than this share of its rows are refused.
MIN_DISTINCT_SHARE = 0.5
#: Calibration inputs outside the training ranges above this share are a warning (if surprising).
MOSTLY_OUTSIDE = 0.5
#: ... and if data drawn like the training data would leave that many out with probability below this.
SURPRISE = 1e-3

Purpose = Literal["training", "calibration"]


def _blocks(data: PerceptionDataset) -> tuple[np.ndarray, list[str]]:
    names = [*data.x_columns, *data.y_columns, *data.yhat_columns]
    return np.hstack([data.x, data.y, data.yhat]), names


def check_informative(data: PerceptionDataset, purpose: Purpose) -> None:
    """Refuse data that cannot carry a contract; warn about data that weaken it.

    * Fewer distinct rows (of ``x``, ``y``, ``yhat``) than half the rows, or fewer than 2:
      repeated rows are not independent samples -- refused.
    * Some rows repeat an earlier one: a :class:`~ipcverify.errors.DataWarning` that says how many
      (for calibration: that the repeats break the exchangeability its guarantee rests on).
    * A constant column: refused for training (the network cannot learn how the errors depend on
      it, and extrapolates on any other value); a warning for calibration (the domain of validity
      then flags every query with another value).

    Parameters
    ----------
    data : PerceptionDataset
        The data.
    purpose : {"training", "calibration"}
        What the data is for (a constant column is refused for training only).

    Raises
    ------
    DataError
        For data made mostly of repeated rows, or a constant column in training data.

    Examples
    --------
    >>> x = np.zeros((4, 1)); y = np.arange(4.0)[:, None]
    >>> check_informative(PerceptionDataset(x, y, y + 1, source="log.csv"), "training")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: log.csv: column x_0 (every row is 0) is constant; ...
    """
    block, names = _blocks(data)
    n = len(block)
    distinct = len(np.unique(block, axis=0))
    if n < 2:
        raise DataError(
            f"{data.source}: only {n} row; {purpose} needs at least 2 distinct rows (independent samples), "
            "and far more for a useful contract"
        )
    if distinct < max(2, math.ceil(MIN_DISTINCT_SHARE * n)):
        raise DataError(
            f"{data.source}: only {distinct} distinct row{'s' if distinct != 1 else ''} among {n}: repeated "
            f"rows are not independent samples, and {purpose} would count them as such (the domain of "
            "validity would shrink to the repeated points); remove the duplicates or check how the file "
            "was assembled"
        )
    if distinct < n:
        warnings.warn(DataWarning(_repeats_text(data.source, n, distinct, purpose)), stacklevel=2)
    constant = [i for i in range(block.shape[1]) if block[0, i] == block[:, i].min() == block[:, i].max()]
    if not constant:
        return
    listed = ", ".join(f"{names[i]} (every row is {block[0, i]:g})" for i in constant)
    plural = "s" if len(constant) > 1 else ""
    if purpose == "training":
        raise DataError(
            f"{data.source}: column{plural} {listed} {'are' if plural else 'is'} constant; "
            "the network cannot learn how the errors depend on a constant column, and would extrapolate "
            f"on any other value -- leave it out ({options('x_columns', 'y_columns', 'yhat_columns')} "
            "name the "
            "columns to use) or train on data where it varies"
        )
    warnings.warn(
        DataWarning(
            f"{data.source}: calibration column{plural} {listed} {'are' if plural else 'is'} constant; "
            "the guarantee then covers only queries with this value, and the domain of validity flags "
            "every other one"
        ),
        stacklevel=2,
    )


def _repeats_text(source: str, n: int, distinct: int, purpose: Purpose) -> str:
    """The warning for ``n - distinct`` repeated rows; for calibration, what they break."""
    repeats = (
        f"{source}: {n - distinct:,} of {n:,} {purpose} rows repeat an earlier row ({distinct:,} distinct)"
    )
    if purpose == "calibration":
        return (
            f"{repeats}; the guarantee rests on the calibration rows being exchangeable with deployment "
            "rows, and a repeated row is one sample counted again, which breaks that exchangeability -- "
            "remove the repeats unless the data really repeat (the domain of validity is fitted on the "
            "distinct inputs)"
        )
    return (
        f"{repeats}; repeated rows are not independent samples -- remove them unless the data really repeat"
    )


def input_ranges(data: PerceptionDataset) -> dict[str, Any]:
    """The ranges of the inputs ``(x, yhat)`` and their number, stored in the model at training.

    Parameters
    ----------
    data : PerceptionDataset
        The training data.

    Examples
    --------
    >>> d = PerceptionDataset(np.array([[0.0], [2.0]]), np.zeros((2, 1)), np.array([[1.0], [-1.0]]))
    >>> input_ranges(d)
    {'columns': ['x_0', 'yhat_0'], 'lower': [0.0, -1.0], 'upper': [2.0, 1.0], 'n': 2}
    """
    z = np.hstack([data.x, data.yhat])
    return {
        "columns": [*data.x_columns, *data.yhat_columns],
        "lower": [float(v) for v in z.min(axis=0)],
        "upper": [float(v) for v in z.max(axis=0)],
        "n": len(z),
    }


def warn_outside_training(metadata: Mapping[str, Any], data: PerceptionDataset) -> float | None:
    """Warn if most calibration inputs lie outside the ranges of the training inputs.

    A calibration input exchangeable with the ``n`` training inputs lies outside their range in a
    given column with probability at most ``2 / (n + 1)`` (it would have to be the smallest or the
    largest of ``n + 1``), so outside the box of ``D`` columns with probability at most
    ``p0 = min(1, 2 D / (n + 1))``. The warning needs more than :data:`MOSTLY_OUTSIDE` of the rows
    outside *and* a count that a binomial ``(m, p0)`` reaches with probability below ``1e-3``:
    calibration data drawn like the training data trigger it at most that often (fewer training
    rows than ``4 D`` can never trigger it).

    Returns the share of rows with some input outside the training range (None if the model
    stores no ranges: models trained before ipcverify stored them).

    Parameters
    ----------
    metadata : mapping
        The model's metadata (its training input ranges, from :func:`input_ranges`).
    data : PerceptionDataset
        The calibration data.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> train = PerceptionDataset(rng.normal(size=(500, 1)), np.zeros((500, 1)), rng.normal(size=(500, 1)))
    >>> far = PerceptionDataset(train.x + 9.0, train.y, train.yhat)
    >>> import warnings
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     share = warn_outside_training({"training_inputs": input_ranges(train)}, far)
    >>> share, "x_0: 100 % outside" in str(w[0].message)
    (1.0, True)
    """
    ranges = metadata.get("training_inputs")
    if not isinstance(ranges, Mapping):
        return None
    lower, upper = np.asarray(ranges["lower"], dtype=float), np.asarray(ranges["upper"], dtype=float)
    z = np.hstack([data.x, data.yhat])
    if z.shape[1] != len(lower):
        return None
    out = (z < lower) | (z > upper)
    outside = int(out.any(axis=1).sum())
    share = outside / len(z)
    n_train = int(ranges.get("n", metadata.get("train_n", 0)))
    p0 = min(1.0, 2.0 * len(lower) / (n_train + 1))
    if share > MOSTLY_OUTSIDE and stats.binom.sf(outside - 1, len(z), p0) < SURPRISE:
        names = [*data.x_columns, *data.yhat_columns]
        counts = out.sum(axis=0)
        worst = [i for i in np.argsort(-counts, kind="stable")[:3] if counts[i]]
        detail = "; ".join(
            f"{names[i]}: {100 * counts[i] / len(z):.0f} % outside [{lower[i]:.4g}, {upper[i]:.4g}]"
            for i in worst
        )
        warnings.warn(
            DataWarning(
                f"{data.source}: {100 * share:.0f} % of the calibration inputs lie outside the ranges of the "
                f"training inputs ({detail}; rows exchangeable with the {n_train} training rows would leave "
                f"at most {100 * p0:.2g} %); the network extrapolates there, so the calibration will make "
                "its sets large to cover it -- calibrate on data drawn like the training data, or train on "
                "data that covers these inputs"
            ),
            stacklevel=2,
        )
    return share


def group_like_counts(data: PerceptionDataset) -> dict[str, int]:
    """Extra columns that look like a group of correlated rows, with their numbers of groups.

    A column counts when it is named like ``run`` or ``flight_id`` (a name of
    :data:`GROUP_NAMES`, maybe with ``_id``, ``id``, ``_name`` or ``s`` after it) and has at least
    2 groups and fewer groups than rows; the one with the most groups comes first.

    Parameters
    ----------
    data : PerceptionDataset
        The data.

    Examples
    --------
    >>> d = PerceptionDataset(np.zeros((6, 1)), np.zeros((6, 1)), np.zeros((6, 1)),
    ...                       extra={"Run": np.arange(6) // 3, "flight_id": np.arange(6) // 2,
    ...                              "t": np.arange(6.0)})
    >>> group_like_counts(d)
    {'flight_id': 3, 'Run': 2}
    """
    found: list[tuple[int, str]] = []
    for name in data.extra:
        base = name.strip().lower()
        for suffix in ("_id", "id", "_name", "s"):
            if base.endswith(suffix) and base[: -len(suffix)] in GROUP_NAMES:
                base = base[: -len(suffix)]
        if base in GROUP_NAMES:
            groups = len(np.unique(np.asarray(data.extra[name]).astype(str)))
            if 2 <= groups < len(data):
                found.append((groups, name))
    return {name: groups for groups, name in sorted(found, key=lambda t: -t[0])}


def warn_correlated_rows(
    data: PerceptionDataset, what: str, remedy: str, parameter: str = "group_column"
) -> None:
    """A :class:`~ipcverify.errors.Hint` that rows of one run (flight, ...) are likely correlated.

    Parameters
    ----------
    data : PerceptionDataset
        The data about to be used row by row.
    what : str
        What is done row by row ("calibrating", "certifying").
    remedy : str
        What naming the group column would do instead, e.g. "to calibrate with whole runs
        as the exchangeable units".
    parameter : str
        The parameter that names the column (a key of
        :data:`ipcverify._wording._spelling.PARAMETERS`): ``"group_column"``, or ``"grouped"`` for
        a calibration.
    """
    counts = group_like_counts(data)
    if not counts:
        return
    columns = list(counts)
    col, groups = columns[0], counts[columns[0]]
    others = "".join(f" (or {option(parameter, c)})" for c in columns[1:])
    few = ""
    # the smallest epsilon a PAC calibration by group certifies: k = n, (1 - eps)^groups <= delta
    floor = 1.0 - FEW_GROUPS_DELTA ** (1.0 / groups)
    if floor >= FEW_GROUPS_EPSILON:
        few = (
            f"; but with {groups} groups a calibration by group can certify no epsilon below "
            f"{floor:.2g} at delta = {FEW_GROUPS_DELTA:g}: for one or a few long runs, cut them into "
            "contiguous time blocks "
            f"({command('split', [('...', 'DATA')], block='SECONDS', group_name='segment')}) "
            "and use "
            "those as the groups"
        )
    warnings.warn(
        Hint(
            f"{data.source} has a {col!r} column ({groups} groups): rows of one {col} are usually "
            f"correlated, and {what} row by row treats every row as an independent sample; pass "
            f"{option(parameter, col)}{others} {remedy}{few}"
        ),
        stacklevel=3,
    )


#: A group column whose groups cannot certify an epsilon below this (at :data:`FEW_GROUPS_DELTA`) is
#: called too few in the correlated-rows hint (6 groups or fewer at 0.5 and 0.01).
FEW_GROUPS_EPSILON = 0.5
FEW_GROUPS_DELTA = 0.01

#: Names of a time column, as ``ipcverify ingest`` writes it (``t``) and as logs often name it.
TIME_NAMES = ("t", "time", "timestamp", "stamp")


def time_column(data: PerceptionDataset) -> str | None:
    """The first extra column named as in :data:`TIME_NAMES` that holds numbers (None: no such column).

    Parameters
    ----------
    data : PerceptionDataset
        The log.

    Examples
    --------
    >>> z = np.zeros((2, 1))
    >>> time_column(PerceptionDataset(z, z, z, extra={"run": np.array(["a", "b"]), "Time": np.arange(2.0)}))
    'Time'
    """
    for name in data.extra:
        if name.strip().lower() in TIME_NAMES and np.asarray(data.extra[name]).dtype.kind in "iuf":
            return name
    return None


def warn_out_of_time_order(data: PerceptionDataset, what: str) -> None:
    """A :class:`~ipcverify.errors.Hint` when a time column goes back within a run (for row-order work).

    The time column is the first extra column named as in :data:`TIME_NAMES` that holds
    numbers; the run is the first column :func:`group_like_counts` finds. A step back in time
    between consecutive rows of the same run (or anywhere, without a run column) is reported
    with its row, since ``what`` follows the file's order, not the clock's.

    Parameters
    ----------
    data : PerceptionDataset
        The log.
    what : str
        What follows the rows in file order ("the monitor replays").

    Examples
    --------
    >>> import warnings
    >>> z = np.zeros((4, 1))
    >>> runs, t = np.array([0, 0, 1, 1]), np.array([0.0, 1.0, 0.0, 1.0])
    >>> d = PerceptionDataset(z, z, z, extra={"run": runs, "t": t})
    >>> with warnings.catch_warnings(record=True) as w:
    ...     warnings.simplefilter("always")
    ...     warn_out_of_time_order(d, "the monitor replays")  # each run in order: nothing to say
    >>> len(w)
    0
    """
    col = time_column(data)
    if col is None or len(data) < 2:
        return
    t = np.asarray(data.extra[col], dtype=np.float64)
    back = np.diff(t) < 0
    runs = list(group_like_counts(data))
    if runs:
        labels = np.asarray(data.extra[runs[0]]).astype(str)
        back &= labels[1:] == labels[:-1]
    if not back.any():
        return
    r = int(np.flatnonzero(back)[0]) + 1
    where = f" within {runs[0]} {labels[r]}" if runs else ""
    new_run = (
        "" if runs else ", or a new run starts there without a column naming the runs (add one, e.g. run)"
    )
    warnings.warn(
        Hint(
            f"{data.source}: column {col!r} goes back in time at row {r} (0-based){where}, from {t[r - 1]:g} "
            f"to {t[r]:g}; {what} the rows in file order, so sort the log by time{new_run}"
        ),
        stacklevel=3,
    )
