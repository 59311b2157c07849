"""Containment certificates: the record of one question and its answer, and its exact re-check.

A :class:`ContainmentCertificate` says PROVEN, REFUTED (with an exact witness point) or
UNKNOWN. :func:`verify` re-checks any certificate in exact rational arithmetic,
independently of the float code and of any solver: a certificate is PROVEN only if that
check passes; REFUTED carries a witness point (exact rationals) that is inside the inner
set and outside the outer one; anything else is UNKNOWN.

Examples
--------
>>> import numpy as np
>>> from ipcverify.decision.containment import prove
>>> from ipcverify.sets import Box, Ellipsoid
>>> cert = prove(Ellipsoid(np.zeros(1), np.eye(1)), Box([-1.0], [1.0]))
>>> verify(cert).status.name
'PROVEN'
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from fractions import Fraction
from types import MappingProxyType
from typing import Any, cast

from ipcverify.decision.containment._face_lmi import check_face_lmis
from ipcverify.decision.containment._geometry import ExactEllipsoid, check_faces, check_lmi, is_outside
from ipcverify.decision.containment._io import set_from_dict, set_to_dict
from ipcverify.decision.containment._status import Method, Status, check_method, parse_method
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.sets._ellipsoid import Ellipsoid, single_ellipsoid
from ipcverify.sets._exact import decode_exact, encode_exact
from ipcverify.sets._faces import FacedSet
from ipcverify.sets._json import json_field, json_number
from ipcverify.sets._outer import OuterSet


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
    outer : OuterSet
        The outer set (a Box, Polytope or Ellipsoid, or any :class:`~ipcverify.sets.OuterSet`).
    method : Method
        How the answer was reached.
    status : Status
        PROVEN, REFUTED or UNKNOWN; only exactly-checked evidence gives the first two.
    multipliers : mapping of str to tuple of Fraction
        Method data. ``sdp`` against an ellipsoid: ``{"lambda": (lam,), "tau": (tau,)}``, exact
        rationals with ``lam Q1 - Q2 + tau e e^T >= 0`` and ``tau <= 1`` for PROVEN. ``sdp``
        against a box or polytope: ``{"lambda": (lam_1, ..., lam_m)}``, one per face (in the
        order of ``outer.faces()``) with ``[[lam_j A, -a_j/2], [-a_j^T/2, b_j - a_j^T c - lam_j]]
        >= 0`` for PROVEN.
        ``closed-form`` / ``socp``: ``{"support": (h_1, ..., h_m)}``, float estimates
        of ``max_{y in E} a_j^T y - a_j^T c`` (informative; :func:`verify` re-derives
        them exactly and does not read them).
    margin : float or None
        Float estimate of the slack: ``min_j (b_j - max_E a_j^T y)`` for boxes and
        polytopes (units of ``b``; by the ``sdp`` method, the solver's estimate); for
        ellipsoids ``1 - tau_solver``, where ``tau_solver``
        estimates ``max_{y in E1} ||C2 (y - c2)||^2`` (the certified bound is the
        ``tau`` multiplier). ``>= 0`` when contained, up to rounding.
    witness : tuple of Fraction or None
        For REFUTED (required): an exact point inside ``inner`` and outside ``outer``.
    detail : str
        Human-readable notes (solver status, why UNKNOWN, which multipliers passed).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.decision.containment import prove
    >>> from ipcverify.sets import Box
    >>> inner = Ellipsoid(np.zeros(1), np.eye(1))
    >>> cert = prove(inner, Box([-1.0], [1.0]))
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
        single_ellipsoid(self.inner, "certificate inner set")
        if not isinstance(self.outer, OuterSet):
            raise SetError(f"outer must be a Box, Polytope or Ellipsoid; got {type(self.outer).__name__}")
        self.outer.as_outer("certificate outer set")
        if self.outer.dim != self.inner.dim:
            raise SetError(f"outer dimension {self.outer.dim} != inner dimension {self.inner.dim}")
        method = self.method if isinstance(self.method, Method) else parse_method(self.method, "method")
        status = self.status if isinstance(self.status, Status) else Status(self.status)
        check_method(method, self.outer)
        object.__setattr__(self, "method", method)
        object.__setattr__(self, "status", status)
        object.__setattr__(self, "multipliers", _freeze_multipliers(self.multipliers))
        if self.margin is not None:
            m = float(self.margin)
            if not math.isfinite(m):
                raise InvalidInputError("certificate margin must be finite or None")
            object.__setattr__(self, "margin", m)
        if method is Method.SDP and status is Status.PROVEN:
            _SDP_MULTIPLIERS[self.outer.proof_form](self.outer, self.multipliers)
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


#: The ``format`` of ``certify``'s certificate.json (ipcverify.certification), a file users hand to
#: check-certificate by mistake.
_CERTIFY_FORMAT = "ipcverify-certificate"
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

    Parameters
    ----------
    data : mapping
        The certificate's JSON object (as read by :func:`json.load`); unknown fields, a missing
        field, a status other than PROVEN / REFUTED / UNKNOWN or a method the outer set does not
        admit are refused.

    Raises
    ------
    InvalidInputError
        Naming the offending field.
    """
    if not isinstance(data, Mapping):
        raise InvalidInputError("a certificate must be a JSON object")
    if data.get("format") == _CERTIFY_FORMAT:
        raise InvalidInputError(
            "this is the calibration certificate `ipcverify certify` writes (certificate.json), not a "
            "containment certificate; check-certificate re-verifies the certificates `ipcverify "
            "prove-containment` writes (to check a model's certificate, run `ipcverify certify` again)"
        )
    unknown = sorted(set(data) - _CERT_KEYS)
    if unknown:
        raise InvalidInputError(f"field '{unknown[0]}' is not part of a certificate")
    status_raw = json_field(data, "status", "")
    try:
        status = Status(status_raw)
    except ValueError:
        raise InvalidInputError(
            f"field 'status': {json.dumps(status_raw)[:40]} is not PROVEN, REFUTED or UNKNOWN"
        ) from None
    method = parse_method(json_field(data, "method", ""), "method")
    inner = set_from_dict(json_field(data, "inner", ""), "inner.")
    if not isinstance(inner, Ellipsoid):
        raise InvalidInputError("field 'inner.type': the inner set must be an ellipsoid")
    outer = set_from_dict(json_field(data, "outer", ""), "outer.")
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
        margin = json_number(margin, "margin")
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
    check_method(method, outer)
    return ContainmentCertificate(inner, outer, method, status, mult, margin, witness, detail)


