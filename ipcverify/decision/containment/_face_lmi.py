"""The S-lemma certificate of an ellipsoid in a half-space, checked in exact integer arithmetic.

For ``E = E(c, C)`` with ``A = C^T C``, a face ``a^T y <= b`` with slack ``s = b - a^T c``,
and a multiplier ``lam``, let

    ``M(lam) = [[lam A, -a/2], [-a^T/2, s - lam]]``    (size ``n + 1``).

With ``v = y - c``, ``(v, 1)^T M(lam) (v, 1) = lam (||C (y - c)||^2 - 1) + b - a^T y``, so
``lam >= 0`` and ``M(lam) >= 0`` prove ``a^T y <= b`` on all of ``E`` (the S-lemma for a
half-space, ``proofs/containment.md`` section 3). Feasible multipliers form the interval with
endpoints ``(s -+ sqrt(s^2 - ||C^{-T} a||^2)) / 2``, centred at :func:`face_centre` ``= s / 2``.

Every finite float is a dyadic rational ``m 2^e``, so ``M(lam)`` times a positive number is an
integer matrix; :func:`check_face_lmis` decides its definiteness with fraction-free
elimination (:func:`integer_definiteness`) on Python integers, exactly, and falls back to the
pivoted rational test of :mod:`ipcverify.sets._exact` only when a leading minor is zero.

Examples
--------
>>> import numpy as np
>>> from fractions import Fraction
>>> from ipcverify.sets import Box, Ellipsoid
>>> disc = Ellipsoid(np.zeros(2), np.eye(2))
>>> box = Box([-1.0, -1.0], [1.0, 1.0])
>>> check_face_lmis(disc, box, [Fraction(1, 2)] * 4)[0]      # the touching box: lam = s / 2
True
>>> check_face_lmis(disc, box, [Fraction(1, 3)] * 4)[0]      # any other lam fails when touching
False
"""

from __future__ import annotations

from collections.abc import Sequence
from fractions import Fraction

from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import dyadic, is_positive_semidefinite
from ipcverify.sets._faces import FacedSet

IntMatrix = list[list[int]]


def integer_definiteness(m: IntMatrix) -> bool | None:
    """Exact definiteness of a symmetric integer matrix by fraction-free elimination (Bareiss).

    After step ``k`` the pivot ``m[k][k]`` equals the leading ``(k+1) x (k+1)`` principal minor
    (every division is exact), so by Sylvester's criterion the matrix is positive definite iff
    every pivot is positive. Only the lower triangle is read.

    Returns
    -------
    bool or None
        True: positive definite. False: a leading principal minor is negative, so the matrix
        is not positive semidefinite. None: the first non-positive minor is zero (undecided
        here; use a pivoted test).

    Examples
    --------
    >>> integer_definiteness([[2, 1], [1, 2]]), integer_definiteness([[1, 2], [2, 1]])
    (True, False)
    >>> integer_definiteness([[1, 1], [1, 1]]) is None
    True
    """
    a = [list(row) for row in m]
    n = len(a)
    prev = 1
    for k in range(n):
        p = a[k][k]
        if p <= 0:
            return None if p == 0 else False
        col = [a[i][k] for i in range(n)]
        for i in range(k + 1, n):
            row = a[i]
            for j in range(k + 1, i + 1):
                row[j] = (row[j] * p - col[i] * col[j]) // prev
        prev = p
    return True


def _scaled(value: int, exp: int, low: int) -> int:
    return value << (exp - low)


