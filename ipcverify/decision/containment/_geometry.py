"""Exact rational geometry of one ellipsoid against a box, polytope or ellipsoid.

The float data of a set are taken as exact rationals (:mod:`ipcverify.sets._exact`); every
test here is decided without rounding:

* :class:`ExactEllipsoid` -- ``E(c, C)`` with its exact inverse, score and boundary map;
* :func:`exact_faces` / :func:`check_faces` -- the closed form ``E in {A y <= b}`` iff
  ``b_j - a_j^T c >= 0`` and ``(b_j - a_j^T c)^2 >= ||C^{-T} a_j||^2`` for every face;
* :func:`check_lmi` -- the S-lemma certificate ``lam Q1 - Q2 + tau e e^T >= 0``, ``tau <= 1``;
* :func:`is_outside`, :func:`face_witness`, :func:`witness_from_direction` -- exact
  witness points that lie in the inner set and outside the outer one.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> ex = ExactEllipsoid.of(Ellipsoid(np.zeros(2), np.diag([2.0, 4.0])))
>>> check_faces(ex, Box([-0.5, -0.25], [0.5, 0.25]))[0]
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction

from ipcverify.errors import InvalidInputError
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import (
    ExactMatrix,
    ExactVector,
    exact_matrix,
    exact_vector,
    inverse,
    is_positive_definite,
    is_positive_semidefinite,
    matvec,
    sqnorm,
    sqrt_upper,
)
from ipcverify.sets._faces import FacedSet
from ipcverify.sets._outer import OuterSet


@dataclass
class ExactEllipsoid:
    """Exact rational data of one ellipsoid ``E(c, C)``, inverse computed lazily.

    Build it with :meth:`of`; ``cinv`` is the exact ``C^{-1}``.
    """

    c: ExactVector
    C: ExactMatrix
    _ci: ExactMatrix | None = None

    @classmethod
    def of(cls, e: Ellipsoid) -> ExactEllipsoid:
        return cls(exact_vector(e.centers[0]), exact_matrix(e.shapes[0]))

    @property
    def cinv(self) -> ExactMatrix:
        if self._ci is None:
            self._ci = inverse(self.C)
        return self._ci

    def g2(self, y: Sequence[Fraction]) -> Fraction:
        """``||C (y - c)||^2`` exactly."""
        return sqnorm(matvec(self.C, [a - b for a, b in zip(y, self.c, strict=True)]))

    def point(self, u: Sequence[Fraction]) -> ExactVector:
        """``c + C^{-1} u`` exactly (inside iff ``||u|| <= 1``)."""
        return [a + b for a, b in zip(self.c, matvec(self.cinv, u), strict=True)]

    def quadratic_form(self, offset: int) -> ExactMatrix:
        """Homogenised ``||C (y - c)||^2 - offset`` as an (n+1)x(n+1) matrix."""
        n = len(self.c)
        cols = list(zip(*self.C, strict=True))
        a = [
            [sum((x * y for x, y in zip(cols[i], cols[j], strict=True)), Fraction(0)) for j in range(n)]
            for i in range(n)
        ]
        ac = matvec(a, self.c)
        cac = sum((x * y for x, y in zip(self.c, ac, strict=True)), Fraction(0))
        q = [row[:] + [-ac[i]] for i, row in enumerate(a)]
        q.append([-v for v in ac] + [cac - offset])
        return q


@dataclass(frozen=True)
class Face:
    index: int
    a: ExactVector
    b: Fraction
    z: ExactVector  # C^{-T} a
    slack: Fraction  # b - a^T c
    zz: Fraction  # ||z||^2

    @property
    def holds(self) -> bool:
        return self.slack >= 0 and self.slack * self.slack >= self.zz

    @property
    def margin(self) -> float:
        return float(self.slack) - self.support

    @property
    def support(self) -> float:
        """``sqrt(zz)`` in float (``inf`` for a set whose extent is beyond float's range)."""
        try:
            return math.sqrt(float(self.zz))
        except OverflowError:  # zz beyond float's range: its square root may still be a float
            try:
                return float(sqrt_upper(self.zz, 64))
            except OverflowError:
                return math.inf


def exact_faces(ex: ExactEllipsoid, outer: FacedSet) -> list[Face]:
    """Every face of ``outer`` with its exact slack and ``||C^{-T} a||^2`` (the shape's ``exact_faces``)."""
    return [Face(j, *face) for j, face in enumerate(outer.exact_faces(ex.c, ex.cinv))]


def is_outside(outer: OuterSet, y: Sequence[Fraction]) -> bool:
    """Exactly: ``y`` is not in ``outer`` (:meth:`~ipcverify.sets.OuterSet.outside_exact`)."""
    return outer.outside_exact(y)


def _as_float_witness(ex: ExactEllipsoid, outer: OuterSet, y: Sequence[Fraction]) -> ExactVector | None:
    """The witness rounded to floats, if it still checks exactly (nicer to read; None beyond range)."""
    try:
        yf = [Fraction(float(v)) for v in y]
    except OverflowError:
        return None
    if ex.g2(yf) <= 1 and is_outside(outer, yf):
        return yf
    return None


def witness_from_direction(
    ex: ExactEllipsoid, outer: OuterSet, u: Sequence[Fraction], *, boundary: bool = False
) -> ExactVector | None:
    """``c + C^{-1} u`` pulled exactly into the inner ellipsoid; returned if outside ``outer``.

    ``boundary=True`` first scales any non-zero ``u`` to just inside the unit sphere
    (``u / r`` with a rational ``r >= ||u||`` within ``2^-64`` relative), so the point lies on
    the boundary of the inner set up to that: the farthest point along ``u``.
    """
    uu = sqnorm(u)
    if uu > 1 or (boundary and uu > 0):
        r = sqrt_upper(uu, 64)
        u = [v / r for v in u]
    y = ex.point(u)
    if not is_outside(outer, y):
        return None
    return _as_float_witness(ex, outer, y) or y


def face_witness(ex: ExactEllipsoid, outer: FacedSet, face: Face) -> ExactVector | None:
    """Exact witness for a violated face: the maximiser of ``a^T y`` over ``E``, pulled inside."""
    if face.zz == 0:
        y = list(ex.c)
        return y if is_outside(outer, y) else None
    for bits in (64, 128, 256, 1024, 4096):
        r = sqrt_upper(face.zz, bits)  # r >= ||z||, so u = z / r is in the unit ball
        if face.zz / r > face.slack:  # a^T y - b = ||z||^2 / r - slack > 0
            u = [v / r for v in face.z]
            y = ex.point(u)
            if is_outside(outer, y):
                return _as_float_witness(ex, outer, y) or y
    return None


def check_faces(ex: ExactEllipsoid, outer: FacedSet) -> tuple[bool, str]:
    try:
        faces = exact_faces(ex, outer)
    except InvalidInputError as exc:
        return False, f"exact inverse failed: {exc}"
    for f in faces:
        if f.slack < 0:
            return False, f"face {f.index}: b - a^T c < 0 exactly (the centre is outside)"
        if f.slack * f.slack < f.zz:
            return False, f"face {f.index}: (b - a^T c)^2 < ||C^-T a||^2 exactly"
    return (
        True,
        f"all {len(faces)} faces satisfy b - a^T c >= 0 and (b - a^T c)^2 >= ||C^-T a||^2 exactly",
    )


def _lmi(q1: ExactMatrix, q2: ExactMatrix, lam: Fraction, tau: Fraction) -> ExactMatrix:
    n1 = len(q1)
    m = [[lam * q1[i][j] - q2[i][j] for j in range(n1)] for i in range(n1)]
    m[-1][-1] += tau
    return m


def check_lmi(q1: ExactMatrix, q2: ExactMatrix, lam: Fraction, tau: Fraction) -> tuple[bool, str]:
    if lam < 0:
        return False, "lambda < 0"
    if tau > 1:
        return False, f"tau = {float(tau)!r} > 1"
    m = _lmi(q1, q2, lam, tau)
    if is_positive_definite(m):
        return True, "lam Q1 - Q2 + tau e e^T is positive definite (exact LDL^T, all pivots > 0)"
    if is_positive_semidefinite(m):
        return True, "lam Q1 - Q2 + tau e e^T is positive semidefinite (exact pivoted elimination)"
    return False, "lam Q1 - Q2 + tau e e^T is not positive semidefinite (exact)"
