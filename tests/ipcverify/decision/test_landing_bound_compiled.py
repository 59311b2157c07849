"""The landing bound's float tier compiled by Numba computes what the Python function computes.

Every property test of ``test_landing_bound.py`` (11,000 derandomized examples: random sets,
near ties, exact ties, extreme and singular shapes) compares the compiled route's answer with
``landing_by_bound``'s. Here the tier itself is compared, value for value, on the 10⁴ sets of a
trained IPC's landing campaign (``tests/data/landing_sets.npz``), and the routing is checked:
the compiled tier decides the usual sets; scaling and non-finite values go to Python.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import ipcverify.decision._landing_bound as landing_bound
from ipcverify.decision._landing import DecidedBy, LandingRule
from ipcverify.decision._landing_bound import float_tier, landing_by_bound, landing_by_bound_compiled
from ipcverify.sets._box import Box

SETS = Path(__file__).resolve().parents[2] / "data" / "landing_sets.npz"
G = ((-0.05, -0.05, 0.0), (0.05, 0.05, 0.05))


def test_the_compiled_tier_equals_the_python_tier_on_a_campaigns_sets():
    data = np.load(SETS)
    (gl0, gl1, _), (gu0, gu1, _) = data["target_lower"].tolist(), data["target_upper"].tolist()
    compiled = landing_bound._compiled_tier()
    decided = 0
    for c, C in zip(data["centers"].tolist(), data["shapes"].reshape(-1, 9).tolist(), strict=True):
        top = max(max(C), -min(C))
        args = (*c, *C, 1.0, top, gl0, gl1, gu0, gu1)
        python, numba = float_tier(*args), compiled(*args)
        assert tuple(numba) == python  # every float bit for bit, every face, the singularity verdict
        assert type(numba[5]) is float and type(numba[9]) is bool
        fast = landing_by_bound(c, C, data["target_lower"].tolist(), data["target_upper"].tolist())
        assert (
            landing_by_bound_compiled(c, C, data["target_lower"].tolist(), data["target_upper"].tolist())
            == fast
        )
        decided += fast is not None
    assert decided == 10_000  # the campaign's sets are all decided without the exact rational proof


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("where", [1, 4, 11])  # the centre's y, a shape entry, the last entry
def test_non_finite_values_take_the_python_route_and_agree(bad, where):
    values = [0.0, 0.0, 1.0, 40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0]
    values[where] = bad
    c, C = values[:3], values[3:]
    assert landing_by_bound_compiled(c, C, *G) == landing_by_bound(c, C, *G)
    d = LandingRule(Box(*G)).decide(np.array(c), np.array(C).reshape(3, 3))
    assert not d.accept


def test_scaled_matrices_take_the_python_route_and_agree():
    for k in (-120, -101, 101, 300):
        C = [v * 2.0**k for v in (40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0)]
        assert landing_by_bound_compiled([0.0, 0.0, 1.0], C, *G) == landing_by_bound([0.0, 0.0, 1.0], C, *G)


def test_the_rule_reports_the_compiled_route_as_the_bound():
    rule = LandingRule(Box(*G))
    d = rule.decide_values([0.0, 0.0, 1.0], [40.0, 0.0, 0.0, 0.0, 40.0, 0.0, 0.0, 0.0, 80.0])
    assert d.accept and d.decided_by is DecidedBy.BOUND
    assert d.turnoff.tolist() == [0.0, 0.0, 1.0125000000000002]
