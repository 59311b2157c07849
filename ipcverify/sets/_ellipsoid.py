"""The ellipsoid: an immutable *batch* of ellipsoids, the contract's output, and an outer set.

An ellipsoid is ``E(c, C) = {y : ||C (y - c)||_2 <= 1}`` with centre ``c`` and a
non-singular shape matrix ``C`` (the paper's convention). With ``P = (C^T C)^{-1}``
the ellipsoid is also ``{c + P^{1/2} u : ||u|| <= 1}``, so its axis-aligned extent
along coordinate ``i`` is ``c_i +/- sqrt(P_ii)`` and its volume is
``vol(unit ball) / |det C|``. As an :class:`~ipcverify.sets.OuterSet` (a batch of one) it is
proved against by the S-lemma (``proof_form`` ``"ellipsoid"``, method ``sdp``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._exact import exact_matrix, exact_vector, matvec, sqnorm
from ipcverify.sets._json import json_field, json_matrix, json_vector
from ipcverify.sets._outer import OuterSet, register_shape

FloatArray = NDArray[np.float64]

#: Reciprocal condition number below which a shape matrix counts as singular.
SINGULAR_RCOND = 1e-12


def unit_ball_log_volume(n: int) -> float:
    """Log of the volume of the unit Euclidean ball in ``n`` dimensions.

    Parameters
    ----------
    n : int
        The dimension (``n = 0`` gives ``log 1 = 0``).

    Examples
    --------
    >>> round(float(np.exp(unit_ball_log_volume(3))), 6)  # 4/3 pi
    4.18879
    """
    from scipy.special import gammaln  # not at the top: importing ipcverify stays light

    return float(0.5 * n * np.log(np.pi) - gammaln(0.5 * n + 1.0))


def _readonly(a: FloatArray) -> FloatArray:
    a.setflags(write=False)
    return a


@register_shape
@dataclass(frozen=True, eq=False)
class Ellipsoid(OuterSet):
    """An immutable batch of ``B`` ellipsoids in ``R^n``.

    Parameters
    ----------
    centers : array_like, shape (B, n) or (n,)
        Centres ``c``. A single centre is promoted to a batch of one.
    shapes : array_like, shape (B, n, n) or (n, n)
        Shape matrices ``C``; ``E = {y : ||C (y - c)|| <= 1}``.

    Raises
    ------
    SetError
        If shapes do not match, an entry is not finite, or a shape matrix is
        singular (reciprocal condition number below ``1e-12``). The message names
        the offending item.

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros(2), np.diag([2.0, 4.0]))  # semi-axes 0.5 and 0.25
    >>> e.extents()[1]
    array([[0.5 , 0.25]])
    >>> bool(e.contains(np.array([0.4, 0.0]))[0])
    True
    """

    kind: ClassVar[str] = "ellipsoid"
    proof_form: ClassVar[str] = "ellipsoid"
    methods: ClassVar[tuple[str, ...]] = ("sdp",)

    centers: FloatArray
    shapes: FloatArray

    def __post_init__(self) -> None:
        c = np.array(self.centers, dtype=np.float64, copy=True)
        s = np.array(self.shapes, dtype=np.float64, copy=True)
        if c.ndim == 1:
            c = c[None, :]
        if s.ndim == 2:
            s = s[None, :, :]
        if c.ndim != 2:
            raise SetError(f"centers must have shape (B, n); got {c.shape}")
        if s.ndim != 3 or s.shape[1] != s.shape[2]:
            raise SetError(f"shapes must have shape (B, n, n); got {s.shape}")
        if s.shape[0] != c.shape[0] or s.shape[1] != c.shape[1]:
            raise SetError(
                f"centers {c.shape} and shapes {s.shape} disagree: expected shapes "
                f"({c.shape[0]}, {c.shape[1]}, {c.shape[1]})"
            )
        if c.shape[1] == 0:
            raise SetError("an ellipsoid needs dimension n >= 1")
        bad_c = ~np.isfinite(c).all(axis=1)
        if bad_c.any():
            i = int(np.flatnonzero(bad_c)[0])
            raise SetError(f"ellipsoid {i}: center has a non-finite entry ({c[i].tolist()})")
        bad_s = ~np.isfinite(s).all(axis=(1, 2))
        if bad_s.any():
            i = int(np.flatnonzero(bad_s)[0])
            raise SetError(f"ellipsoid {i}: shape matrix has a non-finite entry")
        if s.shape[0] > 0:
            sv = np.linalg.svd(s, compute_uv=False)
            rcond = sv[:, -1] / np.maximum(sv[:, 0], np.finfo(float).tiny)
            bad = ~(rcond >= SINGULAR_RCOND)
            if bad.any():
                i = int(np.flatnonzero(bad)[0])
                raise SetError(
                    f"ellipsoid {i}: shape matrix is singular (reciprocal condition number "
                    f"{rcond[i]:.3g} < {SINGULAR_RCOND:g}); an IPC must output a non-singular C"
                )
        object.__setattr__(self, "centers", _readonly(c))
        object.__setattr__(self, "shapes", _readonly(s))

    # ------------------------------------------------------------------ basics
    @property
    def batch_size(self) -> int:
        """Number of ellipsoids ``B``."""
        return int(self.centers.shape[0])

    @property
    def dim(self) -> int:
        """Ambient dimension ``n``."""
        return int(self.centers.shape[1])

    def __len__(self) -> int:
        return self.batch_size

    def __getitem__(self, index: Any) -> Ellipsoid:
        """Select ellipsoids by integer, slice, mask or index array (always a batch)."""
        if isinstance(index, (int, np.integer)):
            index = [int(index)]
        return Ellipsoid(self.centers[index], self.shapes[index])

    def __repr__(self) -> str:
        return f"Ellipsoid(batch_size={self.batch_size}, dim={self.dim})"

    # ----------------------------------------------------------------- algebra
    def _points(self, y: ArrayLike) -> FloatArray:
        p = np.asarray(y, dtype=np.float64)
        if p.ndim == 1:
            p = np.broadcast_to(p, self.centers.shape)
        if p.shape != self.centers.shape:
            raise SetError(f"points must have shape (n,) or (B, n) = {self.centers.shape}; got {p.shape}")
        return p

    def g(self, y: ArrayLike) -> FloatArray:
        """The score ``g = ||C (y - c)||``; ``y`` is inside iff ``g <= 1``.

        Parameters
        ----------
        y : array_like, shape (n,) or (B, n)
            One point per ellipsoid (or one point broadcast to all).
        """
        d = self._points(y) - self.centers
        return np.linalg.norm(np.einsum("bij,bj->bi", self.shapes, d), axis=1)

    def contains(self, y: ArrayLike) -> NDArray[np.bool_]:
        """Boolean mask: ``y_b`` lies in ellipsoid ``b`` (boundary included)."""
        return self.g(y) <= 1.0

    def precision(self) -> FloatArray:
        """``Q = C^T C`` (B, n, n), so that ``E = {y : (y-c)^T Q (y-c) <= 1}``."""
        return np.einsum("bki,bkj->bij", self.shapes, self.shapes)

    def covariance(self) -> FloatArray:
        """``P = (C^T C)^{-1}`` (B, n, n), computed as ``C^{-1} C^{-T}``."""
        cinv = np.linalg.inv(self.shapes)
        return np.einsum("bik,bjk->bij", cinv, cinv)

    def half_widths(self) -> FloatArray:
        """Half the axis-aligned extent per coordinate, ``sqrt(P_ii)`` (B, n).

        ``P_ii`` is the squared norm of row ``i`` of ``C^{-1}``, computed directly.
        """
        cinv = np.linalg.inv(self.shapes)
        return np.sqrt(np.einsum("bij,bij->bi", cinv, cinv))

    def extents(self) -> tuple[FloatArray, FloatArray]:
        """Axis-aligned bounding box ``(lower, upper)``, each (B, n), in closed form."""
        h = self.half_widths()
        return self.centers - h, self.centers + h

    def log_volume(self) -> FloatArray:
        """Natural log of each ellipsoid's volume, ``log vol(B_n) - log|det C|`` (B,)."""
        _, logabsdet = np.linalg.slogdet(self.shapes)
        return unit_ball_log_volume(self.dim) - logabsdet

    def scaled(self, factor: ArrayLike) -> Ellipsoid:
        """The ellipsoid grown by ``factor`` about its centre: ``E(c, C / factor)``.

        Parameters
        ----------
        factor : float or array_like, shape (B,)
            Positive, finite scale factors (``> 1`` grows the set).
        """
        f = np.asarray(factor, dtype=np.float64)
        if f.ndim == 0:
            f = np.full(self.batch_size, float(f))
        if f.shape != (self.batch_size,):
            raise SetError(f"scale factor must be a scalar or shape ({self.batch_size},)")
        if not (np.isfinite(f).all() and (f > 0).all()):
            raise SetError("scale factors must be finite and > 0")
        return Ellipsoid(self.centers, self.shapes / f[:, None, None])

    def boundary_points(self, directions: ArrayLike) -> FloatArray:
        """Map unit directions ``u`` (B, n) to boundary points ``c + C^{-1} u``."""
        u = self._points(directions)
        norms = np.linalg.norm(u, axis=1, keepdims=True)
        if not (norms > 0).all():
            raise SetError("directions must be non-zero")
        u = u / norms
        return self.centers + np.linalg.solve(self.shapes, u[..., None])[..., 0]

    def sample(self, rng: np.random.Generator, surface: bool = False) -> FloatArray:
        """One random point per ellipsoid, uniform in its volume (or on its boundary map).

        Parameters
        ----------
        rng : numpy.random.Generator
            Source of randomness.
        surface : bool
            If true, return points with ``g == 1`` (up to rounding).
        """
        u = rng.standard_normal(self.centers.shape)
        u /= np.linalg.norm(u, axis=1, keepdims=True)
        if not surface:
            u *= rng.random((self.batch_size, 1)) ** (1.0 / self.dim)
        return self.centers + np.linalg.solve(self.shapes, u[..., None])[..., 0]

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form ``{"centers": [[...]], "shapes": [[[...]]]}`` (JSON-ready)."""
        return {"centers": self.centers.tolist(), "shapes": self.shapes.tolist()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Ellipsoid:
        """Inverse of :meth:`to_dict`."""
        try:
            return cls(np.asarray(data["centers"]), np.asarray(data["shapes"]))
        except KeyError as exc:
            raise SetError(f"ellipsoid data lacks the key {exc}") from None

    # ---------------------------------------------------------- as an outer set
    def as_outer(self, what: str) -> Ellipsoid:
        """The ellipsoid itself if it is a batch of one (an outer set is one set)."""
        return single_ellipsoid(self, what)

    def to_set_dict(self) -> dict[str, Any]:
        """JSON form of a single ellipsoid, ``{"type": "ellipsoid", "center": [...], "shape": [[...]]}``."""
        single_ellipsoid(self, "ellipsoid")
        return {"type": "ellipsoid", "center": self.centers[0].tolist(), "shape": self.shapes[0].tolist()}

    @classmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> Ellipsoid:
        """Inverse of :meth:`to_set_dict`; errors name the field."""
        c = json_vector(json_field(d, "center", where), f"{where}center")
        s = json_matrix(json_field(d, "shape", where), f"{where}shape", len(c))
        if len(s) != len(c):
            raise InvalidInputError(
                f"field '{where}shape': expected {len(c)} rows to match the center, got {len(s)}"
            )
        return cls(np.array(c), np.array(s))

    def outside_exact(self, y: Sequence[Fraction]) -> bool:
        """Exactly: ``||C (y - c)||^2 > 1`` for the first ellipsoid of the batch."""
        c, C = exact_vector(self.centers[0]), exact_matrix(self.shapes[0])
        return sqnorm(matvec(C, [a - b for a, b in zip(y, c, strict=True)])) > 1


def single_ellipsoid(e: Ellipsoid, what: str) -> Ellipsoid:
    """``e`` itself if it is an :class:`Ellipsoid` batch of one; else a :class:`SetError` naming ``what``.

    Examples
    --------
    >>> single_ellipsoid(Ellipsoid(np.zeros(2), np.eye(2)), "inner").batch_size
    1
    """
    if not isinstance(e, Ellipsoid):
        raise SetError(f"{what} must be an Ellipsoid; got {type(e).__name__}")
    if e.batch_size != 1:
        raise SetError(
            f"{what} must be a single ellipsoid (batch of 1); got a batch of {e.batch_size}: "
            "use ipcverify.decision.containment.prove_batch for batches"
        )
    return e
