"""The groups of a Mondrian calibration: the distinct values of a column, or quantile bins of it.

For a continuous column the bin edges are quantiles of a seeded random share of the
calibration set (``edge_fraction``) that is then left out of the scores, so that the bins are
fixed independently of the samples they calibrate. The column must be an ``x`` or ``yhat``
column (:func:`locate_column`): the groups are looked up at predict time.
"""

from __future__ import annotations

import math
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ipcverify._wording._spelling import option
from ipcverify.calibration._protocol import FloatArray
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError

#: Most distinct values a discrete group column may have (use ``bins`` beyond that).
MAX_GROUPS = 64
#: Default share of the calibration data spent on placing the bin edges.
EDGE_FRACTION = 0.2


Groups = tuple[list[dict[str, Any]], list[NDArray[np.bool_]], tuple[float, ...], int]


def discrete_groups(values: FloatArray, column: str) -> Groups:
    """One group per distinct value: specs, membership masks, no edges, no edge samples."""
    uniq = np.unique(values)
    if len(uniq) > MAX_GROUPS:
        raise InvalidInputError(
            f"column {column!r} has {len(uniq)} distinct values (more than {MAX_GROUPS}); "
            f"it looks continuous -- pass {option('mondrian_bins', 'K')} to calibrate per quantile bin"
        )
    specs: list[dict[str, Any]] = [{"label": f"{column}={u:g}", "value": float(u)} for u in uniq]
    return specs, [values == u for u in uniq], (), 0


def quantile_bins(
    values: FloatArray, column: str, bins: int, edge_fraction: float, seed: int
) -> tuple[list[dict[str, Any]], list[NDArray[np.bool_]], tuple[float, ...], int, NDArray[np.intp]]:
    """Quantile bins whose edges come from a seeded share of the samples (then left out).

    Returns the specs, membership masks over the kept samples, the interior edges, the
    number of edge samples and the indices of the kept samples.
    """
    check_bins(bins)
    check_edge_fraction(edge_fraction)
    perm = np.random.default_rng(seed).permutation(len(values))
    n_edge = max(1, int(round(edge_fraction * len(values))))
    edge_vals, keep = values[perm[:n_edge]], np.sort(perm[n_edge:])
    e = np.unique(np.quantile(edge_vals, np.arange(1, bins) / bins)) if bins > 1 else np.zeros(0)
    edges = tuple(float(v) for v in e)
    idx = np.searchsorted(e, values[keep], side="right")
    bounds = [-math.inf, *edges, math.inf]
    specs: list[dict[str, Any]] = [
        {
            "label": f"{bounds[j]:.4g} <= {column} < {bounds[j + 1]:.4g}",
            "lower": bounds[j],
            "upper": bounds[j + 1],
        }
        for j in range(len(edges) + 1)
    ]
    return specs, [idx == j for j in range(len(specs))], edges, n_edge, keep


def check_bins(bins: int) -> None:
    """Refuse a number of bins that is not a positive integer."""
    if isinstance(bins, bool) or not isinstance(bins, (int, np.integer)) or bins < 1:
        raise InvalidInputError(f"bins must be a positive integer; got {bins!r}")


def check_edge_fraction(edge_fraction: float) -> None:
    """Refuse an edge share outside ``(0, 1)``."""
    if not (isinstance(edge_fraction, (int, float)) and 0.0 < edge_fraction < 1.0):
        raise InvalidInputError(f"edge_fraction must lie in (0, 1); got {edge_fraction!r}")


def locate_column(data: PerceptionDataset, name: str) -> tuple[Literal["x", "yhat"], int]:
    """Where a Mondrian column lives at predict time: ``("x" or "yhat", position)``.

    Raises
    ------
    InvalidInputError
        If the column is part of ``y`` or an extra column (neither is known at predict time).
    DataError
        If ``data`` has no such column (the message lists the columns).
    """
    if name in data.x_columns:
        return "x", data.x_columns.index(name)
    if name in data.yhat_columns:
        return "yhat", data.yhat_columns.index(name)
    if name in data.y_columns:
        raise InvalidInputError(
            f"group column {name!r} is part of the ground truth y, which is unknown at predict time; "
            "group by an x or yhat column"
        )
    data.column(name)  # raises DataError listing the available columns if unknown
    raise InvalidInputError(
        f"group column {name!r} is an extra column of {data.source}, which the contract cannot see at "
        f"predict time; group by an x column ({', '.join(data.x_columns)}) or a yhat column"
    )
