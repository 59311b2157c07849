"""Tests of the single-query API: same sets as predict, exact landing decisions, input errors."""

from __future__ import annotations

import numpy as np
import pytest

from ipcverify.calibration import Mondrian
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.decision._landing import LandingRule, Verdict
from ipcverify.decision._landing_float import landing_accept_float
from ipcverify.decision._landing_proof import check_landing, landing_decision
from ipcverify.decision._landing_query import LandingQuery
from ipcverify.decision._query import IPCQuery
from ipcverify.errors import InvalidInputError, SetError
from ipcverify.network._architecture import ModelConfig
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid
from ipcverify.training._train import TrainConfig, train

#: The paper's target box G (the library takes it from the caller).
G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])


@pytest.fixture(scope="module")
def data():
    return make_lagged_perception(1500, seed=0), make_lagged_perception(1000, seed=1)


@pytest.fixture(
    scope="module",
    params=[("lowrank", "offset"), ("cholesky", "offset"), ("full", "raw"), ("cholesky", "raw")],
)
def trained(request, data):
    param, center = request.param
    mc = ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16), param=param, center=center)
    return train(data[0], mc, TrainConfig(epochs=2, seed=1)).model


@pytest.mark.parametrize("calibrated", [False, True])
def test_query_sets_are_the_models_sets(trained, data, calibrated):
    model = calibrate(trained, data[1], 0.05, 0.01) if calibrated else trained
    q = LandingQuery(IPCQuery(model), G)
    test = make_lagged_perception(50, seed=2)
    ref = model.predict_unguarded(test.x, test.yhat)
    for i in range(len(test)):
        c, C = q.ellipsoid(test.x[i], test.yhat[i])
        np.testing.assert_allclose(c, ref.centers[i], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(C, ref.shapes[i], rtol=1e-12, atol=1e-15)


def test_mondrian_calibration_is_applied_per_query(data):
    model = train(data[0], ModelConfig(x_dim=6, y_dim=3, hidden=(8,)), TrainConfig(epochs=1)).model
    cal = calibrate(model, make_lagged_perception(3000, seed=5), 0.1, 0.05, Mondrian(column="x_5", bins=2))
    test = make_lagged_perception(20, seed=3)
    ref = cal.predict_unguarded(test.x, test.yhat)
    q = LandingQuery(IPCQuery(cal), G)
    for i in range(len(test)):
        np.testing.assert_allclose(q.ellipsoid(test.x[i], test.yhat[i])[1], ref.shapes[i], rtol=1e-12)


def _near_threshold_ellipsoids(rng, count):
    """Random 3-D ellipsoids scaled so that the tightest face is within +-1e-6 relative of touching."""
    out = []
    for _ in range(count):
        q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
        C = q @ np.diag(1.0 / rng.uniform(0.01, 0.04, 3))
        if rng.random() < 0.5:
            C = np.linalg.cholesky(C.T @ C).T  # upper-triangular factor, same set
        e = Ellipsoid(rng.normal(scale=2.0, size=3), C)
        h = e.half_widths()[0]
        critical = max(h[0] / 0.05, h[1] / 0.05, 2 * h[2] / 0.05)
        factor = critical * (1.0 + rng.choice([-1.0, 1.0]) * 10.0 ** rng.uniform(-12, -6))
        out.append(Ellipsoid(e.centers[0], e.shapes[0] * factor))
    return out


def test_decide_agrees_with_the_exact_decision_near_the_threshold(trained):
    q = LandingQuery(IPCQuery(trained), G)
    rng = np.random.default_rng(11)
    cases = _near_threshold_ellipsoids(rng, 150)
    cases += [Ellipsoid(rng.normal(size=3), np.diag(1.0 / rng.uniform(0.005, 0.1, 3))) for _ in range(150)]
    accepted = 0
    for e in cases:
        d = q.rule.decide(e.centers[0], e.shapes[0])
        exact = landing_decision(e, G)
        assert d.accept == exact.accept
        # the same rule on Python floats (the query path's form): the same answer
        dv = q.rule.decide_values(e.centers[0].tolist(), e.shapes[0].ravel().tolist())
        assert (dv.accept, dv.decided_by, dv.verdict) == (d.accept, d.decided_by, d.verdict)
        np.testing.assert_array_equal(dv.turnoff, d.turnoff)
        np.testing.assert_array_equal(dv.shape, e.shapes[0])
        if d.accept:
            accepted += 1
            assert d.proven and check_landing(d.proof).status.name == "PROVEN"
            np.testing.assert_array_equal(d.turnoff, exact.turnoff)
    assert 0 < accepted < len(cases)


def test_single_float_rule_matches_the_batch_rule_away_from_the_threshold(trained):
    """One rule, two half-width computations (3x3 adjugate vs batched inverse): same answers."""
    q = LandingQuery(IPCQuery(trained), G)
    rng = np.random.default_rng(3)
    es = [Ellipsoid(rng.normal(size=3), np.diag(1.0 / rng.uniform(0.005, 0.1, 3))) for _ in range(200)]
    batch = Ellipsoid(np.stack([e.centers[0] for e in es]), np.stack([e.shapes[0] for e in es]))
    expected = landing_accept_float(batch, G)
    for e, exp in zip(es, expected, strict=True):
        h = e.half_widths()[0]
        if abs(max(h[0], h[1], 2 * h[2]) / 0.05 - 1.0) < 1e-6:
            continue
        assert q.rule.decide_float(e.centers[0], e.shapes[0]).accept == bool(exp)


def test_decide_end_to_end_runs_and_reports_a_proof_only_for_accepts(trained, data):
    q = LandingQuery(IPCQuery(calibrate(trained, data[1], 0.05, 0.01)), G)
    test = make_lagged_perception(30, seed=4)
    for i in range(len(test)):
        d = q.decide(test.x[i], test.yhat[i])
        assert d.proven == d.accept
        assert d.turnoff.shape == (3,)
        assert q.decide_float(test.x[i], test.yhat[i]).accept >= d.accept  # float never stricter here


@pytest.mark.parametrize(("method", "seed"), [("decide", 6), ("decide_float", 7)])
def test_decide_is_the_rules_decision_on_the_querys_own_set(trained, data, method, seed):
    """decide() and decide_float() keep the set in Python floats until the answer: the array path's."""
    q_small = LandingQuery(IPCQuery(calibrate(trained, data[1], 0.05, 0.01)), G)
    q_wide = LandingQuery(IPCQuery(q_small.model), Box([-20.0, -20.0, -20.0], [20.0, 20.0, 20.0]))
    q_tiny = LandingQuery(IPCQuery(q_small.model), Box([-1e-6, -1e-6, 0.0], [1e-6, 1e-6, 1e-6]))
    test = make_lagged_perception(40, seed=seed)
    verdicts = set()
    for q in (q_small, q_wide, q_tiny):
        decide = getattr(q, method)
        for i in range(len(test)):
            d = decide(test.x[i], test.yhat[i])
            ref = decide(test.x[i], test.yhat[i], transform=lambda c, C: (c, C))  # the array path
            c, C = q.ellipsoid(test.x[i], test.yhat[i])
            assert (d.accept, d.decided_by, d.verdict, d.proven) == (
                ref.accept,
                ref.decided_by,
                ref.verdict,
                ref.proven,
            )
            for a, b in ((d.turnoff, ref.turnoff), (d.center, c), (d.shape, C)):
                np.testing.assert_array_equal(a, b)
            verdicts.add(d.verdict.name)
    assert {"ACCEPT", "REJECT"} <= verdicts


@pytest.mark.parametrize("seed", range(4))
def test_the_float_rule_on_floats_equals_the_array_rule_near_ties_and_on_degenerate_sets(seed):
    rng = np.random.default_rng(seed)
    rule = LandingRule(G)
    for _ in range(500):
        C = np.diag(1.0 / rng.uniform(0.005, 0.05, 3)) @ np.array(
            [[1.0, rng.uniform(-0.5, 0.5), 0.0], [0.0, 1.0, rng.uniform(-0.5, 0.5)], [0.0, 0.0, 1.0]]
        )
        c = rng.normal(size=3)
        h = Ellipsoid(c, C).half_widths()[0]
        C = C * max(h[0], h[1], 2 * h[2]) / 0.05 * (1.0 + rng.choice([-1, 1]) * 10.0 ** rng.uniform(-16, -1))
        kind = rng.integers(6)
        if kind == 0:
            C[2] = 0.0  # singular: infinite half-widths
        elif kind == 1:
            C[0, 0] = np.inf
        elif kind == 2:
            c[1] = np.nan
        d = rule.decide_float_values(c.tolist(), C.ravel().tolist())
        ref = rule.decide_float(c, C)
        assert (d.accept, d.decided_by, d.verdict) == (ref.accept, ref.decided_by, ref.verdict)
        np.testing.assert_array_equal(d.turnoff, ref.turnoff)


def test_the_rule_on_floats_needs_three_and_nine_values():
    rule = LandingRule(G)
    with pytest.raises(SetError, match="3 centre and 9 shape values; got 2 and 9"):
        rule.decide_values([0.0, 0.0], [1.0] * 9)
    with pytest.raises(SetError, match="3 centre and 9 shape values; got 3 and 4"):
        rule.outside_domain_values([0.0, 0.0, 0.0], [1.0] * 4)


def test_the_outside_domain_answer_on_floats_is_the_one_on_arrays():
    rng = np.random.default_rng(3)
    shapes = [rng.normal(size=(3, 3)) for _ in range(50)] + [np.zeros((3, 3)), np.full((3, 3), np.inf)]
    rule = LandingRule(G)
    for C in shapes:
        c = rng.normal(size=3)
        a = rule.outside_domain(c, C)
        b = rule.outside_domain_values(c.tolist(), C.ravel().tolist())
        assert a.verdict is b.verdict is Verdict.OUTSIDE_DOMAIN and not b.accept
        for u, v in ((a.center, b.center), (a.shape, b.shape), (a.turnoff, b.turnoff)):
            np.testing.assert_array_equal(u, v)


@pytest.mark.parametrize(
    ("x", "yhat", "match"),
    [
        (np.zeros(5), np.zeros(3), r"x of shape \(6,\) and yhat of shape \(3,\)"),
        (np.zeros((1, 6)), np.zeros(3), "use IPCModel.predict for batches"),
        (np.zeros(6), np.array([0.0, np.nan, 0.0]), "must be finite"),
    ],
)
def test_bad_queries_are_refused_with_a_message(trained, x, yhat, match):
    with pytest.raises(InvalidInputError, match=match):
        LandingQuery(IPCQuery(trained), G).decide(x, yhat)


def test_landing_needs_three_dimensions():
    q = IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=2, hidden=(4,), param="cholesky"))))
    assert q.ellipsoid(np.zeros(2), np.zeros(2))[1].shape == (2, 2)
    with pytest.raises(SetError, match="needs a 3-D ellipsoid; this model has n = 2"):
        LandingQuery(q, G)
    three = IPCQuery(IPCModel(IPCNetwork(ModelConfig(x_dim=2, y_dim=3, hidden=(4,), param="cholesky"))))
    with pytest.raises(SetError, match="the landing target must be a 3-D Box"):
        LandingQuery(three, Box([0.0, 0.0], [1.0, 1.0]))


