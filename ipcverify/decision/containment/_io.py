"""The JSON formats of sets and containment problems (``docs/containment.md``).

Floats round-trip exactly through :mod:`json` (it writes ``repr``). Every parse error is
an :class:`~ipcverify.errors.InvalidInputError` naming the offending field.

Examples
--------
>>> set_from_dict(set_to_dict(Box([0.0], [1.0]))).upper
array([1.])
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from ipcverify.decision.containment._status import Method, check_method, parse_method
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._shapes import Box, Ellipsoid, OuterSet, Polytope, single_ellipsoid

__all__ = [
    "json_number",
    "json_field",
    "set_to_dict",
    "set_from_dict",
    "problem_from_dict",
]


def set_to_dict(s: OuterSet) -> dict[str, Any]:
    """JSON-ready form of a single set (floats round-trip exactly through :mod:`json`).

    Examples
    --------
    >>> set_to_dict(Box([0.0], [1.0]))
    {'type': 'box', 'lower': [0.0], 'upper': [1.0]}
    """
    if isinstance(s, Box):
        return {"type": "box", "lower": s.lower.tolist(), "upper": s.upper.tolist()}
    if isinstance(s, Polytope):
        return {"type": "polytope", "A": s.A.tolist(), "b": s.b.tolist()}
    if isinstance(s, Ellipsoid):
        single_ellipsoid(s, "ellipsoid")
        return {"type": "ellipsoid", "center": s.centers[0].tolist(), "shape": s.shapes[0].tolist()}
    raise SetError(f"cannot serialise a {type(s).__name__}; expected Box, Polytope or Ellipsoid")


def json_number(v: Any, where: str) -> float:
    """A finite JSON number as a float (an integer must be exactly representable)."""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InvalidInputError(f"field '{where}': expected a number, got {json.dumps(v)[:40]}")
    if isinstance(v, int):
        f = float(v) if abs(v) < 2**1024 else math.inf
        if not math.isfinite(f) or int(f) != v:
            raise InvalidInputError(
                f"field '{where}': integer {v} is not exactly a float; write it as a float"
            )
        return f
    if not math.isfinite(v):
        raise InvalidInputError(f"field '{where}': {v} is not finite; use finite numbers")
    return float(v)


def _json_vector(v: Any, where: str, length: int | None = None) -> list[float]:
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of numbers")
    if length is not None and len(v) != length:
        raise InvalidInputError(f"field '{where}': expected {length} numbers, got {len(v)}")
    return [json_number(x, f"{where}[{i}]") for i, x in enumerate(v)]


def _json_matrix(v: Any, where: str, cols: int | None = None) -> list[list[float]]:
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of rows")
    rows = [_json_vector(r, f"{where}[{i}]", cols) for i, r in enumerate(v)]
    width = len(rows[0])
    for i, r in enumerate(rows):
        if len(r) != width:
            raise InvalidInputError(f"field '{where}[{i}]': row has {len(r)} entries, expected {width}")
    return rows


def json_field(d: Mapping[str, Any], key: str, where: str) -> Any:
    """``d[key]``, or an error naming the missing field ``where + key``."""
    if key not in d:
        raise InvalidInputError(f"field '{where}{key}' is missing")
    return d[key]


def set_from_dict(d: Any, where: str = "") -> OuterSet:
    """Parse ``{"type": "box" | "polytope" | "ellipsoid", ...}`` (see ``docs/containment.md``).

    Parameters
    ----------
    d : dict
        The set's JSON object.
    where : str
        Field-path prefix used in error messages (for example ``"outer."``).

    Raises
    ------
    InvalidInputError
        Naming the offending field.

    Examples
    --------
    >>> set_from_dict({"type": "ellipsoid", "center": [0.0], "shape": [[2.0]]})
    Ellipsoid(batch_size=1, dim=1)
    """
    if not isinstance(d, Mapping):
        raise InvalidInputError(f"field '{where.rstrip('.') or 'set'}': expected a JSON object")
    kind = json_field(d, "type", where)
    try:
        if kind == "box":
            lo = _json_vector(json_field(d, "lower", where), f"{where}lower")
            up = _json_vector(json_field(d, "upper", where), f"{where}upper", len(lo))
            return Box(np.asarray(lo, dtype=np.float64), np.asarray(up, dtype=np.float64))
        if kind == "polytope":
            a = _json_matrix(json_field(d, "A", where), f"{where}A")
            b = _json_vector(json_field(d, "b", where), f"{where}b", len(a))
            return Polytope(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
        if kind == "ellipsoid":
            c = _json_vector(json_field(d, "center", where), f"{where}center")
            s = _json_matrix(json_field(d, "shape", where), f"{where}shape", len(c))
            if len(s) != len(c):
                raise InvalidInputError(
                    f"field '{where}shape': expected {len(c)} rows to match the center, got {len(s)}"
                )
            return Ellipsoid(np.array(c), np.array(s))
    except SetError as exc:
        raise SetError(f"field '{where.rstrip('.') or 'set'}': {exc}") from None
    raise InvalidInputError(
        f"field '{where}type': {json.dumps(kind)[:40]} is not one of 'box', 'polytope', 'ellipsoid'"
    )


def problem_from_dict(d: Any) -> tuple[Ellipsoid, OuterSet, Method | None]:
    """Parse one problem ``{"inner": ELLIPSOID, "outer": SET, "method"?: str}``.

    Examples
    --------
    >>> p = {"inner": {"type": "ellipsoid", "center": [0.0], "shape": [[1.0]]},
    ...      "outer": {"type": "box", "lower": [-1.0], "upper": [1.0]}}
    >>> problem_from_dict(p)[2] is None
    True
    """
    if not isinstance(d, Mapping):
        raise InvalidInputError("a problem must be a JSON object with 'inner' and 'outer'")
    unknown = sorted(set(d) - {"inner", "outer", "method"})
    if unknown:
        raise InvalidInputError(f"field '{unknown[0]}' is not allowed (use inner, outer, method)")
    inner = set_from_dict(json_field(d, "inner", ""), "inner.")
    if not isinstance(inner, Ellipsoid):
        raise InvalidInputError("field 'inner.type': the inner set must be an ellipsoid")
    outer = set_from_dict(json_field(d, "outer", ""), "outer.")
    if outer.dim != inner.dim:
        raise InvalidInputError(
            f"field 'outer': dimension {outer.dim} differs from the inner ellipsoid's {inner.dim}"
        )
    method = None
    if "method" in d:
        method = parse_method(d["method"], "method")
        check_method(method, outer)
    return inner, outer, method
