"""The closed-form prover for boxes and polytopes, decided exactly.

``E(c, C)`` is inside ``{y : A y <= b}`` iff ``b_j - a_j^T c >= 0`` and
``(b_j - a_j^T c)^2 >= ||C^{-T} a_j||^2`` for every face ``j`` (``proofs/containment.md``);
both are evaluated in exact rational arithmetic. A violated face gives an exact witness:
the maximiser of ``a_j^T y`` over the inner set, pulled inside it.

Examples
--------
>>> import numpy as np
>>> from ipcverify.sets import Box, Ellipsoid
>>> prove_closed_form(Ellipsoid(np.zeros(1), np.eye(1)), Box([-0.5], [2.0])).witness_floats()
(-1.0,)
"""

from __future__ import annotations

import math
from fractions import Fraction
from functools import partial

from ipcverify.decision.containment._certificate import ContainmentCertificate
from ipcverify.decision.containment._geometry import ExactEllipsoid, exact_faces, face_witness
from ipcverify.decision.containment._rounding import support_slack_bounds
from ipcverify.decision.containment._status import Method, Status
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._exact import sqrt_upper
from ipcverify.sets._faces import FacedSet


def prove_closed_form(
    inner: Ellipsoid, outer: FacedSet, exact: ExactEllipsoid | None = None, *, fast: bool = True
) -> ContainmentCertificate:
    """Prove or refute ``inner ⊆ outer`` for a box or polytope, exactly.

    Parameters
    ----------
    inner : Ellipsoid
        A single ellipsoid.
    outer : FacedSet
        The outer set: a Box, a Polytope or any set given by faces.
    exact : ExactEllipsoid, optional
        ``inner`` in exact arithmetic, if the caller already has it (saves one exact inverse).
    fast : bool
        Try the float margins with rigorous rounding bounds first (a PROVEN answer needs no
        exact inverse); False decides in exact arithmetic only.
    """
    answer = partial(ContainmentCertificate, inner, outer, Method.CLOSED_FORM)
    if fast:
        fb = support_slack_bounds(inner, outer)
        if bool(fb.proven()[0]):
            slack = fb.slack[0]
            support = [s - m for s, m in zip(_face_sigma(inner, outer), slack.tolist(), strict=True)]
            return answer(
                Status.PROVEN,
                {"support": tuple(Fraction(v) for v in support)},
                float(slack.min()),
                detail=f"all {len(slack)} faces hold: each float slack exceeds its rigorous rounding bound "
                "(proofs/float_landing.md, part II); verify() re-checks them exactly",
            )
    ex = ExactEllipsoid.of(inner) if exact is None else exact
    faces = exact_faces(ex, outer)
    margin: float | None = min(f.margin for f in faces)
    margin = margin if margin is not None and math.isfinite(margin) else None  # beyond float's range
    # informative estimates; an extent beyond float's range is given as its exact upper bound
    mult = {
        "support": tuple(Fraction(f.support) if f.support < math.inf else sqrt_upper(f.zz, 64) for f in faces)
    }
    violated = [f for f in faces if not f.holds]
    if not violated:
        return answer(Status.PROVEN, mult, margin, detail=f"all {len(faces)} faces hold exactly")
    violated.sort(key=lambda f: f.margin)
    for f in violated:
        w = face_witness(ex, outer, f)
        if w is not None:
            return answer(
                Status.REFUTED,
                mult,
                margin,
                tuple(w),
                detail=f"face {f.index} is violated; witness maximises a^T y over the inner set",
            )
    return answer(Status.UNKNOWN, mult, margin, detail="a face fails exactly but no exact witness was found")


def _face_sigma(inner: Ellipsoid, outer: FacedSet) -> list[float]:
    """Float ``b_j - a_j^T c`` per face, for the support multipliers (the shape's ``face_offsets``)."""
    return outer.face_offsets(inner.centers[0]).tolist()  # type: ignore[no-any-return]
