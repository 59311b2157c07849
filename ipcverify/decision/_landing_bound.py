"""Proposition 1 decided in float64 with a rigorous bound on the rounding error.

:func:`landing_by_bound` is the fast path of :meth:`ipcverify.decision.LandingRule.decide`.
It decides the same question as the exact :func:`ipcverify.decision.landing_decision` --
does ``E(c, C)`` lie in ``[P - G.upper, P - G.lower]``, with the same turn-off point ``P``
(``P_z`` the smallest float above ``c_z + sqrt_upper(P_zz)``) and the same inward-rounded
box -- and answers only when the answer is certain; the error analysis is in
``proofs/float_landing.md``.

* **Float margins with error bounds (tier 1).** The half-widths ``h_i = ||row i of C^-1||``
  are computed from the adjugate (``h_i = ||column i of cof C|| / |det C|``) in float64,
  with an enclosure ``h_lo <= h_i <= h_hi`` from a forward error analysis (every product
  and sum rounds by at most ``u = 2^-53``, plus an absolute underflow allowance). The box
  is rounded exactly (error-free transformations), and each face ``s >= h_i`` is decided
  when ``s`` and the enclosure of ``h_i`` do not overlap.
* **Exact turn-off height (tier 2).** ``P_z`` is found in float when the enclosure of
  ``c_z + h_z`` rounds up to a single float; otherwise it, and the two ``z`` faces, are
  decided in exact integer arithmetic (the matrix scaled to integers by one power of two:
  ``h_z^2 = ||cof col 2||^2 / det^2`` compared with squares of exact dyadic slacks). When
  ``c_z + h_z`` lies within ``2^-64 h_z`` of a float, ``P_z`` is the exact path's own
  ``float_up(c_z + sqrt_upper(h_z^2, 64))`` on the same rational ``h_z^2``.
* Anything else -- a face within its rounding band, a matrix out of the range the analysis
  covers, a nearly singular matrix -- returns None: the caller falls back to the exact
  rational :func:`~ipcverify.decision.landing_decision`.

An answer of :func:`landing_by_bound` is therefore a proof, not an estimate: ``accept``
equals the exact decision's, and ``turnoff_z`` equals its ``P_z`` (checked against the exact
rational decision by the property tests of ``tests/ipcverify/decision/test_landing_bound.py``).

Examples
--------
>>> r = landing_by_bound((0.0, 0.0, 1.0), (40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0),
...                      (-0.05, -0.05, 0.0), (0.05, 0.05, 0.05))
>>> r.accept, r.turnoff_z   # 1 + 1/80 rounded up
(True, 1.0125000000000002)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from fractions import Fraction
from typing import Any, NamedTuple

from numba.extending import register_jitable

from ipcverify.sets._ellipsoid import SINGULAR_RCOND
from ipcverify.sets._exact import dyadic, float_up, sqrt_upper

#: Entries of ``C`` are brought into ``[-RANGE, RANGE]`` by an exact power-of-two scaling (the centre
#: and ``G`` must lie in ``[-2^600, 2^600]``): then nothing in the analysis overflows, and underflow
#: is covered by absolute allowances.
RANGE = 2.0**100
_CENTER_RANGE = 2.0**600
_U = 2.0**-53
# constants of proofs/float_landing.md (all exact floats)
_N_SUM = 1.25 * _U  # column norm: per unit of the summed |products| of the cofactors (Lemma 2)
_N_EST = 5.0 * _U  # ... per unit of the computed norm
_D_SUM = 6.25 * _U  # determinant: per unit of sum |c_0j| (|p| + |q|)_0j (Lemma 3)
_DOWN = 1.0 - 4.0 * _U  # covers one division and one product rounding (Lemma 4)
_UP = 1.0 + 4.0 * _U
_ABS_NORM = 2.0**-530  # absolute underflow allowance of a column norm
_ABS_DET = 2.0**-960  # ... of the determinant
_SMALLEST = 2.0**-1000  # half-widths below this are not trusted (gradual underflow)
_BAND = (1 << 64) + 1  # sqrt_upper(q, 64) <= sqrt(q) (1 + 2^-64)
_MIN_TOP = 2.0**-100  # matrices whose largest entry is outside [2^-100, 2^100] are scaled first
_NORMAL = 2.0**-1022
_INF = math.inf
_nextafter = math.nextafter
_sqrt = math.sqrt


class BoundDecision(NamedTuple):
    """A landing decision reached without the exact rational proof (but proven all the same).

    Attributes
    ----------
    accept : bool
        ``E`` fits ``[P - G.upper, P - G.lower]`` (every face proven); False: a face provably fails.
    turnoff_z : float
        ``P_z``, equal to the exact decision's.
    exact_turnoff : bool
        Exact integer arithmetic was needed (tier 2) for ``P_z`` or a ``z`` face.
    """

    accept: bool
    turnoff_z: float
    exact_turnoff: bool


def bound_target(lower: Sequence[float], upper: Sequence[float]) -> bool:
    """True if a target box is inside the range :func:`landing_by_bound` covers (finite, ``<= 2^600``).

    Examples
    --------
    >>> bound_target((-0.05, -0.05, 0.0), (0.05, 0.05, 0.05)), bound_target((0.0,) * 3, (1e300,) * 3)
    (True, False)
    """
    values = [*lower, *upper]
    return bool(max(values) <= _CENTER_RANGE and min(values) >= -_CENTER_RANGE)


@register_jitable
def _up_sum(x: float, y: float) -> float:
    """The smallest float ``>= x + y`` (exact: TwoSum gives the rounding error of ``x + y``)."""
    s = x + y
    bb = s - x
    err = (x - (s - bb)) + (y - bb)
    return _nextafter(s, _INF) if err > 0.0 else s


@register_jitable
def _down_sum(x: float, y: float) -> float:
    """The largest float ``<= x + y``."""
    s = x + y
    bb = s - x
    err = (x - (s - bb)) + (y - bb)
    return _nextafter(s, -_INF) if err < 0.0 else s


@register_jitable
def _face(x: float, y: float, h_lo: float, h_hi: float) -> int:
    """Face ``x - y >= h`` for ``h in [h_lo, h_hi]``: 1 holds, -1 fails, 0 undecided (rounding band)."""
    y = -y
    s = x + y
    bb = s - x
    err = (x - (s - bb)) + (y - bb)  # s + err is the slack x - y exactly
    if (s if err >= 0.0 else _nextafter(s, -_INF)) >= h_hi:
        return 1
    return -1 if (s if err <= 0.0 else _nextafter(s, _INF)) < h_lo else 0


class _ExactZ:
    """``h_z`` of ``C`` in exact integers (tier 2): ``C = M 2^exp`` with ``M`` an integer matrix, so
    ``h_z^2 = num / den2 * 4^-exp`` with ``num = ||cofactor column 2 of M||^2``, ``den2 = det(M)^2``."""

    __slots__ = ("cz", "czf", "den2", "exp", "num", "unscale")

    def __init__(self, shape: Sequence[float], cz: float) -> None:
        ints, self.exp = dyadic([*shape, cz])
        a, b, c, d, e, f, g, h, i, self.cz = ints
        self.czf = cz
        self.unscale = math.ldexp(1.0, -self.exp) if -1000 < self.exp < 0 else None
        k0, k1, k2 = d * h - e * g, b * g - a * h, a * e - b * d  # cofactor column 2 = row 2 of adj M
        det = c * k0 + f * k1 + i * k2
        self.num, self.den2 = k0 * k0 + k1 * k1 + k2 * k2, det * det

    def turnoff(self, t_lo: float, t_hi: float) -> float | None:
        """``P_z`` = the smallest float ``>= c_z + sqrt_upper(h_z^2)``, as the exact path computes it.

        An integer square root gives ``h_z`` to 130 bits: ``h_z 2^s`` lies in ``[r, r + 1)``, so
        ``c_z + sqrt_upper`` lies in ``[c_z + r 2^-s, c_z + (r + 1)(1 + 2^-64) 2^-s]`` (``sqrt_upper``
        exceeds ``h_z`` by at most ``2^-64`` relative). If both ends round up to the same float,
        that float is ``P_z``. When ``P_z`` is known to be ``t_lo`` or the next float ``t_hi``,
        one exact comparison of ``t_lo - c_z`` with ``h_z`` decides instead. If neither settles it,
        ``c_z + h_z`` lies within ``2^-64 h_z`` of a float and ``P_z`` depends on the rational that
        ``sqrt_upper`` picks: it is computed by the exact path's own formula, on the same rational
        ``h_z^2`` (None only if ``c_z + h_z`` overflows, where the exact path fails too).
        """
        if t_hi == _nextafter(t_lo, _INF):
            r = self.compare(t_lo, True, True)
            if r:
                return t_lo if r > 0 else t_hi
            return self.turnoff_exact()
        num, den2 = self.num, self.den2
        m = 130 - (num.bit_length() - den2.bit_length()) // 2
        r = math.isqrt((num << 2 * m) // den2 if m >= 0 else num // (den2 << -2 * m))
        s = m + self.exp  # h_z = (r + theta) 2^-s, 0 <= theta < 1
        e = min(self.exp, -s - 64)
        cz = self.cz << (self.exp - e)
        low = _float_up_dyadic(cz + (r << (-s - e)), e)
        high = _float_up_dyadic(cz + ((r + 1) * _BAND << (-s - 64 - e)), e)
        return low if low is not None and low == high else self.turnoff_exact()

    def turnoff_exact(self) -> float | None:
        """``float_up(c_z + sqrt_upper(h_z^2, 64))`` with ``h_z^2 = num / den2 * 4^-exp`` (Fractions).

        The exact path (``ipcverify.decision._landing``) evaluates the same expression on the same rational
        (``sqrt_upper`` depends only on its value), so the two ``P_z`` are the same float.
        """
        hz2 = Fraction(self.num, self.den2) * (Fraction(4) ** -self.exp)
        try:
            return float_up(Fraction(self.czf) + sqrt_upper(hz2, 64))
        except OverflowError:
            return None

    def compare(self, x: float, above: bool, band: bool = False) -> int:
        """The exact slack ``s = x - c_z`` (``above``) or ``c_z - x`` against ``h_z``.

        -1: ``s < h_z``; 1: ``s >= h_z``, and with ``band`` even ``s >= h_z (1 + 2^-64)``;
        0: ``band`` and ``h_z <= s < h_z (1 + 2^-64)``. ``det(M) = 0`` gives -1 (never used:
        the caller proved ``det > 0`` in float).
        """
        scaled = x * self.unscale if self.unscale is not None else 0.5
        if scaled.is_integer():  # x on the same grid as C and c_z (the usual case)
            n = int(scaled)
            diff, exp = (n - self.cz if above else self.cz - n), self.exp
        else:
            (dx, dc), exp = dyadic((x, self.czf))
            diff = dx - dc if above else dc - dx
        if diff < 0:
            return -1
        lhs, rhs, shift = diff * diff * self.den2, self.num, 2 * (exp + self.exp)
        if shift >= 0:
            lhs <<= shift
        else:
            rhs <<= -shift
        if lhs < rhs:
            return -1
        return 1 if not band or lhs << 128 >= rhs * (_BAND * _BAND) else 0


def _float_up_dyadic(x: int, e: int) -> float | None:
    """The smallest float ``>= x 2^e`` (None outside the normal range, where one rounding is not enough)."""
    try:
        f = math.ldexp(float(x), e)  # float(x) is correctly rounded; the scaling is exact if f is normal
    except OverflowError:
        return None
    if not _SMALLEST <= abs(f) < _INF:
        return None if x else 0.0
    num, den = f.as_integer_ratio()  # f = num / den; f >= x 2^e  <=>  num >= x den 2^e
    below = num < (x * den << e) if e >= 0 else num << -e < x * den
    return _nextafter(f, _INF) if below else f


def landing_by_bound(
    center: Sequence[float], shape: Sequence[float], lower: Sequence[float], upper: Sequence[float]
) -> BoundDecision | None:
    """Decide Proposition 1 in float64 with rigorous rounding bounds; None when not certain.

    Parameters
    ----------
    center : sequence of 3 floats
        The ellipsoid's centre ``c``.
    shape : sequence of 9 floats
        Its shape matrix ``C``, row-major (``E = {y : ||C (y - c)|| <= 1}``).
    lower, upper : sequence of 3 floats
        The target ``G = [lower, upper]`` (checked by :func:`bound_target` once by the caller).

    Returns
    -------
    BoundDecision or None
        The exact decision's ``accept`` and ``P_z`` when the rounding bounds settle them
        (and, for an accept, the matrix is certainly non-singular by the rule of
        :class:`~ipcverify.sets.Ellipsoid`); None otherwise (decide exactly instead).

    Examples
    --------
    >>> G = ((-0.05, -0.05, 0.0), (0.05, 0.05, 0.05))
    >>> landing_by_bound((0.0, 0.0, 0.0), (10.0, 0, 0, 0, 40.0, 0, 0, 0, 80.0), *G).accept  # x too wide
    False
    >>> landing_by_bound((0.0, 0.0, 0.0), (1.0, 0, 0, 0, 1.0, 0, 0, 0, 0.0), *G) is None  # singular
    True
    """
    cx, cy, cz = center
    if not -_CENTER_RANGE <= min(center) <= max(center) <= _CENTER_RANGE:
        return None  # also NaN
    big, small = max(shape), min(shape)
    top = max(big, -small)
    scale = 1.0  # h_i(C) = h_i(C / 2^k) / 2^k: huge or tiny matrices are scaled exactly first
    if not _MIN_TOP <= top <= RANGE:
        if not 0.0 < top < _INF:
            return None  # zero, non-finite or NaN
        k = math.frexp(top)[1]
        if k < -1023:  # 2^-k is beyond float's range; so are the half-widths (>= 1 / (3 top))
            return None  # the exact path answers (a degenerate set: OUTSIDE_DOMAIN)
        scale = math.ldexp(1.0, -k)
        scaled = [v * scale for v in shape]
        if any(v and abs(w) < _NORMAL for v, w in zip(shape, scaled, strict=True)):
            return None  # a dynamic range beyond the float format: scaling would round
        a, b, c, d, e, f, g, h, i = scaled
    else:
        a, b, c, d, e, f, g, h, i = shape
    gl0, gl1, gl2 = lower
    gu0, gu1, gu2 = upper
    tier = float_tier(cx, cy, cz, a, b, c, d, e, f, g, h, i, scale, top, gl0, gl1, gu0, gu1)
    return finish(tier, shape, cz, gl2, gu2)


def float_tier(
    cx: float,
    cy: float,
    cz: float,
    a: float,
    b: float,
    c: float,
    d: float,
    e: float,
    f: float,
    g: float,
    h: float,
    i: float,
    scale: float,
    top: float,
    gl0: float,
    gl1: float,
    gu0: float,
    gu1: float,
) -> tuple[int, int, int, int, int, float, float, float, float, bool]:
    """Tier 1 in floats alone: the half-widths' enclosures, the ``x`` and ``y`` faces, ``P_z``'s bracket.

    ``a .. i`` is ``C`` (row-major) already scaled by ``scale``, ``top`` the largest ``|C_ij|``
    before scaling, the centre and ``G``'s ``x`` and ``y`` bounds finite and in range (as
    :func:`landing_by_bound` checks). Returns ``(ok, f0, f1, f2, f3, t_lo, t_hi, hz_lo, hz_hi,
    nonsingular)``: ``ok = 0`` means no answer (:func:`landing_by_bound` returns None);
    otherwise the four ``x``/``y`` faces (1 holds, -1 fails, 0 undecided), the floats that
    bracket ``P_z``, the enclosure of ``h_z`` and whether an accept clears the singularity rule.

    Its only operations are IEEE 754 float arithmetic, ``abs``, ``min``, ``max``,
    ``math.sqrt`` and ``math.nextafter`` on Python floats, so Numba compiles it without
    fast-math to the same numbers (:meth:`ipcverify.decision.LandingRule.decide` runs it
    compiled; a test checks both on every property-test input).

    Parameters
    ----------
    cx, cy, cz : float
        The ellipsoid's centre ``c``.
    a, b, c, d, e, f, g, h, i : float
        ``C`` row-major, multiplied by ``scale`` (largest ``|entry|`` in ``[2^-100, 2^100]``).
    scale : float
        The exact power of two applied to ``C`` (1.0 when unscaled); half-widths are rescaled by it.
    top : float
        The largest ``|C_ij|`` before scaling (for the singularity rule).
    gl0, gl1, gu0, gu1 : float
        ``G.lower`` and ``G.upper`` in ``x`` and ``y`` (the ``z`` bounds go to :func:`finish`).
    """
    # cofactors K_rc (row r, column c) and the sums |p| + |q| of their two products
    p, q = e * i, f * h
    k00, a00 = p - q, abs(p) + abs(q)
    p, q = f * g, d * i
    k01, a01 = p - q, abs(p) + abs(q)
    p, q = d * h, e * g
    k02, a02 = p - q, abs(p) + abs(q)
    p, q = c * h, b * i
    k10, a10 = p - q, abs(p) + abs(q)
    p, q = a * i, c * g
    k11, a11 = p - q, abs(p) + abs(q)
    p, q = b * g, a * h
    k12, a12 = p - q, abs(p) + abs(q)
    p, q = b * f, c * e
    k20, a20 = p - q, abs(p) + abs(q)
    p, q = c * d, a * f
    k21, a21 = p - q, abs(p) + abs(q)
    p, q = a * e, b * d
    k22, a22 = p - q, abs(p) + abs(q)
    det = abs(a * k00 + b * k01 + c * k02)
    e_det = _D_SUM * (abs(a) * a00 + abs(b) * a01 + abs(c) * a02) + _ABS_DET
    d_lo, d_hi = det - e_det, det + e_det
    if not d_lo > 0.0:
        return 0, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, False  # singular, or too close to it for the bound
    # h_i = ||column i of the cofactor matrix|| / |det|, enclosed in [h_lo, h_hi]
    s0 = math.sqrt(k00 * k00 + k10 * k10 + k20 * k20)
    s1 = math.sqrt(k01 * k01 + k11 * k11 + k21 * k21)
    s2 = math.sqrt(k02 * k02 + k12 * k12 + k22 * k22)
    e0 = _N_SUM * (a00 + a10 + a20) + _N_EST * s0 + _ABS_NORM
    e1 = _N_SUM * (a01 + a11 + a21) + _N_EST * s1 + _ABS_NORM
    e2 = _N_SUM * (a02 + a12 + a22) + _N_EST * s2 + _ABS_NORM
    n0, n1, n2 = s0 + e0, s1 + e1, s2 + e2
    hx_hi, hy_hi, hz_hi = n0 / d_lo * _UP * scale, n1 / d_lo * _UP * scale, n2 / d_lo * _UP * scale
    if not (min(hx_hi, hy_hi, hz_hi) >= _SMALLEST and max(hx_hi, hy_hi, hz_hi) < _INF):
        return 0, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, False  # out of the range the analysis covers
    hx_lo = (s0 - e0) / d_hi * _DOWN * scale
    hy_lo = (s1 - e1) / d_hi * _DOWN * scale
    hz_lo = (s2 - e2) / d_hi * _DOWN * scale
    hx_lo = hx_lo if hx_lo >= _SMALLEST else 0.0
    hy_lo = hy_lo if hy_lo >= _SMALLEST else 0.0
    hz_lo = hz_lo if hz_lo >= _SMALLEST else 0.0
    # x and y: P_x = c_x, P_y = c_y; the box [P - G.upper, P - G.lower] rounded inward, exactly
    up0, low0, up1, low1 = _down_sum(cx, -gl0), _up_sum(cx, -gu0), _down_sum(cy, -gl1), _up_sum(cy, -gu1)
    if low0 > up0 or low1 > up1:
        return 0, 0, 0, 0, 0, 0.0, 0.0, 0.0, 0.0, False  # G narrower than one float spacing here
    f0 = _face(up0, cx, hx_lo, hx_hi)
    f1 = _face(cx, low0, hx_lo, hx_hi)
    f2 = _face(up1, cy, hy_lo, hy_hi)
    f3 = _face(cy, low1, hy_lo, hy_hi)
    # P_z = the smallest float >= c_z + sqrt_upper(h_z^2), and h_z <= sqrt_upper(h_z^2) < next(h_hi)
    t_lo, t_hi = _up_sum(cz, hz_lo), _up_sum(cz, math.nextafter(hz_hi, _INF))
    # accept only what Ellipsoid accepts: rcond >= |det| / (||C||_F ||adj C||_F) >= 2 * its minimum
    nonsingular = not d_lo < 2.0 * SINGULAR_RCOND * 3.0 * top * scale * (n0 + n1 + n2) * _UP
    return 1, f0, f1, f2, f3, t_lo, t_hi, hz_lo, hz_hi, nonsingular


def finish(
    tier: tuple[int, int, int, int, int, float, float, float, float, bool],
    shape: Sequence[float],
    cz: float,
    gl2: float,
    gu2: float,
) -> BoundDecision | None:
    """The rest of :func:`landing_by_bound` after :func:`float_tier`: ``P_z`` and the ``z`` faces.

    In floats when ``P_z``'s bracket is one float and the faces clear their bands, in exact
    integers (tier 2, on the unscaled ``shape``) otherwise.

    Parameters
    ----------
    tier : tuple
        :func:`float_tier`'s result; ``ok = 0`` returns None.
    shape : sequence of 9 floats
        ``C`` row-major, unscaled (for the exact tier).
    cz, gl2, gu2 : float
        The centre's ``z``, and ``G.lower`` and ``G.upper`` in ``z``. Returns None (as
        :func:`landing_by_bound`) when a face or ``P_z`` stays undecided.
    """
    ok, f0, f1, f2, f3, t_lo, t_hi, hz_lo, hz_hi, nonsingular = tier
    if not ok:
        return None
    exact = None
    if t_lo == t_hi:
        pz = t_hi
    else:
        exact = _ExactZ(shape, cz)
        pz_exact = exact.turnoff(t_lo, t_hi)
        if pz_exact is None:
            return None
        pz = pz_exact
    up2, low2 = _down_sum(pz, -gl2), _up_sum(pz, -gu2)
    if low2 > up2:
        return None
    # the upper z face holds by construction when up2 >= P_z (P_z >= c_z + h_z)
    face_up = 1 if up2 >= pz else _face(up2, cz, hz_lo, hz_hi)
    face_low = _face(cz, low2, hz_lo, hz_hi)
    if not (face_up and face_low):
        exact = exact or _ExactZ(shape, cz)
        face_up = face_up or exact.compare(up2, True)
        face_low = face_low or exact.compare(low2, False)
    faces = (f0, f1, f2, f3, face_up, face_low)
    if -1 in faces:
        return BoundDecision(False, pz, exact is not None)
    if 0 in faces or not nonsingular:
        return None
    return BoundDecision(True, pz, exact is not None)


@functools.cache
def _compiled_tier() -> Any:
    """:func:`float_tier` compiled by Numba (no fast-math: the same IEEE operations), once per process."""
    from ipcverify.network._kernels import compiled

    return compiled(float_tier)


def prepare() -> None:
    """Compile :func:`float_tier` now (a few seconds after installation, then from Numba's disk cache).

    :class:`ipcverify.decision.IPCQuery` calls it when it is built, so that a control loop's first
    frame costs what the others do.
    """
    identity = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    landing_by_bound_compiled([0.0, 0.0, 1.0], identity, (-1.0,) * 3, (1.0,) * 3)


def landing_by_bound_compiled(
    center: list[float], shape: list[float], lower: Sequence[float], upper: Sequence[float]
) -> BoundDecision | None:
    """:func:`landing_by_bound`, with its float tier compiled: the same answer, about 5 µs sooner.

    The compiled :func:`float_tier` runs where the matrix needs no scaling and every value is
    finite (the usual case); anything else goes to :func:`landing_by_bound` itself. The
    continuation (:func:`finish`, exact integers where needed) is the same Python code.

    Parameters
    ----------
    center : list of 3 floats
        The ellipsoid's centre ``c`` (None is returned outside ``[-2^600, 2^600]``).
    shape : list of 9 floats
        ``C`` row-major.
    lower, upper : sequence of 3 floats
        The target ``G = [lower, upper]``, as for :func:`landing_by_bound`.

    Examples
    --------
    >>> r = landing_by_bound_compiled([0.0, 0.0, 1.0], [40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0],
    ...                               (-0.05, -0.05, 0.0), (0.05, 0.05, 0.05))
    >>> r.accept, r.turnoff_z
    (True, 1.0125000000000002)
    """
    cx, cy, cz = center
    top = max(max(shape), -min(shape))
    # a finite sum means finite values; the centre's range check is landing_by_bound's own
    if _MIN_TOP <= top <= RANGE and math.isfinite(cx + cy + cz):
        if not -_CENTER_RANGE <= min(center) <= max(center) <= _CENTER_RANGE:
            return None
        gl0, gl1, gl2 = lower
        gu0, gu1, gu2 = upper
        tier = _compiled_tier()(cx, cy, cz, *shape, 1.0, top, gl0, gl1, gu0, gu1)
        return finish(tier, shape, cz, gl2, gu2)
    return landing_by_bound(center, shape, lower, upper)