class FaceSystem:
    """The exact data of one ellipsoid against the faces of a box or polytope, as integers.

    ``C`` and ``c`` are written ``Ci 2^e`` and ``ci 2^e`` (one exponent, :func:`ipcverify.sets.dyadic`);
    each face ``(a, b)`` as ``ai 2^f``, ``bi 2^f``. Then ``A = Ci^T Ci 4^e`` and
    ``s = bi 2^f - (ai . ci) 2^(e+f)`` exactly.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid.
    outer : Box or Polytope
        Faces in the order of ``outer.faces()`` (a box: upper faces, then lower).
    """

    def __init__(self, inner: Ellipsoid, outer: FacedSet) -> None:
        c, C = inner.centers[0], inner.shapes[0]
        n = c.shape[0]
        ints, self._e = dyadic([*C.ravel().tolist(), *c.tolist()])
        rows = [ints[i * n : (i + 1) * n] for i in range(n)]
        self._ci = ints[n * n :]
        cols = list(zip(*rows, strict=True))
        self._a = [
            [sum(x * y for x, y in zip(cols[i], cols[j], strict=True)) for j in range(n)] for i in range(n)
        ]
        a_mat, b_vec = outer.faces()
        self._faces = []
        for a, b in zip(a_mat.tolist(), b_vec.tolist(), strict=True):
            fi, f = dyadic([*a, b])
            self._faces.append((fi[:-1], fi[-1], f))
        self.n = n

    def __len__(self) -> int:
        return len(self._faces)

    def slack(self, j: int) -> Fraction:
        """``s_j = b_j - a_j^T c`` exactly."""
        ai, bi, f = self._faces[j]
        e = self._e
        dot = sum(x * y for x, y in zip(ai, self._ci, strict=True))
        return Fraction(bi) * Fraction(2) ** f - Fraction(dot) * Fraction(2) ** (e + f)

    def matrix(self, j: int, lam: Fraction) -> IntMatrix:
        """``q 2^-E M_j(lam)`` as integers (``q`` the denominator of ``lam``, ``2^E`` the finest scale)."""
        ai, bi, f = self._faces[j]
        e, n = self._e, self.n
        p, q = lam.numerator, lam.denominator
        dot = sum(x * y for x, y in zip(ai, self._ci, strict=True))
        # entries times q: lam A -> p Ai 4^e;  -a/2 -> -q ai 2^(f-1);  s - lam -> q (bi 2^f - dot 2^(e+f)) - p
        low = min(2 * e, f - 1, e + f, 0)
        top = [[_scaled(p * x, 2 * e, low) for x in row] for row in self._a]
        side = [_scaled(-q * x, f - 1, low) for x in ai]
        corner = _scaled(q * bi, f, low) - _scaled(q * dot, e + f, low) - _scaled(p, 0, low)
        out = [top[i] + [side[i]] for i in range(n)]
        out.append([*side, corner])
        return out

    def check(self, j: int, lam: Fraction) -> tuple[bool, str]:
        """Exactly: ``lam >= 0`` and ``M_j(lam) >= 0``; with the reason."""
        if lam < 0:
            return False, f"face {j}: lambda < 0"
        m = self.matrix(j, lam)
        verdict = integer_definiteness(m)
        if verdict:
            return True, "positive definite"
        if verdict is None and is_positive_semidefinite([[Fraction(v) for v in row] for row in m]):
            return True, "positive semidefinite"
        return False, f"face {j}: M(lambda) is not positive semidefinite (exact)"


def face_centre(system: FaceSystem, j: int) -> Fraction:
    """``s_j / 2``: the centre of face ``j``'s interval of feasible multipliers (exact).

    Parameters
    ----------
    system : FaceSystem
        The exact data of one ellipsoid against the faces of a box or polytope.
    j : int
        The face's index, in the order of ``outer.faces()``.
    """
    return system.slack(j) / 2


def check_face_lmis(inner: Ellipsoid, outer: FacedSet, lambdas: Sequence[Fraction]) -> tuple[bool, str]:
    """Exactly: ``lam_j >= 0`` and ``M_j(lam_j) >= 0`` for every face ``j``, i.e. ``inner ⊆ outer``.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid.
    outer : Box or Polytope
        The outer set; faces in the order of ``outer.faces()``.
    lambdas : sequence of Fraction
        One multiplier per face.

    Returns
    -------
    (bool, str)
        Whether every face certificate holds, and why (the first failing face).
    """
    system = FaceSystem(inner, outer)
    if len(lambdas) != len(system):
        return False, f"{len(lambdas)} multipliers for {len(system)} faces"
    kinds: set[str] = set()
    for j, lam in enumerate(lambdas):
        ok, how = system.check(j, Fraction(lam))
        if not ok:
            return False, how
        kinds.add(how)
    how = "positive definite" if kinds == {"positive definite"} else "positive semidefinite"
    return (
        True,
        f"all {len(system)} face LMIs [[lam_j A, -a_j/2], [-a_j^T/2, b_j - a_j^T c - lam_j]] are {how} "
        "(exact integer elimination), lam_j >= 0",
    )
