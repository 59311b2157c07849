"""Proposition 1 of the paper as code: the exact landing decision and its certificate.

The IPC returns an ellipsoid ``E`` that contains the landing pad's true position
``y`` with high probability. The landing state machine accepts the measurement
only if ``E`` fits the target box ``G`` (the paper's is ``[-0.05, 0.05]^2 x [0, 0.05]``;
the caller passes its own, e.g. the case study's); it then flies to the turn-off point
``P = [mid_x, mid_y, z_max]`` of ``E``'s bounding box, and Proposition 1 says
``P in {y} + G`` for every ``y in E``.

:func:`landing_decision` proves exactly the statement the controller relies on,
``P - y in G`` for all ``y in E``, i.e. ``E`` is inside the box ``{P} + (-G) =
[P - G.upper, P - G.lower]``, and accepts only if that proof is PROVEN. The proof
is in ``proofs/proposition1.md``. The decision of record, which reaches the same answer in
float64 with a rigorous rounding bound, is :class:`ipcverify.decision.LandingRule`
(:mod:`ipcverify.decision._landing`); the float rule alone is :mod:`ipcverify.decision._landing_float`.

Rounding is handled so that the float ``P`` makes the statement true, not just a
nearby real point: ``mid_x`` and ``mid_y`` of the exact bounding box are the centre's
coordinates (floats already), and ``z_max = c_z + sqrt(P_zz)`` is irrational, so
``P_z`` is rounded *upward* to a float (checked exactly). The outer box
``[P - G.upper, P - G.lower]`` is rounded *inward* to floats, so the certified box
lies inside the exact one.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
>>> e = Ellipsoid([1.0, 2.0, 0.3], np.diag([40.0, 40.0, 80.0]))  # semi-axes .025,.025,.0125
>>> d = landing_decision(e, G)
>>> d.accept, d.turnoff.tolist(), d.certificate.status.name
(True, [1.0, 2.0, 0.3125], 'PROVEN')
>>> landing_decision(e.scaled(3.0), G).accept   # 0.15 wide: too uncertain, take another look
False
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ipcverify.decision.containment._certificate import ContainmentCertificate, Verification, verify
from ipcverify.decision.containment._closed_form import prove_closed_form
from ipcverify.decision.containment._geometry import ExactEllipsoid
from ipcverify.decision.containment._status import Status
from ipcverify.errors import SetError
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import exact_vector, float_down, float_up, sqnorm, sqrt_upper

FloatArray = NDArray[np.float64]


def _check_ellipsoid(ellipsoid: Ellipsoid) -> None:
    if not isinstance(ellipsoid, Ellipsoid) or ellipsoid.batch_size != 1 or ellipsoid.dim != 3:
        raise SetError(
            "landing needs a single 3-D ellipsoid (batch of 1, n = 3); for batches use "
            "landing_accept_float or call landing_decision per ellipsoid"
        )


def check_target(target: Box) -> None:
    if not isinstance(target, Box) or target.dim != 3:
        raise SetError("the target G must be a 3-D Box")
    if not (target.lower < target.upper).all():
        raise SetError("the target G must have positive width in every coordinate")


def _turnoff(ex: ExactEllipsoid) -> FloatArray:
    """``[c_x, c_y, z_max rounded up]`` with ``(P_z - c_z)^2 >= ||row z of C^{-1}||^2`` exactly."""
    hz2 = sqnorm(ex.cinv[2])  # squared half-height P_zz
    pz = float_up(ex.c[2] + sqrt_upper(hz2, 64))
    return np.array([float(ex.c[0]), float(ex.c[1]), pz])


def turnoff_point(ellipsoid: Ellipsoid) -> FloatArray:
    """The turn-off point ``P = [mid_x, mid_y, z_max]`` of the ellipsoid's bounding box.

    ``mid_x = c_x`` and ``mid_y = c_y`` exactly; ``P_z`` is the smallest float found
    ``>= z_max = c_z + sqrt((C^T C)^{-1}_zz)`` (rounded upward, never below).

    Parameters
    ----------
    ellipsoid : Ellipsoid
        One 3-D ellipsoid ``E(c, C)`` (a batch of 1); anything else raises :class:`SetError`.

    Examples
    --------
    >>> import numpy as np
    >>> turnoff_point(Ellipsoid(np.zeros(3), np.diag([1.0, 1.0, 4.0]))).tolist()
    [0.0, 0.0, 0.25]
    """
    _check_ellipsoid(ellipsoid)
    return _turnoff(ExactEllipsoid.of(ellipsoid))


def _offset_box(p: FloatArray, target: Box) -> Box:
    """``[P - G.upper, P - G.lower]`` rounded inward to floats (a subset of the exact box)."""
    pq, gl, gu = exact_vector(p), exact_vector(target.lower), exact_vector(target.upper)
    lower = [float_up(a - b) for a, b in zip(pq, gu, strict=True)]
    upper = [float_down(a - b) for a, b in zip(pq, gl, strict=True)]
    if any(lo > up for lo, up in zip(lower, upper, strict=True)):
        raise SetError(
            "the box {P} + (-G) is narrower than one float spacing at the turn-off point; "
            "G is too small for coordinates of this magnitude"
        )
    return Box(np.asarray(lower, dtype=np.float64), np.asarray(upper, dtype=np.float64))


@dataclass(frozen=True, eq=False)
class LandingDecision:
    """What the landing state machine needs after one measurement.

    Parameters
    ----------
    accept : bool
        True iff the certificate is PROVEN: switch to ``Landing`` and fly to
        ``turnoff``. False: go to ``New Waypoint`` and measure again.
    turnoff : ndarray, shape (3,)
        The turn-off point ``P`` (defined even when not accepted).
    certificate : ContainmentCertificate
        ``E ⊆ [P - G.upper, P - G.lower]`` (closed form, decided exactly); its outer
        box is rounded inward, so it lies inside ``{P} + (-G)``.
    target : Box
        The target region ``G``.
    """

    accept: bool
    turnoff: FloatArray
    certificate: ContainmentCertificate
    target: Box

    def __post_init__(self) -> None:
        p = np.array(self.turnoff, dtype=np.float64, copy=True)
        if p.shape != (3,) or not np.isfinite(p).all():
            raise SetError("turnoff must be 3 finite numbers")
        p.setflags(write=False)
        object.__setattr__(self, "turnoff", p)
        if bool(self.accept) != (self.certificate.status is Status.PROVEN):
            raise SetError("accept must be True exactly when the certificate is PROVEN")
        object.__setattr__(self, "accept", bool(self.accept))


def landing_decision(ellipsoid: Ellipsoid, target: Box) -> LandingDecision:
    """Decide, with an exact certificate, whether to land on this measurement.

    Call once per measurement with the IPC's ellipsoid (about a millisecond for
    ``n = 3``: one exact 3x3 inverse and six exact face checks).

    Parameters
    ----------
    ellipsoid : Ellipsoid
        One 3-D ellipsoid ``E(c, C)`` from the IPC.
    target : Box
        The target region ``G`` (3-D, positive width in every coordinate).

    Returns
    -------
    LandingDecision
        ``accept`` is True only if ``P - y in G`` is PROVEN for every ``y in E``.

    Examples
    --------
    >>> import numpy as np
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> d = landing_decision(Ellipsoid(np.zeros(3), np.diag([20.0, 20.0, 40.0])), G)
    >>> d.accept, d.certificate.margin >= 0
    (True, True)
    """
    _check_ellipsoid(ellipsoid)
    check_target(target)
    ex = ExactEllipsoid.of(ellipsoid)
    p = _turnoff(ex)
    cert = prove_closed_form(ellipsoid, _offset_box(p, target), ex, fast=False)
    return LandingDecision(cert.status is Status.PROVEN, p, cert, target)


def check_landing(decision: LandingDecision) -> Verification:
    """Re-check a decision exactly: the certificate, and that its box lies in ``{P} + (-G)``.

    An accepted decision re-verifies as PROVEN only if :func:`verify` proves the
    certificate and ``box.lower >= P - G.upper``, ``box.upper <= P - G.lower`` hold
    exactly, and the certificate's inner set is the decision's ellipsoid.

    Parameters
    ----------
    decision : LandingDecision
        A decision of :func:`landing_decision` (or one read back from a file). A rejected
        decision, or one whose certificate's outer set is not a box or not inside
        ``{P} + (-G)``, re-verifies as what :func:`verify` says or as UNKNOWN, never PROVEN.

    Examples
    --------
    >>> import numpy as np
    >>> G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])
    >>> d = landing_decision(Ellipsoid(np.zeros(3), np.diag([20.0, 20.0, 40.0])), G)
    >>> check_landing(d).status.name
    'PROVEN'
    """
    cert = decision.certificate
    v = verify(cert)
    if v.status is not Status.PROVEN:
        return v
    try:
        box = _certified_box(cert)
    except SetError as exc:
        return Verification(cert.status, Status.UNKNOWN, str(exc))
    pq = exact_vector(decision.turnoff)
    gl, gu = exact_vector(decision.target.lower), exact_vector(decision.target.upper)
    lo, up = exact_vector(box.lower), exact_vector(box.upper)
    for i in range(3):
        if lo[i] < pq[i] - gu[i] or up[i] > pq[i] - gl[i]:
            return Verification(
                cert.status, Status.UNKNOWN, f"coordinate {i}: the box is not inside {{P}} + (-G)"
            )
    return Verification(cert.status, Status.PROVEN, v.reason + "; box inside {P} + (-G) exactly")


def _certified_box(cert: ContainmentCertificate) -> Box:
    """The certificate's outer set, which a landing certificate requires to be a box."""
    if not isinstance(cert.outer, Box):
        raise SetError("the certificate's outer set is not a box")
    return cert.outer
