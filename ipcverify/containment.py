"""Proofs that an ellipsoid lies inside a box, a polytope or another ellipsoid.

Three provers, one certificate type, one exact checker:

* **closed form** (box, polytope): ``max_{y in E(c, C)} a^T y = a^T c + ||C^{-T} a||``,
  so ``E`` is inside ``{y : A y <= b}`` iff ``a_j^T c + ||C^{-T} a_j|| <= b_j`` for every
  face ``j``. :func:`support_slack` evaluates this in float for whole batches; the
  certificate's status comes from the same inequality re-derived in exact rational
  arithmetic (``b - a^T c >= 0`` and ``(b - a^T c)^2 >= ||C^{-T} a||^2``).
* **SOCP** (box, polytope): the support values ``max a_j^T y`` computed by Clarabel,
  as a cross-check of the closed form (a PROVEN status still needs the exact check).
* **SDP** (ellipsoid): the S-lemma LMI ``lam Q1 - Q2 + tau e e^T >= 0``; minimising
  ``tau`` gives ``tau* = max_{y in E1} ||C2 (y - c2)||^2``, so ``E1`` is inside ``E2``
  iff ``tau* <= 1`` (derivation in ``proofs/containment.md``). Clarabel proposes
  ``(lam, tau)``; the certificate holds multipliers that pass an exact PSD test.

:func:`verify` re-checks any certificate in exact arithmetic, independently of the
float code and of the solver. A certificate is PROVEN only if that check passes;
REFUTED carries a witness point (exact rationals) that is inside the inner set and
outside the outer one; anything else is UNKNOWN.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Ellipsoid
>>> inner = Ellipsoid(np.zeros(2), np.diag([2.0, 4.0]))     # semi-axes 0.5, 0.25
>>> cert = prove_containment(inner, Box([-0.5, -0.25], [0.5, 0.25]))
>>> cert.status.name, verify(cert).status.name
('PROVEN', 'PROVEN')
>>> cert = prove_containment(inner, Box([-0.4, -1.0], [0.4, 1.0]))
>>> cert.status.name, cert.witness_floats()
('REFUTED', (0.5, 0.0))
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from enum import Enum
from fractions import Fraction
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ipcverify.errors import InvalidInputError, SetError
from ipcverify.exact import (
    ExactMatrix,
    ExactVector,
    decode_exact,
    encode_exact,
    exact_matrix,
    exact_vector,
    inverse,
    is_positive_definite,
    is_positive_semidefinite,
    matvec,
    sqnorm,
    sqrt_upper,
)
from ipcverify.sets import Ellipsoid

__all__ = [
    "Box",
    "ContainmentCertificate",
    "Method",
    "OuterSet",
    "Polytope",
    "Status",
    "Verification",
    "contained_float",
    "certificate_from_dict",
    "problem_from_dict",
    "prove_containment",
    "prove_containment_batch",
    "set_from_dict",
    "set_to_dict",
    "support_slack",
    "verify",
]

FloatArray = NDArray[np.float64]


# --------------------------------------------------------------------------- enums
class Status(Enum):
    """Outcome of a containment proof; ``str(status)`` says what to do next.

    Examples
    --------
    >>> Status.UNKNOWN.advice.startswith("neither")
    True
    """

    PROVEN = "PROVEN"
    REFUTED = "REFUTED"
    UNKNOWN = "UNKNOWN"

    @property
    def advice(self) -> str:
        """What the status means for the caller and what to do next."""
        return _ADVICE[self]

    def __str__(self) -> str:
        return f"{self.value}: {self.advice}"


_ADVICE = {
    Status.PROVEN: (
        "the inner set is inside the outer set; the certificate re-verifies in exact "
        "rational arithmetic, so it may be relied on"
    ),
    Status.REFUTED: (
        "the inner set is NOT inside the outer set; the witness point lies in the inner "
        "set and outside the outer set (checked exactly): shrink the inner set or grow "
        "the outer set"
    ),
    Status.UNKNOWN: (
        "neither proven nor refuted (solver not optimal, or the sets are too close to "
        "touching for float multipliers); treat the containment as NOT established, or "
        "retry with another method or with a slightly larger outer set"
    ),
}


class Method(Enum):
    """How a containment was decided.

    ``closed-form`` and ``socp`` apply to boxes and polytopes, ``sdp`` to ellipsoids.
    """

    CLOSED_FORM = "closed-form"
    SOCP = "socp"
    SDP = "sdp"


# --------------------------------------------------------------------------- sets
def _float_array(values: ArrayLike, ndim: int, what: str) -> FloatArray:
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


@dataclass(frozen=True, eq=False)
class Box:
    """The axis-aligned box ``{y : lower <= y <= upper}`` (closed).

    Parameters
    ----------
    lower, upper : array_like, shape (n,)
        Finite bounds with ``lower <= upper``.

    Examples
    --------
    >>> Box([-1.0, 0.0], [1.0, 2.0]).dim
    2
    """

    lower: FloatArray
    upper: FloatArray

    def __post_init__(self) -> None:
        lo = _float_array(self.lower, 1, "box lower")
        up = _float_array(self.upper, 1, "box upper")
        if lo.shape != up.shape or lo.size == 0:
            raise SetError(f"box lower {lo.shape} and upper {up.shape} must both have shape (n,), n >= 1")
        if not (lo <= up).all():
            i = int(np.flatnonzero(~(lo <= up))[0])
            raise SetError(
                f"box coordinate {i}: lower {lo[i]!r} > upper {up[i]!r}; swap them or widen the box"
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


@dataclass(frozen=True, eq=False)
class Polytope:
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
    """

    A: FloatArray
    b: FloatArray

    def __post_init__(self) -> None:
        a = _float_array(self.A, 2, "polytope A")
        b = _float_array(self.b, 1, "polytope b")
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


