"""The polyhedron ``{y : A y <= b}``, an outer set given by its faces (the dense face arithmetic)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np

from ipcverify.errors import SetError
from ipcverify.sets._faces import FacedSet, FloatArray, float_array
from ipcverify.sets._json import json_field, json_matrix, json_vector
from ipcverify.sets._outer import register_shape


@register_shape
@dataclass(frozen=True, eq=False)
class Polytope(FacedSet):
    """The polyhedron ``{y : A y <= b}`` (``m >= 1`` closed halfspaces).

    Parameters
    ----------
    A : array_like, shape (m, n)
        Face normals (need not be normalised; a zero row means ``0 <= b_j``).
    b : array_like, shape (m,)
        Offsets.

    Examples
    --------
    >>> Polytope([[1.0, 1.0]], [1.0]).faces()[1]
    array([1.])
    >>> Polytope([[1.0, 1.0]], [1.0]).to_set_dict()
    {'type': 'polytope', 'A': [[1.0, 1.0]], 'b': [1.0]}
    """

    kind: ClassVar[str] = "polytope"

    A: FloatArray
    b: FloatArray

    def __post_init__(self) -> None:
        a = float_array(self.A, 2, "polytope A")
        b = float_array(self.b, 1, "polytope b")
        if a.shape[0] == 0 or a.shape[1] == 0:
            raise SetError(f"polytope A must have shape (m, n) with m, n >= 1; got {a.shape}")
        if b.shape != (a.shape[0],):
            raise SetError(f"polytope b must have shape ({a.shape[0]},) to match A; got {b.shape}")
        object.__setattr__(self, "A", a)
        object.__setattr__(self, "b", b)

    @property
    def dim(self) -> int:
        """Ambient dimension ``n``."""
        return int(self.A.shape[1])

    def faces(self) -> tuple[FloatArray, FloatArray]:
        """``(A, b)``."""
        return self.A, self.b

    def to_set_dict(self) -> dict[str, Any]:
        """``{"type": "polytope", "A": [[...]], "b": [...]}``."""
        return {"type": "polytope", "A": self.A.tolist(), "b": self.b.tolist()}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> Polytope:
        """Inverse of :meth:`to_set_dict`; errors name the field."""
        a = json_matrix(json_field(d, "A", where), f"{where}A")
        b = json_vector(json_field(d, "b", where), f"{where}b", len(a))
        return cls(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
