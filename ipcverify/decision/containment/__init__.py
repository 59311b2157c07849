"""Proofs that an ellipsoid lies inside a box, a polytope or another ellipsoid.

Three provers behind one function, one certificate type, one exact checker; one module
per job:

* :mod:`~ipcverify.decision.containment._status` -- :class:`Status` and :class:`Method`;
* :mod:`~ipcverify.decision.containment._certificate` -- :class:`ContainmentCertificate` and its exact
  re-check :func:`verify`;
* :mod:`~ipcverify.decision.containment._geometry` -- exact rational geometry and witnesses;
* :mod:`~ipcverify.decision.containment._io` -- the JSON formats of sets and problems;
* :mod:`~ipcverify.decision.containment._margin` -- float slacks for whole batches (not proofs);
* :mod:`~ipcverify.decision.containment._rounding` -- the same slacks with rigorous rounding bounds
  (a slack beyond its bound is a proof; the closed form tries them first);
* :mod:`~ipcverify.decision.containment._closed_form`, :mod:`~ipcverify.decision.containment._socp`,
  :mod:`~ipcverify.decision.containment._sdp`,
  :mod:`~ipcverify.decision.containment._face_sdp` -- the provers,
  behind :func:`prove`; :mod:`~ipcverify.decision.containment._face_lmi` -- the exact check of the
  per-face S-lemma certificates.

The set types themselves live in :mod:`ipcverify.sets`, one module per shape; the provers ask
the outer set, through :class:`ipcverify.sets.OuterSet` (and :class:`ipcverify.sets.FacedSet` for
sets given by faces), for what depends on its shape: its JSON form, the methods that apply, its
proof form (faces or an ellipsoid), its face offsets, slacks and rounding bounds, and its exact
faces and membership. A new shape is one module (``docs/containment.md``).

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
* **SDP** (box, polytope; ``method="sdp"``): one S-lemma LMI per face,
  ``[[lam_j A, -a_j/2], [-a_j^T/2, b_j - a_j^T c - lam_j]] >= 0``, solved together by
  Clarabel; each multiplier passes an exact integer definiteness test. An independent
  second route: the closed form stays the default and the decision of record.

:func:`verify` re-checks any certificate in exact arithmetic, independently of the
float code and of the solver. A certificate is PROVEN only if that check passes;
REFUTED carries a witness point (exact rationals) that is inside the inner set and
outside the outer one; anything else is UNKNOWN.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> inner = Ellipsoid(np.zeros(2), np.diag([2.0, 4.0]))     # semi-axes 0.5, 0.25
>>> cert = prove(inner, Box([-0.5, -0.25], [0.5, 0.25]))
>>> cert.status.name, verify(cert).status.name
('PROVEN', 'PROVEN')
>>> cert = prove(inner, Box([-0.4, -1.0], [0.4, 1.0]))
>>> cert.status.name, cert.witness_floats()
('REFUTED', (0.5, 0.0))
>>> sdp = prove(inner, Box([-0.5, -0.25], [0.5, 0.25]), method="sdp")   # the second route
>>> sdp.status.name, verify(sdp).status.name
('PROVEN', 'PROVEN')
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ipcverify._package import lazy_exports

if TYPE_CHECKING:
    from ipcverify.decision.containment._certificate import verify
    from ipcverify.decision.containment._prove import prove
    from ipcverify.decision.containment._status import Status

__all__ = [
    "Status",
    "prove",
    "verify",
]

__getattr__, __dir__ = lazy_exports(__name__, __file__)