@dataclass(frozen=True)
class Verification:
    """Result of :func:`verify`: the status the exact check supports, and why.

    ``ok`` is false exactly when the certificate claims PROVEN or REFUTED and the
    exact check does not support that claim.

    Attributes
    ----------
    claimed : Status
        The status the certificate claims.
    status : Status
        The status the exact re-check supports: the claim, or UNKNOWN (never PROVEN or REFUTED
        without exact evidence).
    reason : str
        Why, in words (which check held, or the first that failed).
    """

    claimed: Status
    status: Status
    reason: str

    @property
    def ok(self) -> bool:
        """The claim is supported (an UNKNOWN claim is always consistent)."""
        return self.claimed is Status.UNKNOWN or self.status is self.claimed


def verify(certificate: ContainmentCertificate) -> Verification:
    """Re-check a certificate in exact rational arithmetic.

    The float data of the sets are taken as exact rationals. PROVEN claims:
    closed-form / socp re-derive ``b - a^T c >= 0`` and ``(b - a^T c)^2 >=
    ||C^{-T} a||^2`` for every face; sdp builds ``M = lam Q1 - Q2 + tau e e^T``
    exactly and tests ``lam >= 0``, ``tau <= 1`` and ``M >= 0`` (exact ``LDL^T``;
    if a pivot is not positive, an exact pivoted PSD test); sdp against a box or polytope
    tests every face LMI the same way, in integers
    (:func:`~ipcverify.decision.containment.check_face_lmis`). REFUTED claims: the
    witness must satisfy ``||C1 (w - c1)||^2 <= 1`` and lie outside the outer set,
    exactly. Anything that fails gives UNKNOWN, never PROVEN.

    Parameters
    ----------
    certificate : ContainmentCertificate
        The certificate to re-check; its float data are read as exact rationals.

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.decision.containment import prove
    >>> ball = Ellipsoid(np.zeros(2), np.eye(2))
    >>> cert = prove(ball, ball.scaled(2.0))
    >>> v = verify(cert)
    >>> v.status.name, v.ok
    ('PROVEN', True)
    """
    claimed = certificate.status
    inner = ExactEllipsoid.of(certificate.inner)
    if claimed is Status.UNKNOWN:
        return Verification(claimed, Status.UNKNOWN, "the certificate claims nothing to check")
    if claimed is Status.REFUTED:
        w = list(certificate.witness or ())
        if inner.g2(w) > 1:
            return Verification(claimed, Status.UNKNOWN, "witness is not inside the inner ellipsoid")
        if not is_outside(certificate.outer, w):
            return Verification(claimed, Status.UNKNOWN, "witness is not outside the outer set")
        return Verification(
            claimed,
            Status.REFUTED,
            "witness is inside the inner set and outside the outer set (exact)",
        )
    ok, why = _PROOF_CHECKS[(certificate.outer.proof_form, certificate.method)](certificate, inner)
    return Verification(claimed, Status.PROVEN if ok else Status.UNKNOWN, why)


