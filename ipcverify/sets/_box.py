"""The axis-aligned box, an outer set with ``2n`` faces ``y_i <= upper_i`` and ``-y_i <= -lower_i``.

Its faces are signed unit vectors, so its face arithmetic is simpler (and its rounding bounds
tighter) than the dense default of :class:`~ipcverify.sets.FacedSet`: ``C^{-T} e_i`` is row
``i`` of ``C^{-1}``, and ``b - a^T c`` is ``upper_i - c_i`` or ``c_i - lower_i``, one rounding.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, ClassVar

import numpy as np

from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import ExactMatrix, ExactVector, exact_vector, sqnorm
from ipcverify.sets._faces import UNIT_ROUNDOFF, ExactFace, FacedSet, FloatArray, float_array
from ipcverify.sets._json import json_field, json_vector
from ipcverify.sets._outer import register_shape


@register_shape
@dataclass(frozen=True, eq=False)
class Box(FacedSet):
    """The axis-aligned box ``{y : lower <= y <= upper}`` (closed).

    Parameters
    ----------
    lower, upper : array_like, shape (n,)
        Finite bounds with ``lower <= upper``.

    Examples
    --------
    >>> Box([-1.0, 0.0], [1.0, 2.0]).dim
    2
    >>> Box([0.0], [1.0]).to_set_dict()
    {'type': 'box', 'lower': [0.0], 'upper': [1.0]}
    """

    kind: ClassVar[str] = "box"

    lower: FloatArray
    upper: FloatArray

    def __post_init__(self) -> None:
        lo = float_array(self.lower, 1, "box lower")
        up = float_array(self.upper, 1, "box upper")
        if lo.shape != up.shape or lo.size == 0:
            raise SetError(f"box lower {lo.shape} and upper {up.shape} must both have shape (n,), n >= 1")
        if not (lo <= up).all():
            i = int(np.flatnonzero(~(lo <= up))[0])
            raise SetError(
                f"box coordinate {i}: lower {float(lo[i])!r} > upper {float(up[i])!r}; swap them or widen "
                "the box"
            )
        object.__setattr__(self, "lower", lo)
        object.__setattr__(self, "upper", up)

    @property
    def dim(self) -> int:
        """Ambient dimension ``n``."""
        return int(self.lower.shape[0])

    def faces(self) -> tuple[FloatArray, FloatArray]:
        """``(A, b)`` with the box ``= {y : A y <= b}``: rows ``e_i`` then ``-e_i``."""
        eye = np.eye(self.dim)
        return np.vstack([eye, -eye]), np.concatenate([self.upper, -self.lower])

    def to_set_dict(self) -> dict[str, Any]:
        """``{"type": "box", "lower": [...], "upper": [...]}``."""
        return {"type": "box", "lower": self.lower.tolist(), "upper": self.upper.tolist()}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> Box:
        """Inverse of :meth:`to_set_dict`; errors name the field."""
        lo = json_vector(json_field(d, "lower", where), f"{where}lower")
        up = json_vector(json_field(d, "upper", where), f"{where}upper", len(lo))
        return cls(np.asarray(lo, dtype=np.float64), np.asarray(up, dtype=np.float64))

    def face_offsets(self, c: FloatArray) -> FloatArray:
        """``upper - c``, then ``c - lower`` (one rounding each), for (n,) or (B, n) centres."""
        return np.concatenate([self.upper - c, c - self.lower], axis=-1)

    def support_slack(self, inner: Ellipsoid) -> FloatArray:
        """Float slacks from the half-widths ``h``: ``upper - c - h``, then ``c - h - lower``."""
        h = inner.half_widths()
        return np.concatenate([self.upper - inner.centers - h, inner.centers - h - self.lower], axis=1)

    def slack_terms(self, c: FloatArray, X: FloatArray) -> tuple[FloatArray, Any, FloatArray, Any]:
        """:meth:`FacedSet.slack_terms` for ``a = +-e_i``: ``X^T a`` is row ``i`` of ``X``, exactly."""
        s_hat = np.sqrt(np.einsum("bij,bij->bi", X, X))
        sigma = self.face_offsets(c)
        return sigma, UNIT_ROUNDOFF * np.abs(sigma), np.concatenate([s_hat, s_hat], axis=1), 0.0

    def exact_faces(self, c: ExactVector, cinv: ExactMatrix) -> list[ExactFace]:
        """The faces ``e_i`` then ``-e_i`` exactly: ``C^{-T} e_i`` is row ``i`` of ``C^{-1}``."""
        n = self.dim
        up, lo = exact_vector(self.upper), exact_vector(self.lower)
        rows = [cinv[i] for i in range(n)]
        norms = [sqnorm(r) for r in rows]
        out: list[ExactFace] = []
        for i in range(n):
            e = [Fraction(int(k == i)) for k in range(n)]
            out.append((e, up[i], rows[i], up[i] - c[i], norms[i]))
        for i in range(n):
            e = [Fraction(-int(k == i)) for k in range(n)]
            out.append((e, -lo[i], [-v for v in rows[i]], c[i] - lo[i], norms[i]))
        return out

    def outside_exact(self, y: Sequence[Fraction]) -> bool:
        """Exactly: some coordinate lies below ``lower`` or above ``upper``."""
        lo, up = exact_vector(self.lower), exact_vector(self.upper)
        return any(v < lo_i or v > up_i for v, lo_i, up_i in zip(y, lo, up, strict=True))