def test_query_needs_a_model():
    with pytest.raises(InvalidInputError, match="needs an IPCModel"):
        IPCQuery("model.pt")  # type: ignore[arg-type]
    with pytest.raises(InvalidInputError, match=r"needs an IPCQuery \(IPCQuery\(model\)\)"):
        LandingQuery("model.pt", G)  # type: ignore[arg-type]


def test_the_constructor_compiles_the_kernels_the_first_query_runs(data):
    # a control loop's first frame must not pay a compilation: IPCQuery compiles the one-query
    # kernels when it is built, with the argument layouts decide() passes them, even when the
    # caller's rows are strided views
    import ipcverify.guard._kernels as domain_kernels
    import ipcverify.network._kernels as kernels

    mc = ModelConfig(x_dim=6, y_dim=3, hidden=(16, 16), param="lowrank", center="offset")
    model = calibrate(train(data[0], mc, TrainConfig(epochs=1, seed=3)).model, data[1], 0.05, 0.01)
    assert model.domain is not None
    q = LandingQuery(IPCQuery(model), G)
    kernel_list = (kernels.lowrank_one, domain_kernels.domain_one)
    compiled = [len(k.signatures) for k in kernel_list]
    assert all(c >= 1 for c in compiled)
    x, yhat = np.asfortranarray(data[1].x), np.asfortranarray(data[1].yhat)  # rows are strided
    assert not yhat[0].flags.c_contiguous
    for i in range(20):
        q.decide(x[i], yhat[i])
    assert [len(k.signatures) for k in kernel_list] == compiled


