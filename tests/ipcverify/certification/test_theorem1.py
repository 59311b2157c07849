"""Theorem 1: its terms, the vacuity flag, the N needed, and the paper's own setting."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.certification._theorem1 import n_needed, theorem1, theorem1_terms, truncated_hinge_mean
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.training._train import TrainConfig, train


def test_truncated_hinge_values():
    # l(t) = max(0, t/alpha + 1), truncated at 1: g <= 1 - alpha -> 0; g >= 1 -> 1; linear in between
    g = np.array([0.0, 0.9, 0.95, 1.0, 5.0])
    assert truncated_hinge_mean(g, 0.1) == pytest.approx((0 + 0 + 0.5 + 1 + 1) / 5)
    with pytest.raises(InvalidInputError, match=r"alpha must be > 0"):
        truncated_hinge_mean(g, 0.0)
    with pytest.raises(InvalidInputError, match=r"Theorem 1 needs N >= 1"):
        truncated_hinge_mean([], 0.1)


def test_paper_setting_is_vacuous():
    """p = 10,900, N = 5000: the complexity term is (12/alpha) L_g sqrt(p/N) >= 17 L_g / alpha."""
    t = theorem1_terms(0.0, 16.0, 10_900, 5000, alpha=0.1, delta=0.05, valid=True)
    assert t.complexity == pytest.approx(12 / 0.1 * 16 * math.sqrt(10_900 / 5000))
    assert t.complexity >= 17 * 16 / 0.1
    assert t.vacuous and t.bound > 1000
    assert t.n_needed is not None and t.n_needed > 5000


@settings(derandomize=True, max_examples=200, deadline=None)
@given(
    emp=st.floats(0.0, 0.999),
    lip=st.floats(0.0, 1e6),
    p=st.integers(1, 10**6),
    alpha=st.floats(1e-3, 10.0),
    delta=st.floats(1e-9, 0.5),
)
def test_n_needed_is_the_smallest_n(emp, lip, p, alpha, delta):
    a = 12.0 / alpha * lip * math.sqrt(p)
    b = math.sqrt(math.log(2.0 / delta) / 2.0)
    n = n_needed(emp, a, b)
    assert n is not None
    if n < 2**50:
        assert theorem1_terms(emp, lip, p, n, alpha, delta, valid=True).bound < 1.0
        if n > 1:
            assert theorem1_terms(emp, lip, p, n - 1, alpha, delta, valid=True).bound >= 1.0 - 1e-12


def test_no_n_when_the_empirical_term_is_one():
    assert n_needed(1.0, 5.0, 1.0) is None
    t = theorem1_terms(1.0, 0.0, 10, 100, alpha=0.1, delta=0.1, valid=True)
    assert t.vacuous and t.n_needed is None


def test_huge_n_is_reported_without_looping():
    n = n_needed(0.0, 1e20, 1.0)
    assert n is not None and n >= 1e40


def test_theorem1_on_a_trained_model_reports_both_constants():
    data = make_lagged_perception(600, seed=0)
    m = train(
        data,
        ModelConfig(x_dim=6, y_dim=3, hidden=(8,), param="cholesky"),
        TrainConfig.recipe("v1", epochs=2, alpha=0.2),
    ).model
    res = theorem1(m, data, delta=0.01)
    assert res.alpha == 0.2 and res.n_train == 600 and res.n_parameters == m.n_parameters
    assert res.sound.lipschitz >= res.optimistic.lipschitz > 0
    assert res.sound.bound >= res.optimistic.bound
    assert res.sound.valid and not res.optimistic.valid
    assert res.confidence_term == pytest.approx(math.sqrt(math.log(2 / 0.01) / 1200))
    d = res.to_dict()
    for key in ("bound", "vacuous", "lipschitz_empirical", "lipschitz_sound", "n_needed"):
        assert key in d
    assert d["vacuous"] is True and d["guarantee"] is False
    assert "vacuous" in res.explanation() and "calibration certificate" in res.explanation()
    wrong = make_lagged_perception(50, seed=1)
    with pytest.raises(InvalidInputError, match=r"records no training alpha"):
        theorem1(type(m)(m.network, None, {}), wrong, delta=0.01)
