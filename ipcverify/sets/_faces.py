"""Sets given by faces, ``{y : A y <= b}``: the face form and its arithmetic against an ellipsoid.

:class:`FacedSet` is the :class:`~ipcverify.sets.OuterSet` of every shape with faces. A shape
gives its faces (:meth:`FacedSet.faces`); the arithmetic the provers need has a default here,
for faces as a dense matrix, which a shape may replace by a faster or tighter one of its own
(:class:`~ipcverify.sets.Box` does, for its axis-aligned faces). For ``E(c, C)`` and face
``a^T y <= b``, ``max_{y in E} a^T y = a^T c + ||C^{-T} a||``, so every method computes a piece
of the face's slack ``b - a^T c - ||C^{-T} a||`` (``proofs/containment.md``):

* :meth:`~FacedSet.face_offsets` -- ``b - A c`` in float;
* :meth:`~FacedSet.support_slack` -- the float slacks of a batch (not a proof);
* :meth:`~FacedSet.slack_terms` -- the pieces of the slack with rigorous bounds on their
  rounding errors (``proofs/float_landing.md``, part II), for
  :func:`~ipcverify.decision.containment.support_slack_bounds`;
* :meth:`~FacedSet.exact_faces` and :meth:`~FacedSet.outside_exact` -- the same in exact
  rational arithmetic.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Polytope
>>> p = Polytope([[1.0, 0.0], [0.0, 1.0]], [1.0, 2.0])
>>> p.face_offsets(np.array([0.5, 0.5])).tolist()
[0.5, 1.5]
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from fractions import Fraction
from typing import Any, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import ExactMatrix, ExactVector, exact_matrix, exact_vector, sqnorm
from ipcverify.sets._outer import OuterSet

FloatArray = NDArray[np.float64]
#: One exact face: ``(a, b, z, s, zz)`` with ``z = C^{-T} a``, ``s = b - a^T c``, ``zz = ||z||^2``.
ExactFace = tuple[ExactVector, Fraction, ExactVector, Fraction, Fraction]

#: The unit roundoff of float64, ``2^-53``.
UNIT_ROUNDOFF = 2.0**-53
#: Absolute allowance for every underflow of the rounding analysis (far above its size).
UNDERFLOW_ALLOWANCE = 2.0**-520


def gamma(k: int) -> float:
    """A float at least ``gamma_k = k u / (1 - k u)`` (and its own rounding), for ``k u < 0.01``."""
    return 1.02 * k * UNIT_ROUNDOFF


class FacedSet(OuterSet):
    """An outer set ``{y : A y <= b}`` given by its faces (see the module docstring).

    A subclass sets :attr:`~ipcverify.sets.OuterSet.kind` and gives :meth:`faces`,
    ``dim``, ``to_set_dict`` and ``from_set_dict``; the other methods default to the dense
    arithmetic on ``faces()``.
    """

    proof_form: ClassVar[str] = "faces"
    methods: ClassVar[tuple[str, ...]] = ("closed-form", "socp", "sdp")

    @abstractmethod
    def faces(self) -> tuple[FloatArray, FloatArray]:
        """``(A, b)`` with the set ``= {y : A y <= b}``, shapes (m, n) and (m,); the order of the faces."""

    def face_offsets(self, c: FloatArray) -> FloatArray:
        """Float ``b - A c`` per face, for one centre (n,) -> (m,) or a batch (B, n) -> (B, m)."""
        a, b = self.faces()
        return np.asarray(b - a @ c if c.ndim == 1 else b - c @ a.T)

    def support_slack(self, inner: Ellipsoid) -> FloatArray:
        """Float slacks ``b_j - a_j^T c - ||C^{-T} a_j||`` of a batch of ellipsoids, shape (B, m)."""
        a, _ = self.faces()
        cinv = np.linalg.inv(inner.shapes)
        z = np.einsum("bki,jk->bji", cinv, a)  # C^{-T} a_j
        return self.face_offsets(inner.centers) - np.linalg.norm(z, axis=2)  # type: ignore[no-any-return]

    def slack_terms(self, c: FloatArray, X: FloatArray) -> tuple[FloatArray, Any, FloatArray, Any]:
        """The pieces of the slack of a batch, each with a bound on its rounding error.

        Parameters
        ----------
        c : ndarray, shape (B, n)
            Centres.
        X : ndarray, shape (B, n, n)
            Float approximations of ``C^{-1}``.

        Returns
        -------
        (sigma, e_sigma, s_hat, e_v)
            ``sigma ~ b - A c`` with ``|error| <= e_sigma``, and ``s_hat ~ ||X^T a_j||`` computed from
            ``X^T a_j``, whose rounding is at most ``e_v`` in norm (both (B, m), or a scalar bound).
        """
        A, b = self.faces()
        n = c.shape[1]
        V = np.einsum("bki,jk->bji", X, A)  # X^T a_j
        s_hat = np.sqrt(np.einsum("bji,bji->bj", V, V))
        W = np.einsum("bki,jk->bji", np.abs(X), np.abs(A))  # |X|^T |a_j|: bounds the rounding of X^T a_j
        e_v = gamma(n + 2) * np.sqrt(np.einsum("bji,bji->bj", W, W)) + UNDERFLOW_ALLOWANCE
        sigma = b - c @ A.T
        e_sigma = gamma(n + 3) * (np.abs(b) + np.abs(c) @ np.abs(A).T) + UNDERFLOW_ALLOWANCE
        return sigma, e_sigma, s_hat, e_v

    def exact_faces(self, c: ExactVector, cinv: ExactMatrix) -> list[ExactFace]:
        """Every face ``(a, b, C^{-T} a, b - a^T c, ||C^{-T} a||^2)`` exactly, given ``c`` and ``C^{-1}``."""
        a_mat, b_vec = self.faces()
        n = len(c)
        out: list[ExactFace] = []
        for a, bj in zip(exact_matrix(a_mat), exact_vector(b_vec), strict=True):
            # C^{-T} a = sum_k a_k * (row k of C^{-1})
            z = [sum((ak * cinv[k][i] for k, ak in enumerate(a) if ak), Fraction(0)) for i in range(n)]
            ac = sum((x * y for x, y in zip(a, c, strict=True)), Fraction(0))
            out.append((a, bj, z, bj - ac, sqnorm(z)))
        return out

    def outside_exact(self, y: Sequence[Fraction]) -> bool:
        """Exactly: ``a_j^T y > b_j`` for some face."""
        a_mat, b_vec = self.faces()
        return any(
            sum((x * v for x, v in zip(a, y, strict=True)), Fraction(0)) > bj
            for a, bj in zip(exact_matrix(a_mat), exact_vector(b_vec), strict=True)
        )

    @classmethod
    @abstractmethod
    def from_set_dict(cls, d: Mapping[str, Any], where: str) -> FacedSet:
        """Inverse of :meth:`to_set_dict`."""


def float_array(values: ArrayLike, ndim: int, what: str) -> FloatArray:
    """``values`` as a read-only finite float64 array of ``ndim`` dimensions.

    Raises a :class:`~ipcverify.errors.SetError` naming ``what`` otherwise.
    """
    try:
        a = np.array(values, dtype=np.float64, copy=True)
    except (TypeError, ValueError) as exc:
        raise SetError(f"{what} must be an array of numbers ({exc})") from None
    if a.ndim != ndim:
        raise SetError(f"{what} must be {ndim}-D; got shape {a.shape}")
    if not np.isfinite(a).all():
        raise SetError(f"{what} has a non-finite entry; use finite numbers")
    a.setflags(write=False)
    return a
