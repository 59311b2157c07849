"""How a dataset is split: of samples, or of whole groups (flights, runs) given by a label column.

:func:`split_parts` gives the row indices of the train, calibration and test parts that
:meth:`~ipcverify.data.PerceptionDataset.split` returns; :func:`group_codes` numbers the
groups of a label column (also for calibration, the group test and the domain test).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import DataError


def split_parts(
    n: int,
    fractions: Sequence[float],
    seed: int,
    groups: ArrayLike | None = None,
    what: str = "group column",
) -> list[NDArray[np.intp]]:
    """Row indices of the train, calibration and test parts of ``n`` samples (a seeded random split).

    Parameters
    ----------
    n : int
        Number of samples.
    fractions : three floats summing to 1
        Shares of the parts (of groups, with ``groups``); a share may be 0.
    seed : int
        The same seed always gives the same split.
    groups : array_like, shape (n,), optional
        A group label per sample: whole groups go to the parts, none is split.
    what : str
        How to name the group column in error messages.

    Returns
    -------
    list of three ndarray of int
        The (unsorted) row indices of each part.

    Raises
    ------
    DataError
        If the fractions are bad, or there are too few groups for every part with a positive share.

    Examples
    --------
    >>> [len(p) for p in split_parts(10, (0.6, 0.2, 0.2), seed=0)]
    [6, 2, 2]
    >>> [sorted(p.tolist()) for p in split_parts(4, (0.5, 0.5, 0.0), 1, groups=["a", "a", "b", "b"])]
    [[0, 1], [2, 3], []]
    """
    fr = split_fractions(fractions)
    if groups is None:
        perm = np.random.default_rng(seed).permutation(n)
        counts = _part_sizes(fr, n)
        parts = np.split(perm, np.cumsum(counts)[:2])
    else:
        codes, labels = group_codes(groups, what)
        G = len(labels)
        counts = _part_sizes(fr, G)
        refuse_empty_parts(fr.tolist(), counts, f"{what} has", "group", fractions)
        group_perm = np.random.default_rng(seed).permutation(G)
        part_of_group = np.empty(G, dtype=np.intp)
        for j, ids in enumerate(np.split(group_perm, np.cumsum(counts)[:2])):
            part_of_group[ids] = j
        part = part_of_group[codes]
        parts = [np.flatnonzero(part == j) for j in range(3)]
    return parts


def refuse_empty_parts(
    fractions: Sequence[float], counts: Sequence[int], who: str, unit: str, given: Sequence[float]
) -> None:
    """Refuse a split in which a part with a positive share gets nothing (too few rows or groups).

    Parameters
    ----------
    fractions : sequence of float
        The checked shares of train, calibration and test.
    counts : sequence of int
        The rows or groups each part got.
    who : str
        The start of the message, naming the data (``"log.csv has"``).
    unit : str
        What was split: ``"row"`` or ``"group"``.
    given : sequence of float
        The shares as the user gave them, for the message.

    Raises
    ------
    DataError
        Naming the empty parts and about how many rows or groups every part needs.

    Examples
    --------
    >>> shares = [0.6, 0.2, 0.2]
    >>> refuse_empty_parts(shares, [1, 0, 0], "one_row.csv has", "row", shares)  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    ipcverify.errors.DataError: one_row.csv has 1 row, too few ... get no row; use about 5 or more rows, ...
    """
    empty = [
        name
        for name, f, c in zip(("train", "calibration", "test"), fractions, counts, strict=True)
        if f > 0 and c == 0
    ]
    if not empty:
        return
    n = sum(counts)
    need = max(math.ceil(1 / f) for f in fractions if f > 0)
    parts_text = " and ".join(empty) + (" parts" if len(empty) > 1 else " part")
    raise DataError(
        f"{who} {n} {unit}{'' if n == 1 else 's'}, too few for split fractions {list(given)}: the "
        f"{parts_text} would get no {unit}; use about {need} or more {unit}s, or change the fractions"
    )


def split_fractions(fractions: Sequence[float]) -> NDArray[np.float64]:
    """The shares of the train, calibration and test parts, checked: three non-negative numbers summing to 1.

    Parameters
    ----------
    fractions : sequence of float
        The shares.

    Examples
    --------
    >>> split_fractions([0.5, 0.5, 0.0]).tolist()
    [0.5, 0.5, 0.0]
    """
    fr = np.asarray(fractions, dtype=float)
    if fr.shape != (3,) or (fr < 0).any() or not np.isclose(fr.sum(), 1.0):
        raise DataError(
            f"split fractions must be three non-negative numbers summing to 1; got {list(fractions)}"
        )
    return fr


def _part_sizes(fractions: NDArray[np.float64], n: int) -> list[int]:
    """Sizes of the train, calibration and test parts of ``n`` items (rounded; test takes the rest)."""
    n_train = int(round(fractions[0] * n))
    n_cal = min(int(round(fractions[1] * n)), n - n_train)
    return [n_train, n_cal, n - n_train - n_cal]


def group_codes(labels: ArrayLike, what: str = "group column") -> tuple[NDArray[np.intp], NDArray[Any]]:
    """Integer codes ``0 .. G - 1`` of group labels, in the order of the sorted distinct labels.

    Parameters
    ----------
    labels : array_like, shape (N,)
        One label per sample (numbers or strings; mixed types are compared as strings).
    what : str
        How to name the labels in error messages.

    Returns
    -------
    codes : ndarray of int, shape (N,)
        The group of every sample.
    distinct : ndarray, shape (G,)
        The distinct labels, sorted; ``distinct[codes]`` gives back the labels.

    Raises
    ------
    DataError
        If there are no labels, they are not one-dimensional, or one is missing (NaN/None).

    Examples
    --------
    >>> codes, distinct = group_codes(["b", "a", "b", "c"])
    >>> codes.tolist(), distinct.tolist()
    ([1, 0, 1, 2], ['a', 'b', 'c'])
    """
    arr = np.asarray(labels)
    if arr.ndim != 1 or arr.size == 0:
        raise DataError(
            f"{what}: need one group label per sample (a non-empty 1-D array); got shape {arr.shape}"
        )
    missing = pd.isna(arr)
    if missing.any():
        r = int(np.flatnonzero(missing)[0])
        raise DataError(
            f"{what}: row {r} (0-based) has no group label (it is empty); every sample needs its group"
        )
    try:
        distinct, codes = np.unique(arr, return_inverse=True)
    except TypeError:  # mixed types in an object array: compare as text
        distinct, codes = np.unique(arr.astype(str), return_inverse=True)
    return codes.astype(np.intp).ravel(), distinct


#: More time blocks than this is a block length in the wrong units (and would overflow a count).
MAX_BLOCKS = 2**40


def time_blocks(
    t: ArrayLike,
    seconds: float,
    groups: ArrayLike | None = None,
    what: str = "time column",
    group_what: str = "group column",
) -> NDArray[np.intp]:
    """Each sample's contiguous time block: ``floor((t - t0) / seconds)``, ``t0`` its group's first time.

    Whole blocks kept together make a split of one long run in which neighbouring rows (the
    most correlated ones) stay in one part; only rows at the edge of two blocks are neighbours
    across parts.

    Parameters
    ----------
    t : array_like, shape (N,)
        Each sample's time, in seconds (any origin; samples need not be in order).
    seconds : float
        The length of a block (> 0).
    groups : array_like, shape (N,), optional
        A run label per sample: blocks are counted from each run's first time (``t0``), so a
        run's first block always starts with it. Default: one ``t0`` for all samples.
    what : str
        How to name ``t`` in error messages.
    group_what : str
        How to name ``groups`` in error messages.

    Returns
    -------
    ndarray of int, shape (N,)
        The block of every sample, 0 for the first ``seconds`` of its run.

    Raises
    ------
    DataError
        If ``seconds`` is not a positive finite number (a bool is not), a time is not a finite
        number, a group label is missing, or the blocks would number more than :data:`MAX_BLOCKS`.

    Examples
    --------
    >>> time_blocks([0.0, 4.9, 5.0, 12.0, 100.0, 103.0], 5.0, groups=[0, 0, 0, 0, 1, 1]).tolist()
    [0, 0, 1, 2, 0, 0]
    """
    if isinstance(seconds, bool) or not isinstance(seconds, numbers.Real):
        raise DataError(f"a time block must last a positive number of seconds; got {seconds!r}")
    length = float(seconds)
    if not (math.isfinite(length) and length > 0):
        raise DataError(f"a time block must last a positive number of seconds; got {seconds!r}")
    try:
        times = np.asarray(t, dtype=np.float64)
    except (TypeError, ValueError):
        raise DataError(f"{what} must hold numbers (seconds) to cut time blocks") from None
    bad = ~np.isfinite(times)
    if times.ndim != 1 or bad.any():
        r = int(np.flatnonzero(bad)[0]) if times.ndim == 1 else 0
        raise DataError(
            f"{what}: row {r} (0-based) has no finite time; every row needs one to cut time blocks"
        )
    codes = np.zeros(len(times), dtype=np.intp) if groups is None else group_codes(groups, group_what)[0]
    start = np.full(int(codes.max(initial=-1)) + 1, np.inf)
    np.minimum.at(start, codes, times)
    blocks = np.floor((times - start[codes]) / length)
    if blocks.size and not blocks.max() < MAX_BLOCKS:
        raise DataError(
            f"{what}: blocks of {seconds!r} s cut the log into {blocks.max() + 1:.3g} blocks; "
            "give a block length in seconds of the same order as the runs"
        )
    return blocks.astype(np.intp)
