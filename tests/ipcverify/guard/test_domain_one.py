"""DomainModel.contains_one (previous query, tree, float32 product, exact test) answers as contains does."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ipcverify.errors import InvalidInputError
from ipcverify.guard._domain import DomainModel
from ipcverify.guard._index import DomainIndex


def _fit(k: int, seed: int = 0) -> tuple[DomainModel, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    u = rng.uniform(-1, 1, (600, 2))
    x = np.column_stack([u[:, 0], u[:, 1], u[:, 0] ** 2]) + 0.05 * rng.standard_normal((600, 3))
    yhat = np.column_stack([np.sin(2 * u[:, 0]), u[:, 0] * u[:, 1]]) + 0.05 * rng.standard_normal((600, 2))
    return DomainModel.fit(x, yhat, flag_rate=0.05, k=k), x, yhat


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
    dom.forget()  # what the previous query left is per model: start afresh
    got = [dom.contains_one(z) for z in stream]
    # contains on the query alone: a batch's matrix product may whiten it an ulp differently
    want = [bool(dom.contains(z[None, :3], z[None, 3:])[0]) for z in stream]
    assert got == want


def test_each_step_of_contains_one_is_used():
    """A walk inside keeps its witness, a walk outside its bound; far points may need tier 2."""
    dom, x, yhat = DOMAINS[1]
    state = dom._one_args()[-2]  # this thread's state of the single-query kernel
    dom.forget()
    z = np.concatenate([x[0], yhat[0]])
    assert dom.contains_one(z) and state[0] == 1.0  # the tree found a witness ...
    witness = state[1]
    assert dom.contains_one(z + 1e-6) and state[1] == witness  # ... that answers the next query
    far = dom.mean + 100.0
    assert not dom.contains_one(far) and state[0] == 2.0  # outside, with a lower bound of the distance
    bound = state[1]
    assert not dom.contains_one(far + 1e-3) and state[1] == bound  # the bound answers, the anchor stays
    assert bound > dom.threshold
    # a query whose search would scan more leaves than the budget goes to the float32 product
    index = dom.index()
    ring = _at_distance(dom, dom.mean, 1.5 * float(np.linalg.norm(dom.reference, axis=1).max()),
                        np.random.default_rng(0))  # fmt: skip
    codes = index.decide(ring[None, :3].copy(), ring[None, 3:].copy(), dom.mean, dom._wt, dom.threshold, 1)
    assert codes.tolist() in ([-2], [0])
    assert dom.contains_one(ring) == bool(dom.contains(ring[None, :3], ring[None, 3:])[0])
    boundary = _at_distance(dom, dom.reference[0], dom.threshold * (1 + 1e-13), np.random.default_rng(1))
    assert dom.contains_one(boundary) == bool(dom.contains(boundary[None, :3], boundary[None, 3:])[0])


def test_a_small_budget_sends_queries_to_the_float32_product_with_the_same_answers():
    dom, x, yhat = DOMAINS[1]
    index = DomainIndex.build(dom.reference, budget=1)
    rng = np.random.default_rng(5)
    z = np.hstack([x, yhat])[rng.integers(0, len(x), 400)] * rng.uniform(0.5, 2.5, (400, 1))
    codes = index.decide(z[:, :3].copy(), z[:, 3:].copy(), dom.mean, dom._wt, dom.threshold, 1)
    over = np.flatnonzero(codes == -2)
    assert len(over) > 50
    scanned = index.scan(dom.whiten(z[over, :3], z[over, 3:]), dom.threshold, 1)
    assert np.array_equal(scanned == 1, dom.contains(z[over, :3], z[over, 3:]))


def test_contains_one_refuses_non_finite_queries():
    dom, _, _ = DOMAINS[1]
    assert not dom.contains_one(np.full(5, np.inf))


@pytest.mark.parametrize("k", [1, 3])
def test_contains_one_on_the_calibration_inputs_matches_contains(k):
    dom, x, yhat = DOMAINS[k]
    dom.forget()
    z = np.hstack([x, yhat])
    assert [dom.contains_one(v) for v in z] == [
        bool(dom.contains(a[None], b[None])[0]) for a, b in zip(x, yhat, strict=True)
    ]


def test_contains_one_refuses_a_query_of_the_wrong_length():
    dom, _, _ = DOMAINS[1]
    with pytest.raises(InvalidInputError, match="1-D \\(x, yhat\\) of length 5; got shape \\(4,\\)"):
        dom.contains_one(np.zeros(4))


def test_threads_keep_their_own_single_query_state():
    """domain_one runs without the GIL: each thread has its own state and search stack."""
    from concurrent.futures import ThreadPoolExecutor

    dom, _, _ = DOMAINS[1]
    streams = [_walk(dom, np.random.default_rng(s), 80, 0.05, 1e-12) for s in range(4)]
    want = [[bool(dom.contains(z[None, :3], z[None, 3:])[0]) for z in s] for s in streams]

    def run(stream: list[np.ndarray]) -> list[bool]:
        dom.forget()
        return [dom.contains_one(z) for z in stream]

    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(run, streams * 2))
    assert got == want * 2


def test_a_domain_model_pickles_and_answers_the_same_after():
    import copy
    import pickle

    dom, x, yhat = DOMAINS[3]
    dom.prepare()
    again = pickle.loads(pickle.dumps(dom))
    assert again.threshold == dom.threshold and np.array_equal(again.reference, dom.reference)
    assert np.array_equal(again.contains(x, yhat), dom.contains(x, yhat))
    z = np.concatenate([x[0], yhat[0]])
    assert copy.deepcopy(dom).contains_one(z) == dom.contains_one(z)
