"""One entry point for containment proofs: :func:`prove` (and :func:`prove_batch`).

``prove(inner, outer, method=...)`` dispatches to the closed-form prover (boxes and
polytopes, the default and the decision of record), the SOCP cross-check, or the S-lemma
SDP (ellipsoids, where it is the only method; boxes and polytopes, one LMI per face, as an
independent second route).
"""

from __future__ import annotations

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._closed_form import prove_closed_form
from ipcverify.decision.containment._face_sdp import prove_sdp_faces
from ipcverify.decision.containment._geometry import ExactEllipsoid
from ipcverify.decision.containment._sdp import prove_sdp
from ipcverify.decision.containment._socp import prove_socp
from ipcverify.decision.containment._status import Method, check_method, default_method, parse_method
from ipcverify.errors import SetError
from ipcverify.sets._shapes import Box, Ellipsoid, OuterSet, Polytope, single_ellipsoid

__all__ = ["prove", "prove_batch"]


def prove(inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` and return a certificate.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid (batch of one).
    outer : Box, Polytope or Ellipsoid
        The outer set (an ellipsoid must be a batch of one).
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
    >>> e = Ellipsoid(np.zeros(2), np.eye(2))
    >>> prove(e, Polytope([[1.0, 1.0]], [1.5])).status.name
    'PROVEN'
    >>> cert = prove(e, Box([-1.0, -1.0], [1.0, 1.0]), method="sdp")   # touching: still PROVEN
    >>> cert.method.value, cert.status.name, len(cert.multipliers["lambda"])
    ('sdp', 'PROVEN', 4)
    """
    inner = single_ellipsoid(inner, "inner")
    if not isinstance(outer, (Box, Polytope, Ellipsoid)):
        raise SetError(f"outer must be a Box, Polytope or Ellipsoid; got {type(outer).__name__}")
    if outer.dim != inner.dim:
        raise SetError(f"outer dimension {outer.dim} != inner dimension {inner.dim}")
    m = (
        default_method(outer)
        if method is None
        else parse_method(method.value if isinstance(method, Method) else method, "method")
    )
    check_method(m, outer)
    ex = ExactEllipsoid.of(inner)
    if isinstance(outer, Ellipsoid):
        return prove_sdp(inner, single_ellipsoid(outer, "outer"), ex)
    if m is Method.SOCP:
        return prove_socp(inner, outer, ex)
    if m is Method.SDP:
        return prove_sdp_faces(inner, outer, ex)
    return prove_closed_form(inner, outer, ex)


def prove_batch(
    inner: Ellipsoid, outer: OuterSet, *, method: Method | str | None = None
) -> list[ContainmentCertificate]:
    """Exact certificates for every ellipsoid of a batch against one outer set.

    Examples
    --------
    >>> import numpy as np
    >>> e = Ellipsoid(np.zeros((2, 1)), np.array([[[2.0]], [[0.5]]]))
    >>> [c.status.name for c in prove_batch(e, Box([-1.0], [1.0]))]
    ['PROVEN', 'REFUTED']
    """
    if not isinstance(inner, Ellipsoid):
        raise SetError("inner must be an Ellipsoid batch")
    return [prove(inner[i], outer, method=method) for i in range(inner.batch_size)]
