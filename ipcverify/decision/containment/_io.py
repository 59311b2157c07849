"""The JSON formats of sets and containment problems (``docs/containment.md``).

Floats round-trip exactly through :mod:`json` (it writes ``repr``). Every parse error is
an :class:`~ipcverify.errors.InvalidInputError` naming the offending field. Each shape writes
and reads its own form (:meth:`~ipcverify.sets.OuterSet.to_set_dict`,
:meth:`~ipcverify.sets.OuterSet.from_set_dict`); the ``"type"`` field picks the shape among the
registered ones (:func:`~ipcverify.sets.register_shape`).

Examples
--------
>>> from ipcverify.sets import Box
>>> set_from_dict(set_to_dict(Box([0.0], [1.0]))).upper
array([1.])
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any

from ipcverify.decision.containment._status import Method, check_method, parse_method
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._json import json_field
from ipcverify.sets._outer import OuterSet, registered_shapes


def set_to_dict(s: OuterSet) -> dict[str, Any]:
    """JSON-ready form of a single set (floats round-trip exactly through :mod:`json`).

    Parameters
    ----------
    s : OuterSet
        A Box, Polytope or Ellipsoid (or another registered shape); anything else raises
        :class:`SetError`.

    Examples
    --------
    >>> from ipcverify.sets import Box
    >>> set_to_dict(Box([0.0], [1.0]))
    {'type': 'box', 'lower': [0.0], 'upper': [1.0]}
    """
    if not isinstance(s, OuterSet):
        raise SetError(
            f"cannot serialise an object of type {type(s).__name__}; expected Box, Polytope or Ellipsoid"
        )
    return s.to_set_dict()


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
    shapes = registered_shapes()
    shape = shapes.get(kind) if isinstance(kind, str) else None
    if shape is None:
        names = ", ".join(f"'{k}'" for k in shapes)
        raise InvalidInputError(f"field '{where}type': {json.dumps(kind)[:40]} is not one of {names}")
    try:
        return shape.from_set_dict(d, where)
    except SetError as exc:
        raise SetError(f"field '{where.rstrip('.') or 'set'}': {exc}") from None


def problem_from_dict(d: Any) -> tuple[Ellipsoid, OuterSet, Method | None]:
    """Parse one problem ``{"inner": ELLIPSOID, "outer": SET, "method"?: str}``.

    Parameters
    ----------
    d : mapping
        The problem's JSON object. The inner set must be an ellipsoid of the outer set's
        dimension; ``method`` is optional (None is returned without it) and must suit the
        outer set. Anything else raises :class:`InvalidInputError` naming the field.

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
