"""Sets whose extent is beyond float's range are decided, not crashed on (an OverflowError before)."""

from __future__ import annotations

import numpy as np
import pytest

from ipcverify.decision.containment import Status, prove, verify
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.sets._polytope import Polytope

OUTERS = [Box([-1.0] * 3, [1.0] * 3), Polytope(np.vstack([np.eye(3), -np.eye(3)]), np.ones(6))]


@pytest.mark.parametrize("scale", [1e-310, 1e-200])
@pytest.mark.parametrize("outer", OUTERS, ids=["box", "polytope"])
def test_a_set_too_large_for_floats_is_refuted_exactly(scale, outer):
    inner = Ellipsoid(np.zeros(3), np.diag([scale] * 3))  # half-widths 1e200 .. 1e310
    cert = prove(inner, outer, method="closed-form")
    assert cert.status is Status.REFUTED and cert.witness is not None
    assert verify(cert).status is Status.REFUTED  # the witness re-checks exactly
    assert cert.margin is None or cert.margin < -1e199  # no float claimed where none exists
    for method in ("sdp", "socp"):  # the solvers cannot represent it: never PROVEN, never an error
        assert prove(inner, outer, method=method).status is not Status.PROVEN
