"""DomainModel.contains_one (cached distance, float32 scan, tree) answers exactly as contains does."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.domain import DomainModel
from ipcverify.errors import InvalidInputError
from ipcverify.kernels import scan_kth


def _fit(k: int, seed: int = 0) -> tuple[DomainModel, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, (600, 2))
    x = np.column_stack([u[:, 0], u[:, 1], u[:, 0] ** 2]) + 0.05 * rng.standard_normal((600, 3))
    yhat = np.column_stack([np.sin(2 * u[:, 0]), u[:, 0] * u[:, 1]]) + 0.05 * rng.standard_normal((600, 2))
    return DomainModel.fit(x, yhat, alpha=0.05, k=k), x, yhat


DOMAINS = {k: _fit(k) for k in (1, 3)}


def _at_distance(dom: DomainModel, center: np.ndarray, radius: float, rng: np.random.Generator) -> np.ndarray:
    """A query z whose whitened point lies at ``radius`` from the whitened ``center`` (up to rounding)."""
    direction = rng.standard_normal(len(center))
    w = center + radius * direction / np.linalg.norm(direction)
    return np.linalg.solve(dom.whitening, w) + dom.mean  # w = W (z - mean)


def _on_boundary(dom: DomainModel, rng: np.random.Generator, near: float) -> np.ndarray:
    """A query a relative ``near`` inside or outside the domain's boundary, found by bisection on a ray."""

    def inside(w: np.ndarray) -> bool:
        z = np.linalg.solve(dom.whitening, w) + dom.mean
        return bool(dom.contains(z[None, :3], z[None, 3:])[0])

    start = next(r for r in dom.reference[rng.permutation(dom.n)] if inside(r))
    direction = rng.standard_normal(len(start))
    direction /= np.linalg.norm(direction)
    lo, hi = 0.0, dom.threshold
    while inside(start + hi * direction):
        lo, hi = hi, 2.0 * hi
    while hi - lo > 1e-15 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if inside(start + mid * direction) else (lo, mid)
    w = start + hi * (1 + rng.choice([-1.0, 1.0]) * near) * direction
    return np.linalg.solve(dom.whitening, w) + dom.mean


def _walk(dom: DomainModel, rng: np.random.Generator, n: int, step: float, near: float) -> list[np.ndarray]:
    """A query stream: a random walk, jumps, points a relative ``near`` off the threshold, NaN."""
    z = dom.mean.copy()
    out = []
    for _ in range(n):
        kind = rng.integers(6)
        if kind == 0:  # jump
            w = rng.standard_normal(len(z)) * rng.uniform(0.1, 4.0)
            z = np.linalg.solve(dom.whitening, w) + dom.mean
        elif kind == 1:  # a relative ``near`` off the boundary of the domain
            z = _on_boundary(dom, rng, near)
        else:  # a small step
            z = z + rng.standard_normal(len(z)) * step
        out.append(z.copy())
    out.append(np.full(len(z), np.nan))
    return out


@settings(derandomize=True, max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.sampled_from([1, 3]),
    step=st.sampled_from([0.005, 0.05, 0.3]),
    near=st.sampled_from([1e-3, 1e-6, 1e-7, 1e-8, 1e-12, 1e-15]),
)
def test_contains_one_answers_as_contains_along_a_stream(seed, k, step, near):
    dom, _, _ = DOMAINS[k]
    rng = np.random.default_rng(seed)
    stream = _walk(dom, rng, 60, step, near)
    dom._last[0] = None  # the cache is per model: start from a fresh one
    got = [dom.contains_one(z) for z in stream]
    # contains on the query alone: a batch's matrix product may whiten it an ulp differently
    want = [bool(dom.contains(z[None, :3], z[None, 3:])[0]) for z in stream]
    assert got == want


def test_each_step_of_contains_one_is_used():
    """A slow walk inside is answered from the cache; a far point by the scan; the boundary by the tree."""
    dom, x, yhat = DOMAINS[1]
    dom._last[0] = None
    z = np.concatenate([x[0], yhat[0]])
    assert dom.contains_one(z)  # scan (fresh cache)
    cached = dom._last[0]
    assert cached is not None
    assert dom.contains_one(z + 1e-6)  # the cache decides ...
    assert dom._last[0] is cached  # ... and keeps its anchor
    far = dom.mean + 100.0
    assert not dom.contains_one(far)
    boundary = _at_distance(dom, dom.reference[0], dom.threshold * (1 + 1e-13), np.random.default_rng(1))
    assert dom.contains_one(boundary) == bool(dom.contains(boundary[None, :3], boundary[None, 3:])[0])
    assert dom._last[0] is None or abs(dom._last[0][1] / dom.threshold - 1) > 1e-9


def test_contains_one_refuses_non_finite_queries():
    dom, _, _ = DOMAINS[1]
    assert not dom.contains_one(np.full(5, np.inf))


@pytest.mark.parametrize("k", [1, 3])
def test_contains_one_on_the_calibration_inputs_matches_contains(k):
    dom, x, yhat = DOMAINS[k]
    dom._last[0] = None
    z = np.hstack([x, yhat])
    assert [dom.contains_one(v) for v in z] == [
        bool(dom.contains(a[None], b[None])[0]) for a, b in zip(x, yhat, strict=True)
    ]


def test_contains_one_refuses_a_query_of_the_wrong_length():
    dom, _, _ = DOMAINS[1]
    with pytest.raises(InvalidInputError, match="1-D \\(x, yhat\\) of length 5; got shape \\(4,\\)"):
        dom.contains_one(np.zeros(4))


@pytest.mark.parametrize("k", [1, 2, 5])
def test_the_compiled_scan_is_the_kth_smallest_product(k):
    # the kernel's k-th smallest of (w, 1) . column_j, against NumPy's float32 product and sort
    rng = np.random.default_rng(k)
    cols = rng.normal(size=(4, 37)).astype(np.float32)
    w = rng.normal(size=3)
    want = np.sort(np.append(w, 1.0).astype(np.float32) @ cols)[k - 1]
    np.testing.assert_allclose(scan_kth(w, cols, k), want, rtol=1e-5, atol=1e-5)
    cols[2, 11] = np.nan  # a NaN product anywhere: NaN, never a finite answer
    assert np.isnan(scan_kth(w, cols, k))
