"""Table I of the paper: the buffer-1 IPC's violation rate on test data at buffer sizes 1..5.

For each buffer size ``b`` the test set is flown on the same paths and flights (only the
camera lag differs); the row holds ``n``, the number of violations (``y`` outside the
calibrated ellipsoid), the rate, a one-sided Clopper--Pearson upper bound and a two-sided
interval. The intervals are simultaneous over the rows (Bonferroni: each row at
``delta / rows``), so "the rate rises with the buffer size" can be read off them.

The bounds treat the test samples as independent draws. They are not quite: they are
10 Hz samples along a few dozen continuous paths and flights, so neighbouring samples are
correlated and the intervals are somewhat too narrow. ``paths_with_violations`` counts
the distinct paths/flights a row's violations fall on, to show whether they cluster.

Examples
--------
>>> PAPER_TABLE1[1], PAPER_TABLE1[5]
(0.0019, 0.1105)
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ipcverify.bounds import clopper_pearson_interval, clopper_pearson_upper
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.model import IPCModel

__all__ = ["PAPER_TABLE1", "table1", "rates_rising"]

#: The paper's Table I: error of the IPC learned at buffer size 1, per buffer size.
PAPER_TABLE1: dict[int, float] = {1: 0.0019, 2: 0.0093, 3: 0.0205, 4: 0.0407, 5: 0.1105}


def table1(
    model: IPCModel, tests: Mapping[int, PerceptionDataset], delta: float = 0.05
) -> dict[int, dict[str, Any]]:
    """The rows of Table I for ``model`` on ``tests`` (buffer size -> test set).

    Parameters
    ----------
    model : IPCModel
        The calibrated IPC (learned at buffer size 1).
    tests : mapping of int to PerceptionDataset
        Test data per buffer size, never used for training or calibration.
    delta : float
        Family-wise error of all rows' bounds together; each row uses ``delta / rows``.

    Returns
    -------
    dict
        Per buffer size: ``n``, ``violations``, ``rate``, ``upper`` (one-sided CP),
        ``interval`` (two-sided CP), ``confidence`` (simultaneous), ``paper_rate``,
        ``paths_with_violations`` and ``paths``.

    Examples
    --------
    >>> from ipcverify.model import IPCNetwork, ModelConfig
    >>> m = IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,))))
    >>> ds = PerceptionDataset(np.zeros((10, 2)), np.ones((10, 3)) * 100, np.zeros((10, 3)))
    >>> table1(m, {1: ds})[1]["violations"]
    10
    """
    if not tests:
        raise InvalidInputError("Table I needs at least one test set")
    if not 0 < delta < 1:
        raise InvalidInputError(f"delta must lie strictly between 0 and 1, got {delta!r}")
    each = delta / len(tests)
    rows: dict[int, dict[str, Any]] = {}
    for b in sorted(tests):
        data = tests[b]
        violated = ~model.predict(data.x, data.yhat).contains(data.y)
        n, k = len(data), int(violated.sum())
        row: dict[str, Any] = {
            "n": n,
            "violations": k,
            "rate": k / n,
            "upper": clopper_pearson_upper(k, n, each),
            "interval": list(clopper_pearson_interval(k, n, each)),
            "confidence": 1 - delta,
            "paper_rate": PAPER_TABLE1.get(b),
        }
        if "path" in data.extra:
            keys = data.extra["path"].astype(np.int64)
            if "source" in data.extra:
                keys = keys * 2 + data.extra["source"].astype(np.int64)
            row["paths"] = int(len(np.unique(keys)))
            row["paths_with_violations"] = int(len(np.unique(keys[violated])))
        rows[b] = row
    return rows


def rates_rising(rows: Mapping[int, Mapping[str, Any]]) -> dict[str, bool]:
    """Whether the rates rise with the buffer size: point rates, and separated intervals.

    ``strict`` — every rate is above the previous one; ``separated`` — every row's
    interval lies entirely above the previous row's (a statement at the rows' simultaneous
    confidence).

    Examples
    --------
    >>> rates_rising({1: {"rate": 0.0, "interval": [0, 0.01]}, 2: {"rate": 0.3, "interval": [0.2, 0.4]}})
    {'strict': True, 'separated': True}
    """
    keys = sorted(rows)
    pairs = list(zip(keys, keys[1:], strict=False))
    return {
        "strict": all(rows[b]["rate"] > rows[a]["rate"] for a, b in pairs),
        "separated": all(rows[b]["interval"][0] > rows[a]["interval"][1] for a, b in pairs),
    }
