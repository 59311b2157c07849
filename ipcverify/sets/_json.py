"""Reading sets from JSON data: numbers, vectors and matrices, each error naming its field.

Floats round-trip exactly through :mod:`json` (it writes ``repr``). Every parse error is an
:class:`~ipcverify.errors.InvalidInputError` naming the offending field, so a shape's
``from_set_dict`` (:class:`~ipcverify.sets.OuterSet`) reads its fields with these.

Examples
--------
>>> json_vector([1, 2.5], "outer.lower")
[1.0, 2.5]
>>> json_number(float("nan"), "b[0]")
Traceback (most recent call last):
...
ipcverify.errors.InvalidInputError: field 'b[0]': nan is not finite; use finite numbers
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

from ipcverify.errors import InvalidInputError


def json_number(v: Any, where: str) -> float:
    """A finite JSON number as a float (an integer must be exactly representable).

    Parameters
    ----------
    v : Any
        The parsed JSON value; a bool, non-number, non-finite float or inexact integer raises
        :class:`InvalidInputError`.
    where : str
        The field's path, for the error message.
    """
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InvalidInputError(f"field '{where}': expected a number, got {json.dumps(v)[:40]}")
    if isinstance(v, int):
        f = float(v) if abs(v) < 2**1024 else math.inf
        if not math.isfinite(f) or int(f) != v:
            digits = str(abs(v))
            shown = (
                str(v)
                if len(digits) <= 40
                else f"{'-' if v < 0 else ''}{digits[:12]}... ({len(digits)} digits)"
            )
            raise InvalidInputError(
                f"field '{where}': integer {shown} is not exactly a float; write it as a float"
            )
        return f
    if not math.isfinite(v):
        raise InvalidInputError(f"field '{where}': {v} is not finite; use finite numbers")
    return float(v)


def json_vector(v: Any, where: str, length: int | None = None) -> list[float]:
    """A non-empty JSON list of numbers (of ``length`` entries, if given).

    Parameters
    ----------
    v : Any
        The parsed JSON value; each entry is read by :func:`json_number`.
    where : str
        The field's path, for error messages (entries are ``where[i]``).
    length : int, optional
        The required number of entries (any, if None).
    """
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of numbers")
    if length is not None and len(v) != length:
        raise InvalidInputError(f"field '{where}': expected {length} numbers, got {len(v)}")
    return [json_number(x, f"{where}[{i}]") for i, x in enumerate(v)]


def json_matrix(v: Any, where: str, cols: int | None = None) -> list[list[float]]:
    """A non-empty JSON list of equally long rows of numbers (of ``cols`` entries, if given)."""
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of rows")
    rows = [json_vector(r, f"{where}[{i}]", cols) for i, r in enumerate(v)]
    width = len(rows[0])
    for i, r in enumerate(rows):
        if len(r) != width:
            raise InvalidInputError(f"field '{where}[{i}]': row has {len(r)} entries, expected {width}")
    return rows


def json_field(d: Mapping[str, Any], key: str, where: str) -> Any:
    """``d[key]``, or an error naming the missing field ``where + key``.

    Parameters
    ----------
    d : mapping
        A parsed JSON object.
    key : str
        The field's name.
    where : str
        The object's path prefix (``""`` at the top, ``"outer."`` inside ``outer``).
    """
    if key not in d:
        raise InvalidInputError(f"field '{where}{key}' is missing")
    return d[key]
