"""Exact rational arithmetic for re-checking containment certificates.

Every finite binary64 float is a rational number, and :class:`fractions.Fraction`
converts it without rounding. The helpers here take float data *as those exact
rationals* and never round: matrix products, inverses and the definiteness tests
below are exact, so a certificate that passes them is a proof about the float data
as written (no tolerance anywhere). Only :func:`float_up` and :func:`float_down`
leave the rationals, and they round in a stated direction.

Matrices are lists of lists of :class:`~fractions.Fraction` (row-major); they are
small (``n + 1 <= ~10`` in practice), so plain Python is fast enough (a 4x4 test
takes well under a millisecond).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from fractions import Fraction
from itertools import repeat

import numpy as np
from numpy.typing import ArrayLike

from ipcverify.errors import InvalidInputError

ExactVector = list[Fraction]
ExactMatrix = list[list[Fraction]]

_ZERO = Fraction(0)
#: :func:`dyadic` tries the exponents ``-100`` and then ``-200`` (small integers, cheap arithmetic).
_DYADIC_SCALES = ((100, 2.0**100), (200, 2.0**200))


def _check_finite(values: np.ndarray, what: str) -> None:
    if not np.isfinite(values).all():
        raise InvalidInputError(f"{what} has a non-finite entry; exact arithmetic needs finite floats")


def exact_vector(values: ArrayLike) -> ExactVector:
    """The exact rationals of a 1-D float array.

    Parameters
    ----------
    values : array_like, shape (n,)
        Finite numbers (converted to float64 first); another shape or a non-finite entry
        raises :class:`InvalidInputError`.

    Examples
    --------
    >>> exact_vector([0.5, 0.1])[1]
    Fraction(3602879701896397, 36028797018963968)
    """
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 1:
        raise InvalidInputError(f"expected a 1-D array; got shape {a.shape}")
    _check_finite(a, "vector")
    return [Fraction(float(v)) for v in a]


def exact_matrix(values: ArrayLike) -> ExactMatrix:
    """The exact rationals of a 2-D float array (list of rows).

    Examples
    --------
    >>> exact_matrix([[1.0, 0.5]])
    [[Fraction(1, 1), Fraction(1, 2)]]
    """
    a = np.asarray(values, dtype=np.float64)
    if a.ndim != 2:
        raise InvalidInputError(f"expected a 2-D array; got shape {a.shape}")
    _check_finite(a, "matrix")
    return [[Fraction(float(v)) for v in row] for row in a]


def matvec(m: Sequence[Sequence[Fraction]], v: Sequence[Fraction]) -> ExactVector:
    """Exact ``m @ v``.

    Examples
    --------
    >>> matvec([[Fraction(1), Fraction(2)]], [Fraction(3), Fraction(4)])
    [Fraction(11, 1)]
    """
    return [sum((a * b for a, b in zip(row, v, strict=True)), _ZERO) for row in m]


def matmul(a: Sequence[Sequence[Fraction]], b: Sequence[Sequence[Fraction]]) -> ExactMatrix:
    """Exact ``a @ b``.

    Parameters
    ----------
    a, b : sequence of sequences of Fraction
        Matrices as lists of rows, ``(p, q)`` and ``(q, r)``; mismatched sizes raise
        :class:`ValueError`.

    Examples
    --------
    >>> matmul([[Fraction(2)]], [[Fraction(3)]])
    [[Fraction(6, 1)]]
    """
    cols = list(zip(*b, strict=True))
    return [[sum((x * y for x, y in zip(row, col, strict=True)), _ZERO) for col in cols] for row in a]


def sqnorm(v: Iterable[Fraction]) -> Fraction:
    """Exact squared Euclidean norm.

    Examples
    --------
    >>> sqnorm([Fraction(3), Fraction(4)])
    Fraction(25, 1)
    """
    return sum((x * x for x in v), _ZERO)


def inverse(m: Sequence[Sequence[Fraction]]) -> ExactMatrix:
    """Exact inverse by Gauss-Jordan elimination (any non-zero pivot is exact).

    Parameters
    ----------
    m : sequence of sequences of Fraction
        A square matrix as a list of rows.

    Raises
    ------
    InvalidInputError
        If the matrix is not square or is exactly singular.

    Examples
    --------
    >>> inverse([[Fraction(2), Fraction(0)], [Fraction(0), Fraction(4)]])
    [[Fraction(1, 2), Fraction(0, 1)], [Fraction(0, 1), Fraction(1, 4)]]
    """
    n = len(m)
    if any(len(row) != n for row in m):
        raise InvalidInputError("inverse needs a square matrix")
    aug = [list(row) + [Fraction(int(i == j)) for j in range(n)] for i, row in enumerate(m)]
    for col in range(n):
        piv = next((r for r in range(col, n) if aug[r][col] != 0), None)
        if piv is None:
            raise InvalidInputError("matrix is exactly singular; a shape matrix must be invertible")
        if piv != col:
            aug[col], aug[piv] = aug[piv], aug[col]
        prow = aug[col]
        inv_p = 1 / prow[col]
        prow[:] = [x * inv_p for x in prow]
        for r in range(n):
            if r != col:
                f = aug[r][col]
                if f != 0:
                    row = aug[r]
                    aug[r] = [x - f * y for x, y in zip(row, prow, strict=True)]
    return [row[n:] for row in aug]


def is_positive_definite(m: Sequence[Sequence[Fraction]]) -> bool:
    """Exact test that a symmetric matrix is positive definite.

    Plain ``L D L^T`` without pivoting: a symmetric matrix is positive definite iff
    every pivot is positive (equivalently, every leading principal minor is), so the
    first non-positive pivot ends the test with ``False``. Only the lower triangle
    and the diagonal are read; the caller must pass a symmetric matrix.

    Examples
    --------
    >>> F = Fraction
    >>> is_positive_definite([[F(2), F(1)], [F(1), F(2)]])
    True
    >>> is_positive_definite([[F(1), F(1)], [F(1), F(1)]])
    False
    """
    a = [list(row) for row in m]
    n = len(a)
    for k in range(n):
        p = a[k][k]
        if p <= 0:
            return False
        col = [a[i][k] for i in range(k + 1, n)]
        for ii, i in enumerate(range(k + 1, n)):
            f = col[ii] / p
            if f != 0:
                row = a[i]
                for jj, j in enumerate(range(k + 1, i + 1)):
                    row[j] -= f * col[jj]
    return True


def is_positive_semidefinite(m: Sequence[Sequence[Fraction]]) -> bool:
    """Exact test that a symmetric matrix is positive semidefinite.

    Symmetric elimination with diagonal pivoting. For a PSD matrix ``M``:
    a negative diagonal entry is impossible; a zero diagonal entry ``M_ii`` forces
    row ``i`` to vanish (else a 2x2 principal minor is negative), so that row and
    column can be dropped; and for ``M_pp > 0`` the matrix is PSD iff the Schur
    complement of ``M_pp`` is. Each step is exact, so the answer is exact.

    Examples
    --------
    >>> F = Fraction
    >>> is_positive_semidefinite([[F(1), F(1)], [F(1), F(1)]])
    True
    >>> is_positive_semidefinite([[F(0), F(1)], [F(1), F(0)]])
    False
    """
    a = [list(row) for row in m]
    while a:
        n = len(a)
        diag = [a[i][i] for i in range(n)]
        if any(d < 0 for d in diag):
            return False
        zero = [i for i in range(n) if diag[i] == 0]
        if zero:
            i = zero[0]
            if any(a[i][j] != 0 for j in range(n)):
                return False
            a = [[a[r][c] for c in range(n) if c != i] for r in range(n) if r != i]
            continue
        p = max(range(n), key=lambda i: diag[i])
        piv = a[p][p]
        keep = [i for i in range(n) if i != p]
        a = [[a[r][c] - a[r][p] * a[p][c] / piv for c in keep] for r in keep]
    return True


def _sqrt_bounds(q: Fraction, bits: int) -> tuple[Fraction, Fraction]:
    if q < 0:
        raise InvalidInputError("square root of a negative number")
    scale = 1 << bits
    num, den = q.numerator, q.denominator
    # sqrt(num/den) = sqrt(num*den)/den; s <= sqrt(num*den*scale^2) < s + 1
    s = math.isqrt(num * den * scale * scale)
    lo = Fraction(s, den * scale)
    hi = lo if s * s == num * den * scale * scale else Fraction(s + 1, den * scale)
    return lo, hi


def sqrt_lower(q: Fraction, bits: int = 64) -> Fraction:
    """A rational ``r`` with ``r <= sqrt(q)`` and ``sqrt(q) - r <= 2**-bits / den(q)``.

    Examples
    --------
    >>> sqrt_lower(Fraction(4))
    Fraction(2, 1)
    >>> sqrt_lower(Fraction(2)) ** 2 <= 2
    True
    """
    return _sqrt_bounds(Fraction(q), bits)[0]


def sqrt_upper(q: Fraction, bits: int = 64) -> Fraction:
    """A rational ``r`` with ``r >= sqrt(q)`` and ``r - sqrt(q) <= 2**-bits / den(q)``.

    Parameters
    ----------
    q : Fraction
        A rational ``>= 0`` (negative raises :class:`InvalidInputError`); the square of a
        rational gives its root exactly.
    bits : int
        Accuracy: the bound is within ``2**-bits / den(q)`` of ``sqrt(q)``.

    Examples
    --------
    >>> sqrt_upper(Fraction(2)) ** 2 >= 2
    True
    """
    return _sqrt_bounds(Fraction(q), bits)[1]


def float_up(q: Fraction) -> float:
    """The smallest float ``>= q`` (directed rounding upward).

    Parameters
    ----------
    q : Fraction
        A rational; one that is a float exactly comes back unchanged (beyond the largest
        float, :class:`OverflowError`).

    Examples
    --------
    >>> float_up(Fraction(1, 10)) >= Fraction(1, 10)
    True
    >>> float_up(Fraction(1, 2))
    0.5
    """
    f = float(q)
    if Fraction(f) < q:
        f = math.nextafter(f, math.inf)
    return f


def float_down(q: Fraction) -> float:
    """The largest float ``<= q`` (directed rounding downward).

    Examples
    --------
    >>> float_down(Fraction(1, 10)) <= Fraction(1, 10)
    True
    """
    f = float(q)
    if Fraction(f) > q:
        f = math.nextafter(f, -math.inf)
    return f


def encode_exact(q: Fraction) -> float | str:
    """JSON-ready form of a rational: the float if it is one exactly, else ``"p/q"``.

    Python's :mod:`json` writes floats with ``repr``, which round-trips exactly.

    Examples
    --------
    >>> encode_exact(Fraction(1, 4)), encode_exact(Fraction(1, 3))
    (0.25, '1/3')
    """
    q = Fraction(q)
    f = float(q)
    return f if Fraction(f) == q else f"{q.numerator}/{q.denominator}"


def decode_exact(value: object) -> Fraction:
    """Inverse of :func:`encode_exact` (also accepts ints).

    Raises
    ------
    InvalidInputError
        If ``value`` is not a finite number or a ``"p/q"`` string.

    Examples
    --------
    >>> decode_exact("1/3"), decode_exact(0.25)
    (Fraction(1, 3), Fraction(1, 4))
    """
    if isinstance(value, bool):
        raise InvalidInputError(f"expected a number, got the boolean {value}")
    if isinstance(value, int):
        return Fraction(value)
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InvalidInputError(f"expected a finite number, got {value}")
        return Fraction(value)
    if isinstance(value, str):
        parts = value.split("/")
        if len(parts) == 2 and all(p.strip().lstrip("-").isdigit() for p in parts):
            den = int(parts[1])
            if den > 0:
                return Fraction(int(parts[0]), den)
        raise InvalidInputError(f"expected a rational written 'p/q' with q > 0, got {value!r}")
    raise InvalidInputError(f"expected a number or a 'p/q' string, got {type(value).__name__}")


def dyadic(values: Iterable[float]) -> tuple[list[int], int]:
    """Integers ``m`` and one exponent ``e`` with ``values[k] == m[k] * 2**e`` exactly (finite floats).

    Every finite float is a dyadic rational, so a list of them shares one power of two:
    products, sums and comparisons of the integers are then exact and much cheaper than
    :class:`~fractions.Fraction` arithmetic (no gcd after every operation). Floats of
    magnitude ``2^-48 .. 2^900`` take the fast route ``e = -100``, down to ``2^-148`` the route
    ``e = -200``; others the exact ratios (the smallest common power of two).

    Parameters
    ----------
    values : iterable of float
        Finite floats (ints are accepted too, by their exact ratios); an infinite or NaN
        value raises :class:`InvalidInputError`.

    Examples
    --------
    >>> m, e = dyadic([0.75, 2.0, -0.125, 1e-300])
    >>> [Fraction(k) * Fraction(2) ** e for k in m] == [Fraction(v) for v in (0.75, 2.0, -0.125, 1e-300)]
    True
    >>> dyadic([0.5, 1.0])
    ([633825300114114700748351602688, 1267650600228229401496703205376], -100)
    >>> dyadic([3, 2**60 + 1])
    ([3, 1152921504606846977], 0)
    """
    vals = list(values)
    try:  # float.__mul__ refuses anything but floats; scaling by 2^k is exact unless it overflows
        for bits, scale in _DYADIC_SCALES:
            scaled = list(map(float.__mul__, vals, repeat(scale)))
            if all(map(float.is_integer, scaled)):  # inf and NaN are not integers
                return list(map(int, scaled)), -bits
    except TypeError:  # ints and other numbers: the exact ratios decide
        pass
    try:
        ratios = [v.as_integer_ratio() for v in vals]
    except (OverflowError, ValueError):
        raise InvalidInputError("dyadic needs finite floats") from None
    den = max(r[1] for r in ratios)
    return [n * (den // d) for n, d in ratios], 1 - den.bit_length()
