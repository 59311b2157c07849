"""The fast domain test answers exactly as the exact k-nearest-neighbour test (SciPy's cKDTree).

``DomainModel.contains`` (k-d tree that stops early, float32 BLAS product, exact fallback in
the rounding band) against an independent float64 cKDTree on the same whitened points, on
10^5 seeded queries of every kind, on queries placed within 1e-9 (down to 0) of the threshold,
and on the real VI-SLAM log; the kernels against NumPy.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.spatial import cKDTree

from ipcverify.guard._domain import DomainModel
from ipcverify.guard._index import BAND, DomainIndex, levels
from ipcverify.guard._kernels import kth_rows, scan_rows, whiten_one, whiten_rows

EUROC = Path(__file__).resolve().parents[3] / "data" / "euroc_mh04_vislam.csv"


def _manifold(rng: np.random.Generator, n: int, d: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """(x, yhat) on a curved 3-D manifold in (d + 3) dimensions, plus noise: like the quad data."""
    u = rng.uniform(-1.0, 1.0, (n, 3))
    basis = np.random.default_rng(99).normal(size=(9, d + 3))
    feats = np.column_stack([u, u**2, np.sin(2 * u)])
    z = feats @ basis + 0.05 * rng.standard_normal((n, d + 3))
    return z[:, :d], z[:, d:]


def _oracle(dom: DomainModel, x: np.ndarray, yhat: np.ndarray) -> np.ndarray:
    """The exact test: SciPy's float64 k-d tree on the model's whitened points, score <= threshold
    (a non-finite query is outside)."""
    w = dom.whiten(x, yhat)
    ok = np.isfinite(w).all(axis=1)
    out = np.zeros(len(w), dtype=bool)
    out[ok] = cKDTree(dom.reference).query(w[ok], k=[dom.k])[0][:, 0] <= dom.threshold
    return out


def _queries(rng: np.random.Generator, n: int, dom: DomainModel) -> tuple[np.ndarray, np.ndarray]:
    """In-distribution, shifted, far, exact copies of references, and NaN / inf rows."""
    x, yhat = _manifold(rng, n)
    z = np.hstack([x, yhat])
    kind = rng.integers(0, 10, n)
    z[kind == 7] *= 1.6  # shifted: near and beyond the boundary
    z[kind == 8] *= 40.0  # far out
    copies = np.flatnonzero(kind == 9)
    refs = np.linalg.solve(dom.whitening, dom.reference[rng.integers(0, dom.n, len(copies))].T).T + dom.mean
    z[copies] = refs  # (up to the rounding of the inverse whitening) a reference itself
    z[:3, 4] = [np.nan, np.inf, -np.inf]
    return z[:, :12], z[:, 12:]


@pytest.fixture(scope="module", params=[1, 3], ids=["k1", "k3"])
def model(request):
    x, yhat = _manifold(np.random.default_rng(0), 3000)
    return DomainModel.fit(x, yhat, flag_rate=0.02, k=request.param)


@pytest.mark.slow
def test_batch_test_equals_an_exact_knn_check_on_1e5_queries(model):
    x, yhat = _queries(np.random.default_rng(1), 100_000 if model.k == 1 else 20_000, model)
    got = model.contains(x, yhat)
    w = model.whiten(x, yhat)
    exact = np.full(len(w), np.inf)
    exact[3:] = cKDTree(model.reference).query(w[3:], k=[model.k])[0][:, 0]
    want = exact <= model.threshold
    assert np.array_equal(got, want)
    assert 0.3 < want.mean() < 0.95 and not got[:3].any()  # both answers; non-finite rows outside
    # tier 2 on many queries: with a budget of 2 leaves the float32 product decides most of them
    small = DomainIndex.build(model.reference, budget=2)
    wt = model.whitening.T.copy()
    codes = small.decide(x, yhat, model.mean, wt, model.threshold, model.k)
    over = np.flatnonzero(codes == -2)
    assert len(over) > len(x) // 5
    codes[over] = small.scan(w[over], model.threshold, model.k)
    band = codes == -1
    assert np.array_equal((codes == 1) | (band & want), want)
    # distance is consistent with the test to the last bit, and the exact distance elsewhere
    dist = model.distance(x, yhat)
    assert np.array_equal(dist <= model.threshold, got)
    np.testing.assert_allclose(dist, exact, rtol=1e-13, atol=0.0)


def _boundary(dom: DomainModel, rng: np.random.Generator, n: int, offsets: list[float]) -> np.ndarray:
    """Queries z whose k-th neighbour distance is ``threshold (1 + offset)`` (up to the rounding of z).

    Bisection along random rays from inside points, with the exact test's own distance.
    """
    tree = cKDTree(dom.reference)
    start = dom.reference[rng.integers(0, dom.n, n)] + 0.01 * rng.standard_normal((n, dom.reference.shape[1]))
    direction = rng.standard_normal(start.shape)
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    out = []
    for offset in offsets:
        target = dom.threshold * (1.0 + offset)
        lo, hi = np.zeros(n), np.full(n, 50.0 * dom.threshold)
        for _ in range(64):
            mid = 0.5 * (lo + hi)
            d = tree.query(start + mid[:, None] * direction, k=[dom.k])[0][:, 0]
            lo, hi = np.where(d <= target, mid, lo), np.where(d <= target, hi, mid)
        w = start + lo[:, None] * direction
        out.append(np.linalg.solve(dom.whitening, w.T).T + dom.mean)
    return np.concatenate(out)


@pytest.mark.slow
def test_queries_within_1e_9_of_the_threshold_get_the_exact_answer(model):
    offsets = [-1e-9, -3e-10, -1e-12, -1e-14, 0.0, 1e-14, 1e-12, 3e-10, 1e-9, -1e-7, 1e-7]
    z = _boundary(model, np.random.default_rng(2), 100, offsets)
    x, yhat = z[:, :12], z[:, 12:]
    want = _oracle(model, x, yhat)
    assert np.array_equal(model.contains(x, yhat), want)
    assert 0.2 < want.mean() < 0.8  # both answers occur right at the threshold
    rel = cKDTree(model.reference).query(model.whiten(x, yhat), k=[model.k])[0][:, 0] / model.threshold - 1
    assert (np.abs(rel) <= BAND).mean() > 0.6  # most of them inside the band the exact test decides
    model.forget()
    assert [model.contains_one(row) for row in z] == want.tolist()
    assert np.array_equal(model.distance(x, yhat) <= model.threshold, want)


@pytest.mark.skipif(not EUROC.is_file(), reason="the real log ships with the repository")
def test_batch_test_equals_the_exact_test_on_the_real_log():
    df = pd.read_csv(EUROC)
    xs, ys = [f"x_{i}" for i in range(5)], [f"yhat_{i}" for i in range(3)]
    group = df["method"] + ":" + df["run"].astype(str)
    half = df["t"] < df["t"].median()
    for fit_rows in (group.isin(np.unique(group)[::2]), half):  # held-out runs; the other half of the hall
        cal = df[fit_rows]
        dom = DomainModel.fit(cal[xs].to_numpy(), cal[ys].to_numpy())
        x, yhat = df[xs].to_numpy(), df[ys].to_numpy()
        want = _oracle(dom, x, yhat)
        assert np.array_equal(dom.contains(x, yhat), want) and 0.005 < 1 - want.mean() < 0.9
        dom.forget()
        rows = np.hstack([x, yhat])[::7]
        assert [dom.contains_one(r) for r in rows] == want[::7].tolist()
    by_run = DomainModel.fit(df[xs].to_numpy(), df[ys].to_numpy(), flag_rate=0.1, groups=group.to_numpy())
    shifted = df[xs].to_numpy() * 1.3
    assert np.array_equal(by_run.contains(shifted, df[ys]), _oracle(by_run, shifted, df[ys].to_numpy()))


def test_whitening_gives_the_same_bits_alone_and_in_any_batch():
    rng = np.random.default_rng(3)
    x, yhat = rng.normal(size=(257, 5)), rng.normal(size=(257, 4)) * 1e3
    mean, wt = rng.normal(size=9), rng.normal(size=(9, 9))
    rows = whiten_rows(x, yhat, mean, wt)
    ones = np.array([whiten_one(np.concatenate([a, b]), mean, wt) for a, b in zip(x, yhat, strict=True)])
    assert np.array_equal(rows, ones) and np.array_equal(
        whiten_rows(x[100:], yhat[100:], mean, wt), rows[100:]
    )
    np.testing.assert_allclose(rows, (np.hstack([x, yhat]) - mean) @ wt, rtol=1e-11, atol=1e-9)


def _numpy_products(w: np.ndarray, refs: np.ndarray) -> np.ndarray:
    cols = np.vstack([-2.0 * refs.T, (refs**2).sum(1)]).astype(np.float32)
    return np.hstack([w, np.ones((len(w), 1))]).astype(np.float32) @ cols


@pytest.mark.parametrize("k", [1, 2, 5])
def test_the_product_kernels_against_numpy(k):
    rng = np.random.default_rng(k)
    refs, w = rng.normal(size=(300, 6)), rng.normal(size=(40, 6)) * 1.5
    g = _numpy_products(w, refs)
    d2 = ((w[:, None, :] - refs[None]) ** 2).sum(2)
    slack = 1e-5 * (np.sqrt((refs**2).sum(1).max()) + np.linalg.norm(w, axis=1)) ** 2
    kth = kth_rows(g, g.min(axis=1), w, refs, k, slack)
    np.testing.assert_allclose(kth, np.sort(d2, axis=1)[:, k - 1], rtol=1e-14)
    t = float(np.sqrt(np.median(kth)))
    t2_in, t2_out = levels(t)
    want = (np.sort(d2, axis=1)[:, k - 1] <= t * t).astype(np.int8)
    assert np.array_equal(scan_rows(g, g.min(axis=1), w, refs, t2_in, t2_out, k, slack), want)
    g[:, 7] = np.nan  # a NaN product is recomputed in float64 by the test, and refused by the distance
    with np.errstate(invalid="ignore"):
        least = g.min(axis=1)
    assert np.isnan(least).all()
    assert np.array_equal(scan_rows(g, least, w, refs, t2_in, t2_out, k, slack), want)
    assert np.isnan(kth_rows(g, least, w, refs, k, slack)).all()


def test_the_index_is_a_k_d_tree_of_the_references():
    ref = np.random.default_rng(4).normal(size=(1000, 4))
    index = DomainIndex.build(ref, leaf_size=8)
    assert np.array_equal(np.sort(index.order), np.arange(1000)) and np.array_equal(
        index.refs, ref[index.order]
    )
    dim = 4
    for node, (start, end, left, right, axis) in enumerate(index.nodes):
        pts = index.refs[start:end]
        assert (pts >= index.boxes[node, :dim]).all() and (pts <= index.boxes[node, dim : 2 * dim]).all()
        if left < 0:
            assert 1 <= end - start <= 8
            continue
        split = index.boxes[node, 2 * dim]
        assert (index.refs[index.nodes[left, 0] : index.nodes[left, 1], axis] <= split).all()
        assert (index.refs[index.nodes[right, 0] : index.nodes[right, 1], axis] >= split).all()
    assert index.prune_stats()["leaves"] == int((index.nodes[:, 2] < 0).sum()) >= 1000 // 8