def _two_dimensional(n: int, seed: int) -> PerceptionDataset:
    """Synthetic 2-D perception: y from x, yhat = y + noise whose scale grows with |x_0|."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1.0, 1.0, (n, 2))
    y = np.column_stack([np.sin(2.0 * x[:, 0]), x[:, 1] ** 2])
    yhat = y + (0.05 + 0.1 * np.abs(x[:, :1])) * rng.standard_normal((n, 2))
    return PerceptionDataset(x, y, yhat)


@pytest.mark.parametrize("param", ["lowrank", "cholesky"])
def test_the_query_path_works_on_a_model_with_a_two_dimensional_output(param):
    mc = ModelConfig(x_dim=2, y_dim=2, hidden=(16,), param=param, members=3 if param == "lowrank" else 1)
    model = train(_two_dimensional(800, 0), mc, TrainConfig(epochs=3, seed=0)).model
    model = calibrate(model, _two_dimensional(1500, 1), 0.05, 0.01)
    assert model.domain is not None and model.config.y_dim == 2
    q = IPCQuery(model)
    test = _two_dimensional(40, 2)
    # half the queries moved far from the data: outside the domain of validity
    xs = np.concatenate([test.x[:20], test.x[20:] + 4.0])
    ref = model.predict_unguarded(xs, test.yhat)
    inside = model.domain.contains(xs, test.yhat)
    assert inside[:20].any() and not inside[20:].any()
    for i in range(len(xs)):
        s = q.evaluate(xs[i], test.yhat[i])
        assert s.center.shape == (2,) and s.shape.shape == (2, 2)
        np.testing.assert_allclose(s.center, ref.centers[i], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(s.shape, ref.shapes[i], rtol=1e-12, atol=1e-15)
        assert s.in_domain is bool(inside[i])
        center, flat, in_domain = q.values(xs[i], test.yhat[i])  # the same numbers as Python floats
        assert (center, flat, in_domain) == (s.center.tolist(), s.shape.ravel().tolist(), s.in_domain)
        c, C = q.ellipsoid(xs[i], test.yhat[i])
        np.testing.assert_array_equal(C, s.shape)
    with pytest.raises(InvalidInputError, match=r"x of shape \(2,\) and yhat of shape \(2,\)"):
        q.evaluate(np.zeros(2), np.zeros(3))
