"""Tests of the batched Ellipsoid set type."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.errors import SetError
from ipcverify.sets._ellipsoid import Ellipsoid, unit_ball_log_volume


def random_ellipsoids(rng: np.random.Generator, b: int, n: int, cond: float = 100.0) -> Ellipsoid:
    # C = U diag(sv) V^T with independent rotations: general, non-symmetric shapes
    u, _ = np.linalg.qr(rng.standard_normal((b, n, n)))
    v, _ = np.linalg.qr(rng.standard_normal((b, n, n)))
    sv = np.exp(rng.uniform(0, np.log(cond), (b, n)))
    shapes = (u * sv[:, None, :]) @ np.swapaxes(v, 1, 2)
    return Ellipsoid(rng.standard_normal((b, n)), shapes)


def test_extents_agree_with_surface_samples():
    rng = np.random.default_rng(0)
    e = random_ellipsoids(rng, 20, 3)
    lo, hi = e.extents()
    pts = np.stack([e.sample(rng, surface=True) for _ in range(4000)], axis=1)  # (B, m, n)
    # every surface point lies inside the box ...
    assert (pts >= lo[:, None, :] - 1e-9).all() and (pts <= hi[:, None, :] + 1e-9).all()
    # ... and the box is tight: the extreme sample comes close to each face
    span = hi - lo
    assert np.all(hi - pts.max(axis=1) < 0.02 * span)
    assert np.all(pts.min(axis=1) - lo < 0.02 * span)


def test_extent_attained_by_closed_form_maximiser():
    rng = np.random.default_rng(1)
    e = random_ellipsoids(rng, 10, 4, cond=1e4)
    _, hi = e.extents()
    cinv = np.linalg.inv(e.shapes)
    for i in range(e.dim):
        # the maximiser of y_i over E is c + C^{-1} u with u = C^{-T} e_i / ||C^{-T} e_i||
        u = cinv[:, i, :]
        pt = e.boundary_points(u)
        assert np.allclose(pt[:, i], hi[:, i], rtol=1e-10, atol=1e-10)
        assert np.allclose(e.g(pt), 1.0, atol=1e-9)


@settings(max_examples=50, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), scale=st.floats(0.1, 10.0))
def test_contains_agrees_with_g(seed: int, scale: float):
    rng = np.random.default_rng(seed)
    e = random_ellipsoids(rng, 50, 3)
    y = e.centers + scale * rng.standard_normal((50, 3))
    g = e.g(y)
    assert np.array_equal(e.contains(y), g <= 1.0)
    # and g is the defining norm
    d = y - e.centers
    assert np.allclose(g, np.sqrt(np.einsum("bi,bij,bj->b", d, e.precision(), d)))


def test_log_volume_matches_monte_carlo_and_formula():
    e = Ellipsoid(np.zeros(3), np.diag([1.0, 2.0, 4.0]))
    expected = np.log(4.0 / 3.0 * np.pi / 8.0)
    assert e.log_volume()[0] == pytest.approx(expected, rel=1e-12)
    assert np.exp(unit_ball_log_volume(2)) == pytest.approx(np.pi)
    # Monte Carlo: fraction of a bounding box inside the ellipsoid
    rng = np.random.default_rng(2)
    lo, hi = e.extents()
    n = 200_000
    pts = rng.uniform(lo[0], hi[0], (n, 3))
    inside = Ellipsoid(np.zeros((n, 3)), np.broadcast_to(e.shapes, (n, 3, 3))).contains(pts)
    p = np.exp(expected) / np.prod(hi - lo)
    k = inside.sum()
    assert abs(k - n * p) < 5 * np.sqrt(n * p * (1 - p))  # 5 sigma


def test_scaled_grows_about_centre():
    rng = np.random.default_rng(3)
    e = random_ellipsoids(rng, 5, 3)
    s = e.scaled(2.0)
    assert np.allclose(s.half_widths(), 2 * e.half_widths())
    assert np.allclose(s.log_volume(), e.log_volume() + 3 * np.log(2.0))
    per = e.scaled(np.arange(1.0, 6.0))
    assert np.allclose(per.half_widths(), e.half_widths() * np.arange(1.0, 6.0)[:, None])


def test_immutable_and_copied():
    c = np.zeros((1, 2))
    e = Ellipsoid(c, np.eye(2)[None])
    c[0, 0] = 5.0
    assert e.centers[0, 0] == 0.0
    with pytest.raises(ValueError):
        e.centers[0, 0] = 1.0
    with pytest.raises(AttributeError):
        e.centers = c  # type: ignore[misc]


@pytest.mark.parametrize(
    ("centers", "shapes", "match"),
    [
        (np.zeros((2, 3)), np.eye(3)[None].repeat(1, 0), r"disagree"),
        (np.array([[0.0, np.nan]]), np.eye(2)[None], r"ellipsoid 0: center has a non-finite"),
        (
            np.zeros((2, 2)),
            np.stack([np.eye(2), [[1.0, np.inf], [0, 1]]]),
            r"ellipsoid 1: shape matrix has a non-finite",
        ),
        (
            np.zeros((2, 2)),
            np.stack([np.eye(2), [[1.0, 1.0], [1.0, 1.0]]]),
            r"ellipsoid 1: shape matrix is singular",
        ),
        (np.zeros((1, 2)), np.zeros((1, 2, 3)), r"shapes must have shape \(B, n, n\)"),
    ],
)
def test_bad_input_is_refused_with_the_item(centers, shapes, match):
    with pytest.raises(SetError, match=match):
        Ellipsoid(centers, shapes)


def test_bad_scale_and_points():
    e = Ellipsoid(np.zeros(2), np.eye(2))
    with pytest.raises(SetError, match="finite and > 0"):
        e.scaled(0.0)
    with pytest.raises(SetError, match="points must have shape"):
        e.g(np.zeros((3, 2)))


def test_roundtrip_dict_and_indexing():
    rng = np.random.default_rng(4)
    e = random_ellipsoids(rng, 6, 3)
    f = Ellipsoid.from_dict(e.to_dict())
    assert np.array_equal(f.centers, e.centers) and np.array_equal(f.shapes, e.shapes)
    assert e[2].batch_size == 1 and np.array_equal(e[2].centers[0], e.centers[2])
    assert len(e[1:4]) == 3
