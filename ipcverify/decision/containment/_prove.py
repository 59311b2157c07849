"""One entry point for containment proofs: :func:`prove` (and :func:`prove_batch`).

``prove(inner, outer, method=...)`` dispatches to the closed-form prover (boxes and
polytopes, the default and the decision of record), the SOCP cross-check, or the S-lemma
SDP (ellipsoids, where it is the only method; boxes and polytopes, one LMI per face, as an
independent second route).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._closed_form import prove_closed_form
from ipcverify.decision.containment._face_sdp import prove_sdp_faces
from ipcverify.decision.containment._geometry import ExactEllipsoid
from ipcverify.decision.containment._sdp import prove_sdp
from ipcverify.decision.containment._socp import prove_socp
from ipcverify.decision.containment._status import Method, check_method, default_method, parse_method
from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid, single_ellipsoid
from ipcverify.sets._outer import OuterSet

#: The prover of each proof form (:attr:`ipcverify.sets.OuterSet.proof_form`) and method.
_PROVERS: dict[tuple[str, Method], Callable[[Ellipsoid, Any, ExactEllipsoid], ContainmentCertificate]] = {
    ("faces", Method.CLOSED_FORM): prove_closed_form,
    ("faces", Method.SOCP): prove_socp,
    ("faces", Method.SDP): prove_sdp_faces,
    ("ellipsoid", Method.SDP): prove_sdp,
}


def prove(inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` and return a certificate.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid (batch of one).
    outer : OuterSet
        The outer set: a Box, Polytope or Ellipsoid (a batch of one), or any
        :class:`~ipcverify.sets.OuterSet`; its ``proof_form`` and the method choose the prover.
    method : Method or str, optional
        ``"closed-form"`` (default for boxes/polytopes: exact, never UNKNOWN), ``"socp"``
        (cross-check) or ``"sdp"`` (the only method, and default, for ellipsoids; for boxes and
        polytopes the per-face S-lemma, :func:`~ipcverify.decision.containment.prove_sdp_faces`).

    Returns
    -------
    ContainmentCertificate
        PROVEN and REFUTED are decided by exact checks (see :func:`verify`).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box, Polytope
    >>> e = Ellipsoid(np.zeros(2), np.eye(2))
    >>> prove(e, Polytope([[1.0, 1.0]], [1.5])).status.name
    'PROVEN'
    >>> cert = prove(e, Box([-1.0, -1.0], [1.0, 1.0]), method="sdp")   # touching: still PROVEN
    >>> cert.method.value, cert.status.name, len(cert.multipliers["lambda"])
    ('sdp', 'PROVEN', 4)
    """
    inner = single_ellipsoid(inner, "inner")
    if not isinstance(outer, OuterSet):
        raise SetError(f"outer must be a Box, Polytope or Ellipsoid; got {type(outer).__name__}")
    if outer.dim != inner.dim:
        raise SetError(f"outer dimension {outer.dim} != inner dimension {inner.dim}")
    m = (
        default_method(outer)
        if method is None
        else parse_method(method.value if isinstance(method, Method) else method, "method")
    )
    check_method(m, outer)
    prover = _PROVERS.get((outer.proof_form, m))
    if prover is None:
        raise SetError(f"no {m.value} prover for sets of proof form '{outer.proof_form}'")
    return prover(inner, outer.as_outer("outer"), ExactEllipsoid.of(inner))


def prove_batch(
    inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None
) -> list[ContainmentCertificate]:
    """Exact certificates for every ellipsoid of a batch against one outer set.

    Parameters
    ----------
    inner : Ellipsoid
        A batch of ellipsoids; certificate ``i`` is about ``inner[i]``.
    outer : OuterSet
        The outer set, as for :func:`prove`.
    method : Method or str, optional
        As for :func:`prove` (the same method for every ellipsoid).

    Examples
    --------
    >>> import numpy as np
    >>> from ipcverify.sets import Box
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> [c.status.name for c in prove_batch(e, Box([-1.0], [1.0]))]
    ['PROVEN', 'REFUTED']
    """
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid batch")
    return [prove(inner[i], outer, method=method) for i in range(inner.batch_size)]
