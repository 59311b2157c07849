"""A frozen record whose ``to_dict`` is its fields in order: the one rule for the reproduction's records.

A field that has a ``to_dict`` (a record, a library result) becomes its ``to_dict()``, a tuple a
list, a mapping a dict of the same; anything else is kept as it is. ``summary.json`` is then
written by :func:`ipcverify.data.write_json` (the one JSON encoder).

Examples
--------
>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Interval(Record):
...     lower: float
...     upper: float
>>> @dataclass(frozen=True)
... class Rate(Record):
...     n: int
...     interval: Interval
...     bounds: tuple[float, float]
>>> Rate(3, Interval(0.0, 0.5), (0.1, 0.2)).to_dict()
{'n': 3, 'interval': {'lower': 0.0, 'upper': 0.5}, 'bounds': [0.1, 0.2]}
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

__all__ = ["Record", "plain"]


def plain(value: Any) -> Any:
    """``value`` as :class:`Record` writes a field: ``to_dict()``, lists for tuples, dicts for mappings."""
    to_dict = getattr(value, "to_dict", None)
    if callable(to_dict) and not isinstance(value, type):
        return to_dict()
    if isinstance(value, tuple):
        return [plain(v) for v in value]
    if isinstance(value, Mapping):
        return {k: plain(v) for k, v in value.items()}
    return value


class Record:
    """Base of a frozen dataclass whose :meth:`to_dict` is its fields in order (see the module)."""

    def to_dict(self) -> dict[str, Any]:
        """The fields in order, each as :func:`plain` writes it."""
        return {f.name: plain(getattr(self, f.name)) for f in dataclasses.fields(self)}  # type: ignore[arg-type]
