"""The cheap non-singularity test gives the SVD test's verdicts; predict's sets are validated by it."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.errors import SetError
from ipcverify.network._nonsingular import CheckedEllipsoid, checked_ellipsoid, nonsingular, svd_rcond
from ipcverify.sets._ellipsoid import SINGULAR_RCOND, Ellipsoid


def _batch(rng: np.random.Generator, size: int, n: int) -> np.ndarray:
    """Rotated diagonal matrices with reciprocal condition numbers around the threshold, and extremes."""
    q1 = np.linalg.qr(rng.standard_normal((size, n, n)))[0]
    q2 = np.linalg.qr(rng.standard_normal((size, n, n)))[0]
    sv = np.exp(rng.uniform(-3, 3, (size, n)))
    sv[:, 0] = sv.max(axis=1) * 10.0 ** -rng.uniform(10.0, 14.0, size)  # rcond 1e-14 .. 1e-10
    shapes = (
        np.einsum("bij,bj,bkj->bik", q1, sv, q2)
        * 10.0 ** rng.choice([-150.0, -60.0, 0.0, 60.0, 150.0], size)[:, None, None]
    )
    shapes[rng.random(size) < 0.1] = np.diag(rng.uniform(1, 2, n))  # well-conditioned ones
    shapes[rng.random(size) < 0.05, -1] = 0.0  # exactly singular
    return shapes


@settings(derandomize=True, max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.sampled_from([2, 3, 3, 4]))
def test_verdicts_are_the_svd_tests(seed, n):
    shapes = _batch(np.random.default_rng(seed), 200, n)
    ok, rcond = nonsingular(shapes)
    assert ok.tolist() == (svd_rcond(shapes) >= SINGULAR_RCOND).tolist()
    decided = ~np.isnan(rcond)
    assert (rcond[decided] == svd_rcond(shapes[decided])).all()  # the same SVD where it ran


def test_well_conditioned_batches_need_no_svd():
    rng = np.random.default_rng(0)
    shapes = np.tril(rng.normal(size=(1000, 3, 3))) + np.eye(3) * 5.0
    ok, rcond = nonsingular(shapes)
    assert ok.all() and np.isnan(rcond).all()


def test_checked_ellipsoid_is_an_ellipsoid_with_the_same_checks_and_messages():
    good = checked_ellipsoid(np.zeros((2, 3)), np.stack([np.eye(3), 2 * np.eye(3)]))
    assert isinstance(good, Ellipsoid) and isinstance(good, CheckedEllipsoid)
    assert not good.shapes.flags.writeable and good.half_widths()[1].tolist() == [0.5, 0.5, 0.5]
    single = checked_ellipsoid(np.zeros(3), np.eye(3))
    assert single.batch_size == 1
    bad = np.stack([np.eye(3), np.diag([1.0, 1.0, 1e-13])])
    for make in (Ellipsoid, checked_ellipsoid):
        with pytest.raises(SetError, match=r"ellipsoid 1: shape matrix is singular \(reciprocal condition"):
            make(np.zeros((2, 3)), bad)
        with pytest.raises(SetError, match="ellipsoid 0: center has a non-finite entry"):
            make(np.full((1, 3), np.nan), np.eye(3)[None])
        with pytest.raises(SetError, match="ellipsoid 0: shape matrix has a non-finite entry"):
            make(np.zeros((1, 3)), np.full((1, 3, 3), np.inf))
        with pytest.raises(SetError, match="disagree"):
            make(np.zeros((2, 3)), np.stack([np.eye(3)] * 3))


@settings(derandomize=True, max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_the_compiled_bound_never_exceeds_the_svd_ratio(seed):
    # the cheap bound may only be lower than sigma_min / sigma_max; the SVD's ratio is itself
    # accurate to a few units of roundoff of sigma_max, hence the absolute slack of ~90 u
    from ipcverify.network._nonsingular import _rcond_lower_3

    shapes = _batch(np.random.default_rng(seed), 300, 3)
    lower = _rcond_lower_3(shapes)
    assert np.isfinite(lower).all() and (lower >= 0).all()
    assert (lower <= svd_rcond(shapes) * (1 + 1e-12) + 1e-14).all()
    assert (lower[np.abs(shapes).sum(axis=(1, 2)) > 0] > 0).any()  # it does show some