OuterSet = Box | Polytope | Ellipsoid


def _single(e: Ellipsoid, what: str) -> Ellipsoid:
    if not isinstance(e, Ellipsoid):
        raise SetError(f"{what} must be an Ellipsoid; got {type(e).__name__}")
    if e.batch_size != 1:
        raise SetError(
            f"{what} must be a single ellipsoid (batch of 1); got a batch of {e.batch_size}: "
            "use prove_containment_batch for batches"
        )
    return e


def set_to_dict(s: OuterSet) -> dict[str, Any]:
    """JSON-ready form of a single set (floats round-trip exactly through :mod:`json`).

    Examples
    --------
    >>> set_to_dict(Box([0.0], [1.0]))
    {'type': 'box', 'lower': [0.0], 'upper': [1.0]}
    """
    if isinstance(s, Box):
        return {"type": "box", "lower": s.lower.tolist(), "upper": s.upper.tolist()}
    if isinstance(s, Polytope):
        return {"type": "polytope", "A": s.A.tolist(), "b": s.b.tolist()}
    if isinstance(s, Ellipsoid):
        _single(s, "ellipsoid")
        return {"type": "ellipsoid", "center": s.centers[0].tolist(), "shape": s.shapes[0].tolist()}
    raise SetError(f"cannot serialise a {type(s).__name__}; expected Box, Polytope or Ellipsoid")


