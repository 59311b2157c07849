"""Row fingerprints: which rows of one dataset are rows of another, whatever their order, subset or repeats.

A whole-file hash recognises only an exact copy: a shuffled, cut or doubled copy of the calibration
data passed it as fresh test data. A **row fingerprint** identifies each row on its own:

* the row's values ``(x, y, yhat)`` (float64), each with its significand rounded to 24 bits -- the
  precision of float32, in which the network trains -- ties to even, keeping float64's exponent
  range (:func:`rounded_bits`: integer arithmetic on the bit pattern, the same bits on every
  machine; ``-0.0`` is ``0.0``);
* its fingerprint is the first 8 bytes of BLAKE2b of those 8-byte values (:func:`row_fingerprints`).

The rounding makes a round trip of the data through any format that keeps float32's precision
give the same fingerprints: CSV written by pandas (shortest round-trip text) or by
:func:`~ipcverify.data.save_dataset` (17 significant digits), Parquet and NPZ in float64 or in
float32. A text with fewer digits than float64 keeps a value's fingerprint unless the value lies
within the text's relative rounding error ``e`` of a boundary between two float32 values, which
happens for a share of about ``e 2^24`` of the values at most (below ``1e-4`` for 12 significant
digits, ``e = 5e-12``): a reused file is still recognised by nearly all of its rows. Two rows get the same
fingerprint when all their values agree to float32's precision (or, for rows that differ there,
with probability ``2^-64`` a pair).

A model file records the **sorted, distinct** fingerprints of its training rows
(:func:`ipcverify.training.train`) and of its calibration rows (:func:`ipcverify.contract.calibrate`)
under :data:`ROWS_KEY` of its metadata: :data:`BYTES_PER_ROW` = 8 bytes a row, 8 MB for 10^6 rows
(:mod:`ipcverify.io._modelio` stores them as an int64 tensor). ``calibrate`` refuses calibration
rows that are training rows, ``certify`` test rows that are either, and ``certify`` counts each
distinct test row once.

Examples
--------
>>> d = PerceptionDataset(np.array([[1.0], [2.0], [1.0]]), np.zeros((3, 1)), np.zeros((3, 1)))
>>> fp = row_fingerprints(d)
>>> bool(fp[0] == fp[2]), bool(fp[0] == fp[1]), first_occurrences(fp).tolist()
(True, False, [0, 1])
>>> count_recorded(fp, np.unique(fp[:1]))   # rows 0 and 2 are the recorded row
2
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from ipcverify.data._dataset import PerceptionDataset

U64 = NDArray[np.uint64]
Role = Literal["training", "calibration"]

#: The metadata key of a model's row fingerprints: ``{"scheme": SCHEME, "training": U64, ...}``.
ROWS_KEY = "row_fingerprints"
#: What the fingerprints are; fingerprints of another scheme are not compared (the overlap is then unchecked).
SCHEME = "ipcverify-rows-1: BLAKE2b-64 of (x, y, yhat) as float64 with 24-bit significands"
#: Bytes a model file spends per distinct training or calibration row.
BYTES_PER_ROW = 8
#: Significand bits of float64 dropped by the rounding (52 - 23: float32's precision).
DROPPED_BITS = 29
_PERSON = b"ipcverify-rows1"


def rounded_bits(values: NDArray[np.float64]) -> U64:
    """The bit patterns of ``values`` (float64) with their significands rounded to 24 bits, ties to even.

    Integer arithmetic on the IEEE-754 bit pattern: exact and the same on every machine. A
    carry out of the significand raises the exponent, as rounding should; ``-0.0`` becomes ``0.0``.

    Parameters
    ----------
    values : ndarray of float64
        Finite values.

    Examples
    --------
    >>> v = np.array([0.1, -0.0, 1.0 + 2.0**-30, 3.0])
    >>> r = rounded_bits(v).view(np.float64)
    >>> bool(r[0] == np.float32(0.1)), r[1:].tolist()
    (True, [0.0, 1.0, 3.0])
    """
    v = np.ascontiguousarray(values, dtype=np.float64) + 0.0  # -0.0 + 0.0 is +0.0
    bits = v.view(np.uint64)
    drop = np.uint64(DROPPED_BITS)
    half_less_one = np.uint64((1 << (DROPPED_BITS - 1)) - 1)
    odd = (bits >> drop) & np.uint64(1)
    mask = ~np.uint64((1 << DROPPED_BITS) - 1)
    return np.asarray((bits + half_less_one + odd) & mask, dtype=np.uint64)


def row_fingerprints(data: PerceptionDataset) -> U64:
    """One 64-bit fingerprint per row of ``data`` (in row order), as the module docstring defines it.

    Parameters
    ----------
    data : PerceptionDataset
        The rows.

    Examples
    --------
    >>> d = PerceptionDataset(np.array([[0.5]]), np.array([[1.0]]), np.array([[1.5]]))
    >>> int(row_fingerprints(d)[0]) == int(row_fingerprints(PerceptionDataset(d.x + 1e-12, d.y, d.yhat))[0])
    True
    """
    block = np.hstack([data.x, data.y, data.yhat])
    raw = rounded_bits(block).astype("<u8", copy=False).tobytes()
    width = 8 * block.shape[1]
    view = memoryview(raw)
    digests = b"".join(
        hashlib.blake2b(view[i : i + width], digest_size=8, person=_PERSON).digest()
        for i in range(0, len(raw), width)
    )
    return np.frombuffer(digests, dtype="<u8").astype(np.uint64)


def first_occurrences(fingerprints: U64) -> NDArray[np.intp]:
    """The rows (ascending) that hold the first occurrence of each distinct fingerprint.

    Parameters
    ----------
    fingerprints : ndarray of uint64
        One fingerprint per row (:func:`row_fingerprints`).
    """
    _, first = np.unique(np.asarray(fingerprints, dtype=np.uint64), return_index=True)
    return np.sort(first).astype(np.intp)


def first_distinct_rows(block: NDArray[np.float64]) -> NDArray[np.intp]:
    """The rows (ascending) of ``block`` (N, D) that hold the first occurrence of each distinct row.

    Exact equality of the float64 values (``-0.0 == 0.0``), for a computation that needs distinct
    points (the domain test's distances), not the fingerprints' rounding.

    Parameters
    ----------
    block : ndarray, shape (N, D)
        The rows.

    Examples
    --------
    >>> first_distinct_rows(np.array([[1.0, 2.0], [1.0, 2.0], [0.0, 2.0], [-0.0, 2.0]])).tolist()
    [0, 2]
    """
    z = np.ascontiguousarray(block, dtype=np.float64) + 0.0
    _, first = np.unique(z, axis=0, return_index=True)
    return np.sort(first).astype(np.intp)


def count_recorded(fingerprints: U64, recorded: U64) -> int:
    """How many of ``fingerprints`` (with repeats) are among ``recorded``.

    Parameters
    ----------
    fingerprints : ndarray of uint64
        One fingerprint per row.
    recorded : ndarray of uint64
        Fingerprints of the other rows (as a model file records them: sorted and distinct).
    """
    fp, rec = np.asarray(fingerprints, dtype=np.uint64), np.asarray(recorded, dtype=np.uint64)
    if len(rec) > 1 and not (rec[1:] > rec[:-1]).all():  # not as a model file records them
        rec = np.unique(rec)
    if len(rec) == 0:
        return 0
    at = np.minimum(np.searchsorted(rec, fp), len(rec) - 1)
    return int((rec[at] == fp).sum())


def recorded_rows(metadata: Mapping[str, Any], role: Role) -> U64 | None:
    """The fingerprints of a model's training or calibration rows (None: not recorded in this scheme).

    Parameters
    ----------
    metadata : mapping
        The model's metadata.
    role : {"training", "calibration"}
        Which rows.
    """
    record = metadata.get(ROWS_KEY)
    if not isinstance(record, Mapping) or record.get("scheme") != SCHEME or record.get(role) is None:
        return None
    return np.asarray(record[role], dtype=np.uint64)


def with_recorded_rows(metadata: Mapping[str, Any], role: Role, fingerprints: U64) -> dict[str, Any]:
    """``metadata`` with the distinct ``fingerprints`` recorded as the model's ``role`` rows.

    The other role's fingerprints are kept if they are of this :data:`SCHEME`.

    Parameters
    ----------
    metadata : mapping
        The model's metadata.
    role : {"training", "calibration"}
        Which rows these are.
    fingerprints : ndarray of uint64
        One fingerprint per row (repeats allowed).

    Examples
    --------
    >>> meta = with_recorded_rows({}, "training", np.array([5, 3, 5], dtype=np.uint64))
    >>> meta[ROWS_KEY]["training"].tolist(), recorded_rows(meta, "calibration") is None
    ([3, 5], True)
    """
    out = dict(metadata)
    old = out.get(ROWS_KEY)
    record = dict(old) if isinstance(old, Mapping) and old.get("scheme") == SCHEME else {}
    distinct = np.unique(np.asarray(fingerprints, dtype=np.uint64))
    distinct.setflags(write=False)
    record.update({"scheme": SCHEME, role: distinct})
    out[ROWS_KEY] = record
    return out