def _ellipsoid_sdp_multipliers(outer: OuterSet, multipliers: Mapping[str, tuple[Fraction, ...]]) -> None:
    for key in ("lambda", "tau"):
        if len(multipliers.get(key, ())) != 1:
            raise InvalidInputError(f"a PROVEN sdp certificate needs one '{key}' multiplier")


def _face_sdp_multipliers(outer: OuterSet, multipliers: Mapping[str, tuple[Fraction, ...]]) -> None:
    faces = cast(FacedSet, outer).faces()[1].shape[0]
    if len(multipliers.get("lambda", ())) != faces:
        raise InvalidInputError(
            f"a PROVEN sdp certificate for a {type(outer).__name__.lower()} needs one "
            f"'lambda' multiplier per face ({faces})"
        )


#: The multipliers a PROVEN sdp certificate must carry, per proof form.
_SDP_MULTIPLIERS: dict[str, Callable[[OuterSet, Mapping[str, tuple[Fraction, ...]]], None]] = {
    "ellipsoid": _ellipsoid_sdp_multipliers,
    "faces": _face_sdp_multipliers,
}


def _check_ellipsoid_lmi(certificate: ContainmentCertificate, inner: ExactEllipsoid) -> tuple[bool, str]:
    lam = certificate.multipliers["lambda"][0]
    tau = certificate.multipliers["tau"][0]
    outer = ExactEllipsoid.of(cast(Ellipsoid, certificate.outer))
    return check_lmi(inner.quadratic_form(1), outer.quadratic_form(0), lam, tau)


def _check_face_lmis(certificate: ContainmentCertificate, inner: ExactEllipsoid) -> tuple[bool, str]:
    outer = cast(FacedSet, certificate.outer)
    return check_face_lmis(certificate.inner, outer, certificate.multipliers["lambda"])


def _check_faces(certificate: ContainmentCertificate, inner: ExactEllipsoid) -> tuple[bool, str]:
    return check_faces(inner, cast(FacedSet, certificate.outer))


#: The exact re-check of a PROVEN claim, per proof form and method.
_Check = Callable[[ContainmentCertificate, ExactEllipsoid], tuple[bool, str]]
_PROOF_CHECKS: dict[tuple[str, Method], _Check] = {
    ("ellipsoid", Method.SDP): _check_ellipsoid_lmi,
    ("faces", Method.SDP): _check_face_lmis,
    ("faces", Method.CLOSED_FORM): _check_faces,
    ("faces", Method.SOCP): _check_faces,
}