def _json_number(v: Any, where: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise InvalidInputError(f"field '{where}': expected a number, got {json.dumps(v)[:40]}")
    if isinstance(v, int):
        f = float(v) if abs(v) < 2**1024 else math.inf
        if not math.isfinite(f) or int(f) != v:
            raise InvalidInputError(
                f"field '{where}': integer {v} is not exactly a float; write it as a float"
            )
        return f
    if not math.isfinite(v):
        raise InvalidInputError(f"field '{where}': {v} is not finite; use finite numbers")
    return float(v)


def _json_vector(v: Any, where: str, length: int | None = None) -> list[float]:
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of numbers")
    if length is not None and len(v) != length:
        raise InvalidInputError(f"field '{where}': expected {length} numbers, got {len(v)}")
    return [_json_number(x, f"{where}[{i}]") for i, x in enumerate(v)]


def _json_matrix(v: Any, where: str, cols: int | None = None) -> list[list[float]]:
    if not isinstance(v, list) or not v:
        raise InvalidInputError(f"field '{where}': expected a non-empty list of rows")
    rows = [_json_vector(r, f"{where}[{i}]", cols) for i, r in enumerate(v)]
    width = len(rows[0])
    for i, r in enumerate(rows):
        if len(r) != width:
            raise InvalidInputError(f"field '{where}[{i}]': row has {len(r)} entries, expected {width}")
    return rows


def _field(d: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in d:
        raise InvalidInputError(f"field '{where}{key}' is missing")
    return d[key]


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
    kind = _field(d, "type", where)
    try:
        if kind == "box":
            lo = _json_vector(_field(d, "lower", where), f"{where}lower")
            up = _json_vector(_field(d, "upper", where), f"{where}upper", len(lo))
            return Box(np.asarray(lo, dtype=np.float64), np.asarray(up, dtype=np.float64))
        if kind == "polytope":
            a = _json_matrix(_field(d, "A", where), f"{where}A")
            b = _json_vector(_field(d, "b", where), f"{where}b", len(a))
            return Polytope(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
        if kind == "ellipsoid":
            c = _json_vector(_field(d, "center", where), f"{where}center")
            s = _json_matrix(_field(d, "shape", where), f"{where}shape", len(c))
            if len(s) != len(c):
                raise InvalidInputError(
                    f"field '{where}shape': expected {len(c)} rows to match the center, got {len(s)}"
                )
            return Ellipsoid(np.array(c), np.array(s))
    except SetError as exc:
        raise SetError(f"field '{where.rstrip('.') or 'set'}': {exc}") from None
    raise InvalidInputError(
        f"field '{where}type': {json.dumps(kind)[:40]} is not one of 'box', 'polytope', 'ellipsoid'"
    )


def problem_from_dict(d: Any) -> tuple[Ellipsoid, OuterSet, Method | None]:
    """Parse one problem ``{"inner": ELLIPSOID, "outer": SET, "method"?: str}``.

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
    inner = set_from_dict(_field(d, "inner", ""), "inner.")
    if not isinstance(inner, Ellipsoid):
        raise InvalidInputError("field 'inner.type': the inner set must be an ellipsoid")
    outer = set_from_dict(_field(d, "outer", ""), "outer.")
    if outer.dim != inner.dim:
        raise InvalidInputError(
            f"field 'outer': dimension {outer.dim} differs from the inner ellipsoid's {inner.dim}"
        )
    method = None
    if "method" in d:
        method = _parse_method(d["method"], "method")
        _check_method(method, outer)
    return inner, outer, method


def _parse_method(v: Any, where: str) -> Method:
    try:
        return Method(v)
    except ValueError:
        names = ", ".join(m.value for m in Method)
        raise InvalidInputError(f"field '{where}': {json.dumps(v)[:40]} is not one of {names}") from None


def _check_method(method: Method, outer: OuterSet) -> None:
    ok = method is Method.SDP if isinstance(outer, Ellipsoid) else method is not Method.SDP
    if not ok:
        raise InvalidInputError(
            f"method '{method.value}' does not apply to a "
            f"{type(outer).__name__.lower()} outer set: "
            "use 'sdp' for ellipsoids, 'closed-form' or 'socp' for boxes and polytopes"
        )


# ------------------------------------------------------------- float batch path
def support_slack(inner: Ellipsoid, outer: Box | Polytope) -> FloatArray:
    """Float slack ``b_j - a_j^T c - ||C^{-T} a_j||`` of every face, shape (B, m).

    Vectorised over the batch (10^5 ellipsoids with ``n = 3`` take a few tens of
    milliseconds). The values are float estimates: a slack of ``0`` means touching;
    the sign decides containment only up to rounding. For a proof use
    :func:`prove_containment` (exact).

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((1, 1)), np.full((1, 1, 1), 2.0))  # [-0.5, 0.5]
    >>> support_slack(e, Box([-1.0], [1.0]))
    array([[0.5, 0.5]])
    """
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid")
    if isinstance(outer, Box):
        if outer.dim != inner.dim:
            raise SetError(f"box dimension {outer.dim} != ellipsoid dimension {inner.dim}")
        h = inner.half_widths()
        return np.concatenate([outer.upper - inner.centers - h, inner.centers - h - outer.lower], axis=1)
    if isinstance(outer, Polytope):
        if outer.dim != inner.dim:
            raise SetError(f"polytope dimension {outer.dim} != ellipsoid dimension {inner.dim}")
        cinv = np.linalg.inv(inner.shapes)
        z = np.einsum("bki,jk->bji", cinv, outer.A)  # C^{-T} a_j
        return outer.b - inner.centers @ outer.A.T - np.linalg.norm(z, axis=2)
    raise SetError(f"support_slack needs a Box or Polytope; got {type(outer).__name__}")


def contained_float(inner: Ellipsoid, outer: Box | Polytope) -> NDArray[np.bool_]:
    """Float-decided containment mask (B,): every face slack ``>= 0``.

    Fast but *not* a proof: near-touching sets can be misjudged by rounding.
    Use :func:`prove_containment` / :func:`prove_containment_batch` for exact
    certificates.

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> contained_float(e, Box([-1.0], [1.0])).tolist()
    [True, False]
    """
    return np.asarray((support_slack(inner, outer) >= 0.0).all(axis=1), dtype=np.bool_)


# ---------------------------------------------------------------- exact helpers
@dataclass
class _Exact:
    """Exact rational data of one ellipsoid ``E(c, C)``, inverse computed lazily."""

    c: ExactVector
    C: ExactMatrix
    _ci: ExactMatrix | None = None

    @classmethod
    def of(cls, e: Ellipsoid) -> _Exact:
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
class _Face:
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
        return float(self.slack) - math.sqrt(float(self.zz))


def _exact_faces(ex: _Exact, outer: Box | Polytope) -> list[_Face]:
    """Every face of ``outer`` with its exact slack and ``||C^{-T} a||^2``."""
    n = len(ex.c)
    ci = ex.cinv
    faces: list[_Face] = []
    if isinstance(outer, Box):
        up, lo = exact_vector(outer.upper), exact_vector(outer.lower)
        rows = [ci[i] for i in range(n)]  # C^{-T} e_i = row i of C^{-1}
        norms = [sqnorm(r) for r in rows]
        for i in range(n):
            e = [Fraction(int(k == i)) for k in range(n)]
            faces.append(_Face(i, e, up[i], rows[i], up[i] - ex.c[i], norms[i]))
        for i in range(n):
            e = [Fraction(-int(k == i)) for k in range(n)]
            faces.append(_Face(n + i, e, -lo[i], [-v for v in rows[i]], ex.c[i] - lo[i], norms[i]))
        return faces
    a_rows, b = exact_matrix(outer.A), exact_vector(outer.b)
    for j, (a, bj) in enumerate(zip(a_rows, b, strict=True)):
        # C^{-T} a = sum_k a_k * (row k of C^{-1})
        z = [sum((ak * ci[k][i] for k, ak in enumerate(a) if ak), Fraction(0)) for i in range(n)]
        ac = sum((x * y for x, y in zip(a, ex.c, strict=True)), Fraction(0))
        faces.append(_Face(j, a, bj, z, bj - ac, sqnorm(z)))
    return faces


def _outside(outer: OuterSet, y: Sequence[Fraction]) -> bool:
    """Exactly: ``y`` is not in ``outer``."""
    if isinstance(outer, Ellipsoid):
        return _Exact.of(outer).g2(y) > 1
    if isinstance(outer, Box):
        lo, up = exact_vector(outer.lower), exact_vector(outer.upper)
        return any(v < lo_i or v > up_i for v, lo_i, up_i in zip(y, lo, up, strict=True))
    a_rows, b = exact_matrix(outer.A), exact_vector(outer.b)
    return any(
        sum((x * v for x, v in zip(a, y, strict=True)), Fraction(0)) > bj
        for a, bj in zip(a_rows, b, strict=True)
    )


def _as_float_witness(ex: _Exact, outer: OuterSet, y: Sequence[Fraction]) -> ExactVector | None:
    """The witness rounded to floats, if it still checks exactly (nicer to read)."""
    yf = [Fraction(float(v)) for v in y]
    if ex.g2(yf) <= 1 and _outside(outer, yf):
        return yf
    return None


def _witness_from_direction(ex: _Exact, outer: OuterSet, u: Sequence[Fraction]) -> ExactVector | None:
    """``c + C^{-1} u`` pulled exactly into the inner ellipsoid; returned if outside ``outer``."""
    uu = sqnorm(u)
    if uu > 1:
        r = sqrt_upper(uu, 64)
        u = [v / r for v in u]
    y = ex.point(u)
    if not _outside(outer, y):
        return None
    return _as_float_witness(ex, outer, y) or y


def _face_witness(ex: _Exact, outer: Box | Polytope, face: _Face) -> ExactVector | None:
    """Exact witness for a violated face: the maximiser of ``a^T y`` over ``E``, pulled inside."""
    if face.zz == 0:
        y = list(ex.c)
        return y if _outside(outer, y) else None
    for bits in (64, 128, 256, 1024, 4096):
        r = sqrt_upper(face.zz, bits)  # r >= ||z||, so u = z / r is in the unit ball
        if face.zz / r > face.slack:  # a^T y - b = ||z||^2 / r - slack > 0
            u = [v / r for v in face.z]
            y = ex.point(u)
            if _outside(outer, y):
                return _as_float_witness(ex, outer, y) or y
    return None


# -------------------------------------------------------------------- certificate
def _freeze_multipliers(m: Mapping[str, Any]) -> Mapping[str, tuple[Fraction, ...]]:
    out: dict[str, tuple[Fraction, ...]] = {}
    for k, v in m.items():
        vals = v if isinstance(v, (list, tuple)) else [v]
        out[str(k)] = tuple(decode_exact(x) if not isinstance(x, Fraction) else x for x in vals)
    return MappingProxyType(out)


@dataclass(frozen=True, eq=False)
class ContainmentCertificate:
    """An immutable record of one containment question and its answer.

    Parameters
    ----------
    inner : Ellipsoid
        The inner set (a batch of one).
    outer : Box, Polytope or Ellipsoid
        The outer set.
    method : Method
        How the answer was reached.
    status : Status
        PROVEN, REFUTED or UNKNOWN; only exactly-checked evidence gives the first two.
    multipliers : mapping of str to tuple of Fraction
        Method data. ``sdp``: ``{"lambda": (lam,), "tau": (tau,)}``, exact rationals
        with ``lam Q1 - Q2 + tau e e^T >= 0`` and ``tau <= 1`` for PROVEN.
        ``closed-form`` / ``socp``: ``{"support": (h_1, ..., h_m)}``, float estimates
        of ``max_{y in E} a_j^T y - a_j^T c`` (informative; :func:`verify` re-derives
        them exactly and does not read them).
    margin : float or None
        Float estimate of the slack: ``min_j (b_j - max_E a_j^T y)`` for boxes and
        polytopes (units of ``b``); for ellipsoids ``1 - tau_solver``, where ``tau_solver``
        estimates ``max_{y in E1} ||C2 (y - c2)||^2`` (the certified bound is the
        ``tau`` multiplier). ``>= 0`` when contained, up to rounding.
    witness : tuple of Fraction or None
        For REFUTED (required): an exact point inside ``inner`` and outside ``outer``.
    detail : str
        Human-readable notes (solver status, why UNKNOWN, which multipliers passed).

    Examples
    --------
    >>> import numpy as np
    >>> inner = Ellipsoid(np.zeros(1), np.eye(1))
    >>> cert = prove_containment(inner, Box([-1.0], [1.0]))
    >>> str(cert.status).split(":")[0], cert.margin
    ('PROVEN', 0.0)
    >>> certificate_from_dict(cert.to_dict()).status is Status.PROVEN
    True
    """

    inner: Ellipsoid
    outer: OuterSet
    method: Method
    status: Status
    multipliers: Mapping[str, tuple[Fraction, ...]] = field(default_factory=dict)
    margin: float | None = None
    witness: tuple[Fraction, ...] | None = None
    detail: str = ""

    def __post_init__(self) -> None:
        _single(self.inner, "certificate inner set")
        if not isinstance(self.outer, (Box, Polytope, Ellipsoid)):
            raise SetError(f"outer must be a Box, Polytope or Ellipsoid; got {type(self.outer).__name__}")
        if isinstance(self.outer, Ellipsoid):
            _single(self.outer, "certificate outer set")
        if self.outer.dim != self.inner.dim:
            raise SetError(f"outer dimension {self.outer.dim} != inner dimension {self.inner.dim}")
        method = self.method if isinstance(self.method, Method) else _parse_method(self.method, "method")
        status = self.status if isinstance(self.status, Status) else Status(self.status)
        _check_method(method, self.outer)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "status", status)
        object.__setattr__(self, "multipliers", _freeze_multipliers(self.multipliers))
        if self.margin is not None:
            m = float(self.margin)
            if not math.isfinite(m):
                raise InvalidInputError("certificate margin must be finite or None")
            object.__setattr__(self, "margin", m)
        if method is Method.SDP and status is Status.PROVEN:
            for key in ("lambda", "tau"):
                if len(self.multipliers.get(key, ())) != 1:
                    raise InvalidInputError(f"a PROVEN sdp certificate needs one '{key}' multiplier")
        if status is Status.REFUTED:
            if self.witness is None or len(self.witness) != self.inner.dim:
                raise InvalidInputError(
                    f"a REFUTED certificate needs a witness point with {self.inner.dim} coordinates"
                )
        elif self.witness is not None:
            raise InvalidInputError("only a REFUTED certificate carries a witness point")
        if self.witness is not None:
            object.__setattr__(
                self,
                "witness",
                tuple(decode_exact(v) if not isinstance(v, Fraction) else v for v in self.witness),
            )
        object.__setattr__(self, "detail", str(self.detail))

    def witness_floats(self) -> tuple[float, ...] | None:
        """The witness rounded to floats (for display; the exact point is :attr:`witness`)."""
        return None if self.witness is None else tuple(float(v) for v in self.witness)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON data; floats and rationals round-trip exactly (see :func:`encode_exact`)."""
        return {
            "status": self.status.value,
            "advice": self.status.advice,
            "method": self.method.value,
            "inner": set_to_dict(self.inner),
            "outer": set_to_dict(self.outer),
            "multipliers": {k: [encode_exact(v) for v in vs] for k, vs in self.multipliers.items()},
            "margin": self.margin,
            "witness": None if self.witness is None else [encode_exact(v) for v in self.witness],
            "detail": self.detail,
        }

    @classmethod
    def from_dict(cls, data: Any) -> ContainmentCertificate:
        """Inverse of :meth:`to_dict`; raises :class:`InvalidInputError` naming the bad field."""
        return certificate_from_dict(data)


_CERT_KEYS = {
    "status",
    "advice",
    "method",
    "inner",
    "outer",
    "multipliers",
    "margin",
    "witness",
    "detail",
}


def certificate_from_dict(data: Any) -> ContainmentCertificate:
    """Parse a certificate written by :meth:`ContainmentCertificate.to_dict`.

    Raises
    ------
    InvalidInputError
        Naming the offending field.
    """
    if not isinstance(data, Mapping):
        raise InvalidInputError("a certificate must be a JSON object")
    unknown = sorted(set(data) - _CERT_KEYS)
    if unknown:
        raise InvalidInputError(f"field '{unknown[0]}' is not part of a certificate")
    status_raw = _field(data, "status", "")
    try:
        status = Status(status_raw)
    except ValueError:
        raise InvalidInputError(
            f"field 'status': {json.dumps(status_raw)[:40]} is not PROVEN, REFUTED or UNKNOWN"
        ) from None
    method = _parse_method(_field(data, "method", ""), "method")
    inner = set_from_dict(_field(data, "inner", ""), "inner.")
    if not isinstance(inner, Ellipsoid):
        raise InvalidInputError("field 'inner.type': the inner set must be an ellipsoid")
    outer = set_from_dict(_field(data, "outer", ""), "outer.")
    mult_raw = data.get("multipliers", {})
    if not isinstance(mult_raw, Mapping):
        raise InvalidInputError("field 'multipliers': expected an object of name -> list")
    mult: dict[str, tuple[Fraction, ...]] = {}
    for k, vs in mult_raw.items():
        if not isinstance(vs, list):
            raise InvalidInputError(f"field 'multipliers.{k}': expected a list")
        try:
            mult[k] = tuple(decode_exact(v) for v in vs)
        except InvalidInputError as exc:
            raise InvalidInputError(f"field 'multipliers.{k}': {exc}") from None
    margin = data.get("margin")
    if margin is not None:
        margin = _json_number(margin, "margin")
    wit_raw = data.get("witness")
    witness = None
    if wit_raw is not None:
        if not isinstance(wit_raw, list):
            raise InvalidInputError("field 'witness': expected a list or null")
        try:
            witness = tuple(decode_exact(v) for v in wit_raw)
        except InvalidInputError as exc:
            raise InvalidInputError(f"field 'witness': {exc}") from None
    detail = data.get("detail", "")
    if not isinstance(detail, str):
        raise InvalidInputError("field 'detail': expected a string")
    if outer.dim != inner.dim:
        raise InvalidInputError(f"field 'outer': dimension {outer.dim} != inner dimension {inner.dim}")
    _check_method(method, outer)
    return ContainmentCertificate(inner, outer, method, status, mult, margin, witness, detail)


# ---------------------------------------------------------------------- verify
@dataclass(frozen=True)
class Verification:
    """Result of :func:`verify`: the status the exact check supports, and why.

    ``ok`` is false exactly when the certificate claims PROVEN or REFUTED and the
    exact check does not support that claim.
    """

    claimed: Status
    status: Status
    reason: str

    @property
    def ok(self) -> bool:
        """The claim is supported (an UNKNOWN claim is always consistent)."""
        return self.claimed is Status.UNKNOWN or self.status is self.claimed


def _check_faces(ex: _Exact, outer: Box | Polytope) -> tuple[bool, str]:
    try:
        faces = _exact_faces(ex, outer)
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


def _check_lmi(q1: ExactMatrix, q2: ExactMatrix, lam: Fraction, tau: Fraction) -> tuple[bool, str]:
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


def verify(certificate: ContainmentCertificate) -> Verification:
    """Re-check a certificate in exact rational arithmetic.

    The float data of the sets are taken as exact rationals. PROVEN claims:
    closed-form / socp re-derive ``b - a^T c >= 0`` and ``(b - a^T c)^2 >=
    ||C^{-T} a||^2`` for every face; sdp builds ``M = lam Q1 - Q2 + tau e e^T``
    exactly and tests ``lam >= 0``, ``tau <= 1`` and ``M >= 0`` (exact ``LDL^T``;
    if a pivot is not positive, an exact pivoted PSD test). REFUTED claims: the
    witness must satisfy ``||C1 (w - c1)||^2 <= 1`` and lie outside the outer set,
    exactly. Anything that fails gives UNKNOWN, never PROVEN.

    Examples
    --------
    >>> import numpy as np
    >>> ball = Ellipsoid(np.zeros(2), np.eye(2))
    >>> cert = prove_containment(ball, ball.scaled(2.0))
    >>> v = verify(cert)
    >>> v.status.name, v.ok
    ('PROVEN', True)
    """
    claimed = certificate.status
    inner = _Exact.of(certificate.inner)
    if claimed is Status.UNKNOWN:
        return Verification(claimed, Status.UNKNOWN, "the certificate claims nothing to check")
    if claimed is Status.REFUTED:
        w = list(certificate.witness or ())
        if inner.g2(w) > 1:
            return Verification(claimed, Status.UNKNOWN, "witness is not inside the inner ellipsoid")
        if not _outside(certificate.outer, w):
            return Verification(claimed, Status.UNKNOWN, "witness is not outside the outer set")
        return Verification(
            claimed,
            Status.REFUTED,
            "witness is inside the inner set and outside the outer set (exact)",
        )
    outer = certificate.outer
    if isinstance(outer, Ellipsoid):
        lam = certificate.multipliers["lambda"][0]
        tau = certificate.multipliers["tau"][0]
        ok, why = _check_lmi(inner.quadratic_form(1), _Exact.of(outer).quadratic_form(0), lam, tau)
    else:
        ok, why = _check_faces(inner, outer)
    return Verification(claimed, Status.PROVEN if ok else Status.UNKNOWN, why)


# ------------------------------------------------------------ closed form prover
def _prove_closed_form(ex: _Exact, inner: Ellipsoid, outer: Box | Polytope) -> ContainmentCertificate:
    faces = _exact_faces(ex, outer)
    support = [math.sqrt(float(f.zz)) for f in faces]
    margin = min(f.margin for f in faces)
    mult = {"support": tuple(Fraction(s) for s in support)}
    violated = [f for f in faces if not f.holds]
    if not violated:
        return ContainmentCertificate(
            inner,
            outer,
            Method.CLOSED_FORM,
            Status.PROVEN,
            mult,
            margin,
            detail=f"all {len(faces)} faces hold exactly",
        )
    violated.sort(key=lambda f: f.margin)
    for f in violated:
        w = _face_witness(ex, outer, f)
        if w is not None:
            return ContainmentCertificate(
                inner,
                outer,
                Method.CLOSED_FORM,
                Status.REFUTED,
                mult,
                margin,
                tuple(w),
                detail=f"face {f.index} is violated; witness maximises a^T y over the inner set",
            )
    return ContainmentCertificate(
        inner,
        outer,
        Method.CLOSED_FORM,
        Status.UNKNOWN,
        mult,
        margin,
        detail="a face fails exactly but no exact witness was found",
    )


# ------------------------------------------------------------------ SOCP prover
_SOCP_CACHE: dict[tuple[int, int], Any] = {}


def _socp_problem(n: int, m: int) -> Any:
    import cvxpy as cp

    key = (n, m)
    if key not in _SOCP_CACHE:
        y = cp.Variable((m, n))
        cpar = cp.Parameter((n, n))
        apar = cp.Parameter((m, n))
        # y_j = c + w_j; maximise sum_j a_j^T w_j  s.t. ||C w_j|| <= 1 (separable in j)
        cons = [cp.norm(y @ cpar.T, 2, axis=1) <= 1]
        prob = cp.Problem(cp.Maximize(cp.sum(cp.multiply(apar, y))), cons)
        _SOCP_CACHE[key] = (prob, y, cpar, apar)
    return _SOCP_CACHE[key]


def _prove_socp(ex: _Exact, inner: Ellipsoid, outer: Box | Polytope) -> ContainmentCertificate:
    import cvxpy as cp

    a, b = outer.faces()
    n, m = inner.dim, a.shape[0]
    c, cmat = inner.centers[0], inner.shapes[0]
    scale = np.linalg.norm(cmat, 2)
    prob, w, cpar, apar = _socp_problem(n, m)
    cpar.value = cmat / scale  # ||C w|| <= 1  <=>  ||(C/s) w|| <= 1/s; solve for v = w s
    anorm = np.maximum(np.linalg.norm(a, axis=1), np.finfo(float).tiny)
    apar.value = a / anorm[:, None]
    try:
        with np.errstate(all="ignore"):
            prob.solve(solver=cp.CLARABEL)
        status = prob.status
    except cp.error.SolverError as exc:
        status = f"solver error ({exc})"
    if status != cp.OPTIMAL or w.value is None:
        return ContainmentCertificate(
            inner=inner,
            outer=outer,
            method=Method.SOCP,
            status=Status.UNKNOWN,
            detail=f"Clarabel status '{status}' is not 'optimal'",
        )
    wv = np.asarray(w.value) / scale
    support = np.einsum("ji,ji->j", a / anorm[:, None], wv) * anorm
    slack = b - a @ c - support
    margin = float(slack.min())
    mult = {"support": tuple(Fraction(float(s)) for s in support)}
    tol = 1e-7 * (1.0 + np.abs(b) + np.abs(a @ c) + np.abs(support))
    ok_exact, why = _check_faces(ex, outer)
    if (slack >= -tol).all() and ok_exact:
        return ContainmentCertificate(
            inner=inner,
            outer=outer,
            method=Method.SOCP,
            status=Status.PROVEN,
            multipliers=mult,
            margin=margin,
            detail=f"Clarabel optimal; exact check: {why}",
        )
    if (slack < -tol).any():
        for j in np.argsort(slack):
            if slack[j] >= -tol[j]:
                break
            wj = exact_vector(wv[j])
            u = matvec(ex.C, wj)  # C (y - c)
            y = _witness_from_direction(ex, outer, u)
            if y is not None:
                return ContainmentCertificate(
                    inner=inner,
                    outer=outer,
                    method=Method.SOCP,
                    status=Status.REFUTED,
                    multipliers=mult,
                    margin=margin,
                    witness=tuple(y),
                    detail=f"Clarabel optimal; maximiser on face {j} checked exactly",
                )
    return ContainmentCertificate(
        inner=inner,
        outer=outer,
        method=Method.SOCP,
        status=Status.UNKNOWN,
        multipliers=mult,
        margin=margin,
        detail=f"Clarabel optimal but not decisive or contradicted by the exact check ({why})",
    )


# ------------------------------------------------------------------- SDP prover
_SDP_CACHE: dict[int, Any] = {}


def _sdp_problem(n: int) -> Any:
    """``min tau  s.t.  lam Q1n - Q2n + tau e e^T >= 0, lam >= 0`` (compiled once per n)."""
    import cvxpy as cp

    if n not in _SDP_CACHE:
        lam = cp.Variable(nonneg=True)
        tau = cp.Variable()
        q2 = cp.Parameter((n + 1, n + 1), symmetric=True)
        q1 = np.diag([1.0] * n + [-1.0])  # normalised inner set: ||u||^2 - 1
        e = np.zeros((n + 1, n + 1))
        e[n, n] = 1.0
        lmi = lam * q1 - q2 + tau * e
        prob = cp.Problem(cp.Minimize(tau), [lmi >> 0])
        assert prob.is_dpp()
        _SDP_CACHE[n] = (prob, lam, tau, q2)
    return _SDP_CACHE[n]


def _normalised(inner: Ellipsoid, outer: Ellipsoid) -> tuple[FloatArray, FloatArray]:
    """Float ``D = C2 C1^{-1}``, ``d = C1 (c2 - c1)``: the outer set in unit-ball coordinates."""
    c1, s1 = inner.centers[0], inner.shapes[0]
    c2, s2 = outer.centers[0], outer.shapes[0]
    d_mat = np.linalg.solve(s1.T, s2.T).T
    d = s1 @ (c2 - c1)
    return d_mat, d


def _q2n(d_mat: FloatArray, d: FloatArray) -> FloatArray:
    n = d.shape[0]
    f = np.hstack([d_mat, -(d_mat @ d)[:, None]])  # ||D u - D d||^2 = ||F (u, 1)||^2
    q = f.T @ f
    return 0.5 * (q + q.T) if n else q


def _trs_maximiser(d_mat: FloatArray, d: FloatArray) -> tuple[FloatArray, float]:
    """Float ``argmax_{||u|| <= 1} ||D (u - d)||^2`` and its multiplier ``mu``.

    The trust-region subproblem: with ``H = D^T D = V diag(h) V^T`` and ``a = h * V^T d``,
    the maximiser is ``u = V w`` with ``w_i = -a_i / (mu - h_i)`` where ``mu >= max h``
    solves ``sum_i a_i^2 / (mu - h_i)^2 = 1`` (bisection); ``mu`` is also the S-lemma
    multiplier ``lambda*``. If the top component of ``a`` vanishes (the "hard case"),
    ``mu = max h`` and the top eigenvector fills ``w`` up to unit length.
    """
    h_mat = d_mat.T @ d_mat
    h, v = np.linalg.eigh(0.5 * (h_mat + h_mat.T))
    e = v.T @ d
    a = h * e  # stationarity: (mu - h_i) w_i = -a_i
    hmax = float(h[-1])
    top = h >= hmax - 1e-14 * max(hmax, 1e-300)
    with np.errstate(all="ignore"):
        if np.linalg.norm(a[top]) <= 1e-15 * (np.linalg.norm(a) + 1e-300):
            rest = ~top
            gaps = hmax - h[rest]
            w = np.zeros_like(h)
            w[rest] = np.where(gaps > 0, -a[rest] / np.where(gaps > 0, gaps, 1.0), 0.0)
            r2 = float(w @ w)
            if r2 <= 1.0:  # hard case: fill the top eigenspace
                w[np.flatnonzero(top)[0]] = math.sqrt(1.0 - r2)
                return v @ w, hmax
        lo, hi = hmax, hmax + float(np.linalg.norm(a)) + 1e-300
        for _ in range(200):
            mid = 0.5 * (lo + hi)
            if mid <= lo or mid >= hi:
                break
            ww = a / (mid - h)
            if float(ww @ ww) > 1.0:
                lo = mid
            else:
                hi = mid
        w = -a / (hi - h)
    nrm = float(np.linalg.norm(w))
    if not (nrm > 0) or not np.isfinite(w).all():
        w = np.zeros_like(h)
        w[-1] = 1.0
        nrm = 1.0
    return v @ (w / nrm), hi


def _normalised_exact(ex: _Exact, outer: Ellipsoid) -> tuple[FloatArray, FloatArray]:
    """``D = C2 C1^{-1}`` and ``d = C1 (c2 - c1)`` computed exactly, then rounded once.

    Slower than :func:`_normalised` but accurate to one rounding even when ``C1``
    is ill-conditioned; used when the fast path neither proves nor refutes.
    """
    o = _Exact.of(outer)
    ci_cols = list(zip(*ex.cinv, strict=True))
    d_mat = [
        [float(sum((x * y for x, y in zip(row, col, strict=True)), Fraction(0))) for col in ci_cols]
        for row in o.C
    ]
    d = matvec(ex.C, [a - b for a, b in zip(o.c, ex.c, strict=True)])
    return np.array(d_mat, dtype=np.float64), np.array([float(v) for v in d])


def _sdp_candidates(lam: float, tau: float, lift: float) -> list[tuple[Fraction, Fraction, str]]:
    """Multipliers to try exactly: lifted solver values, then tau = 1, then snapped rationals.

    Adding ``delta`` to ``lam`` and ``2 delta`` to ``tau`` adds ``diag(delta I, delta)`` in
    unit-ball coordinates, lifting every eigenvalue of the LMI by ``delta``.
    """
    out: list[tuple[Fraction, Fraction, str]] = []
    lam_q, tau_q = Fraction(max(lam, 0.0)), Fraction(tau)
    for delta in (lift, 100.0 * lift):
        dq = Fraction(delta)
        if tau_q + 2 * dq <= 1:
            out.append((lam_q + dq, tau_q + 2 * dq, f"solver multipliers lifted by {delta:.3g}"))
    out.append((lam_q, Fraction(1), "solver lambda, tau = 1"))
    if tau_q < 1:
        dq = (1 - tau_q) / 2
        out.append((lam_q + dq, Fraction(1), "solver lambda lifted, tau = 1"))
    for den in (10**3, 10**6, 10**9):
        lam_s = lam_q.limit_denominator(den)
        for tau_s in (tau_q.limit_denominator(den), Fraction(1)):
            if tau_s <= 1:
                out.append((lam_s, tau_s, f"multipliers snapped to denominators <= {den}"))
    seen: set[tuple[Fraction, Fraction]] = set()
    uniq = []
    for lq, tq, why in out:
        if (lq, tq) not in seen and lq >= 0:
            seen.add((lq, tq))
            uniq.append((lq, tq, why))
    return uniq


def _prove_sdp(ex: _Exact, inner: Ellipsoid, outer: Ellipsoid) -> ContainmentCertificate:
    import cvxpy as cp

    n = inner.dim
    d_mat, d = _normalised(inner, outer)
    q2n = _q2n(d_mat, d)
    scale = max(1.0, float(np.abs(q2n).max()))
    prob, lam_v, tau_v, q2p = _sdp_problem(n)
    q2p.value = q2n / scale
    try:
        with np.errstate(all="ignore"):
            prob.solve(solver=cp.CLARABEL)
        status = prob.status
    except cp.error.SolverError as exc:
        status = f"solver error ({exc})"
    notes = [f"Clarabel status '{status}'"]
    lam = tau = math.nan
    q1 = ex.quadratic_form(1)
    q2 = _Exact.of(outer).quadratic_form(0)
    if status == cp.OPTIMAL and lam_v.value is not None and tau_v.value is not None:
        lam, tau = float(lam_v.value) * scale, float(tau_v.value) * scale
        q1n = np.diag([1.0] * n + [-1.0])
        e = np.zeros((n + 1, n + 1))
        e[n, n] = 1.0
        eig = float(np.linalg.eigvalsh(lam * q1n - q2n + tau * e).min())
        cond = float(np.linalg.cond(inner.shapes[0]))
        lift = 2.0 * max(0.0, -eig) + 8.0 * cond * np.finfo(float).eps * max(1.0, scale, lam, abs(tau))
        if tau <= 1.0 + 1e-6:
            for lq, tq, why in _sdp_candidates(lam, tau, lift):
                ok, how = _check_lmi(q1, q2, lq, tq)
                if ok:
                    return ContainmentCertificate(
                        inner=inner,
                        outer=outer,
                        method=Method.SDP,
                        status=Status.PROVEN,
                        multipliers={"lambda": (lq,), "tau": (tq,)},
                        margin=1.0 - tau,
                        detail=f"{notes[0]}; {why}; {how}",
                    )
            notes.append("no multiplier candidate passed the exact PSD test")
    else:
        notes.append("not 'optimal', so no proof is attempted")
    margin = None if math.isnan(tau) else 1.0 - tau
    mult = {} if math.isnan(tau) else {"lambda": (Fraction(max(lam, 0.0)),), "tau": (Fraction(tau),)}
    solver_ok = not math.isnan(tau)

    def refuted(u: FloatArray, how: str) -> ContainmentCertificate | None:
        for cand in (u, -u):
            y = _witness_from_direction(ex, outer, exact_vector(cand))
            if y is not None:
                return ContainmentCertificate(
                    inner=inner,
                    outer=outer,
                    method=Method.SDP,
                    status=Status.REFUTED,
                    multipliers=mult,
                    margin=margin,
                    witness=tuple(y),
                    detail="; ".join([*notes, how]),
                )
        return None

    u, _ = _trs_maximiser(d_mat, d)
    cert = refuted(u, "witness: trust-region maximiser, checked exactly")
    if cert is not None:
        return cert
    # slow path: normalise exactly (one rounding), re-solve the trust-region problem
    d_mat, d = _normalised_exact(ex, outer)
    u, mu = _trs_maximiser(d_mat, d)
    if solver_ok:
        for lq in (Fraction(mu), Fraction(mu) * (1 + Fraction(1, 2**40))):
            ok, how = _check_lmi(q1, q2, lq, Fraction(1))
            if ok:
                return ContainmentCertificate(
                    inner=inner,
                    outer=outer,
                    method=Method.SDP,
                    status=Status.PROVEN,
                    multipliers={"lambda": (lq,), "tau": (Fraction(1),)},
                    margin=margin,
                    detail=f"{notes[0]}; lambda refined by the trust-region secular equation, tau = 1; {how}",
                )
    cert = refuted(u, "witness: trust-region maximiser of the exactly normalised problem")
    if cert is not None:
        return cert
    notes.append("no exact witness found")
    return ContainmentCertificate(
        inner=inner,
        outer=outer,
        method=Method.SDP,
        status=Status.UNKNOWN,
        multipliers=mult,
        margin=margin,
        detail="; ".join(notes),
    )


# ------------------------------------------------------------------ dispatchers
def _default_method(outer: OuterSet) -> Method:
    return Method.SDP if isinstance(outer, Ellipsoid) else Method.CLOSED_FORM


def prove_containment(
    inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None
) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` and return a certificate.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid (batch of one).
    outer : Box, Polytope or Ellipsoid
        The outer set (an ellipsoid must be a batch of one).
    method : Method or str, optional
        ``"closed-form"`` (default for boxes/polytopes), ``"socp"`` (cross-check) or
        ``"sdp"`` (the only method, and default, for ellipsoids).

    Returns
    -------
    ContainmentCertificate
        PROVEN and REFUTED are decided by exact checks (see :func:`verify`).

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros(2), np.eye(2))
    >>> prove_containment(e, Polytope([[1.0, 1.0]], [1.5])).status.name
    'PROVEN'
    """
    inner = _single(inner, "inner")
    if not isinstance(outer, (Box, Polytope, Ellipsoid)):
        raise SetError(f"outer must be a Box, Polytope or Ellipsoid; got {type(outer).__name__}")
    if outer.dim != inner.dim:
        raise SetError(f"outer dimension {outer.dim} != inner dimension {inner.dim}")
    m = (
        _default_method(outer)
        if method is None
        else _parse_method(method.value if isinstance(method, Method) else method, "method")
    )
    _check_method(m, outer)
    ex = _Exact.of(inner)
    if isinstance(outer, Ellipsoid):
        return _prove_sdp(ex, inner, _single(outer, "outer"))
    if m is Method.SOCP:
        return _prove_socp(ex, inner, outer)
    return _prove_closed_form(ex, inner, outer)


def prove_containment_batch(
    inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None
) -> list[ContainmentCertificate]:
    """Exact certificates for every ellipsoid of a batch against one outer set.

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> [c.status.name for c in prove_containment_batch(e, Box([-1.0], [1.0]))]
    ['PROVEN', 'REFUTED']
    """
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid batch")
    return [prove_containment(inner[i], outer, method=method) for i in range(inner.batch_size)]
