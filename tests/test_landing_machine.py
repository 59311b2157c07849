"""The landing state machine: exact accept and cut tests (proofs/landing_safety.md), waypoints,
contracts, scenarios, approach flights and the certified-bound helpers."""

from __future__ import annotations

import dataclasses
import doctest
import importlib
import json
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from case_studies.quad_landing import Flight, Pad, hover_state
from case_studies.quad_landing.data.approach import ApproachParams, collect_approach, fly_approach
from case_studies.quad_landing.data.datasets import (
    alignment_deg,
    as_dataset,
    cached_mixed,
    collect_mixed,
    is_cached,
)
from case_studies.quad_landing.landing.contracts import LearnedContract, TrivialContract
from case_studies.quad_landing.landing.runs import Outcome
from case_studies.quad_landing.landing.scenario import ScenarioParams, draw_scenario, stopping_reference
from case_studies.quad_landing.landing.state_machine import (
    LandingParams,
    cut_allowed,
    cut_box,
    decision_target,
    in_target,
    new_waypoint,
    run_landing,
)
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    hoeffding_upper,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.config import load_reproduce_config
from case_studies.quad_landing.reproduction.table1 import RatesRising, table1
from case_studies.quad_landing.settings import ConfigError
from case_studies.quad_landing.sim.config import load_config
from case_studies.quad_landing.sim.legs import fly_leg
from ipcverify.containment import Status
from ipcverify.errors import InvalidInputError
from ipcverify.exact import exact_vector
from ipcverify.landing import LANDING_TARGET, landing_decision
from ipcverify.model import IPCModel, IPCNetwork, ModelConfig
from ipcverify.sets import Ellipsoid

CFG = load_config()
TAUS = [0.001, 0.005, 0.01, 0.02]
MODULES = [
    "reproduction.config",
    "landing.scenario",
    "sim.legs",
    "data.approach",
    "landing.contracts",
    "landing.runs",
    "landing.state_machine",
    "reproduction.campaign",
    "data.datasets",
    "reproduction.learn",
    "reproduction.table1",
    "reproduction.certified",
    "reproduction.figures",
    "reproduction.report_page",
    "reproduction.pipeline",
    "reproduction.claims",
]


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    module = importlib.import_module(f"case_studies.quad_landing.{name}")
    result = doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0


# ----------------------------------------------------------------- Theorem 1 (exact)
@pytest.mark.parametrize("tau", TAUS)
def test_box_sum_is_exactly_G(tau):
    lo, hi = cut_box(tau)
    g_tau = decision_target(tau)
    gl, gu = exact_vector(LANDING_TARGET.lower), exact_vector(LANDING_TARGET.upper)
    tl, tu = exact_vector(g_tau.lower), exact_vector(g_tau.upper)
    assert [a + b for a, b in zip(lo, tl, strict=True)] == gl
    assert [a + b for a, b in zip(hi, tu, strict=True)] == gu
    # K is about [-tau, tau]^2 x [0, 2 tau]
    assert np.allclose([float(v) for v in lo], [-tau, -tau, 0.0], atol=1e-15)
    assert np.allclose([float(v) for v in hi], [tau, tau, 2 * tau], atol=1e-15)


def _rational_point_in(e: Ellipsoid, u: np.ndarray, r: Fraction) -> list[Fraction]:
    """An exact point c + r C^{-1} u / ||u|| (approx.) that is certainly inside E, checked exactly."""
    d = np.linalg.solve(e.shapes[0], u / np.linalg.norm(u))
    y = [Fraction(float(c)) + r * Fraction(float(v)) for c, v in zip(e.centers[0], d, strict=True)]
    C = [[Fraction(float(v)) for v in row] for row in e.shapes[0]]
    diff = [a - Fraction(float(c)) for a, c in zip(y, e.centers[0], strict=True)]
    g2 = sum((sum(C[i][j] * diff[j] for j in range(3))) ** 2 for i in range(3))
    return y if g2 <= 1 else []


@settings(max_examples=60, deadline=None, derandomize=True)
@given(
    center=st.lists(st.floats(-2.5, 2.5), min_size=3, max_size=3),
    axes=st.lists(st.floats(0.002, 0.03), min_size=3, max_size=3),
    angle=st.floats(-np.pi, np.pi),
    tau_index=st.integers(0, len(TAUS) - 1),
    u=st.lists(st.floats(-1, 1), min_size=3, max_size=3),
    r=st.fractions(0, 1),
    cut=st.lists(st.fractions(0, 1), min_size=3, max_size=3),
)
def test_theorem1_accept_and_cut_give_p_minus_y_in_G(center, axes, angle, tau_index, u, r, cut):
    tau = TAUS[tau_index]
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    e = Ellipsoid(np.array(center), np.diag(1.0 / np.array(axes)) @ R.T)
    d = landing_decision(e, decision_target(tau))
    if not d.accept or np.linalg.norm(u) < 1e-6:
        return
    y = _rational_point_in(e, np.array(u), r)
    if not y:
        return
    lo, hi = cut_box(tau)
    P = exact_vector(d.turnoff)
    p = [Pi + lo_i + w * (hi_i - lo_i) for Pi, lo_i, hi_i, w in zip(P, lo, hi, cut, strict=True)]
    diff = [a - b for a, b in zip(p, y, strict=True)]
    gl, gu = exact_vector(LANDING_TARGET.lower), exact_vector(LANDING_TARGET.upper)
    assert all(a <= v <= b for a, v, b in zip(gl, diff, gu, strict=True))


def test_cut_allowed_is_exact_at_the_faces():
    P = np.array([0.3, -1.2, 0.021])
    tau = 0.005
    lo, hi = cut_box(tau)
    corner_hi = np.array([float(Fraction(float(a)) + b) for a, b in zip(P, hi, strict=True)])
    # the float nearest the exact face may lie just outside: the test must decide exactly
    exact_inside = all(
        Fraction(float(v)) - Fraction(float(a)) <= b for v, a, b in zip(corner_hi, P, hi, strict=True)
    )
    assert cut_allowed(corner_hi, P, tau) == exact_inside
    assert cut_allowed(P + np.array([0.0, 0.0, tau]), P, tau)
    assert not cut_allowed(P + np.array([0.0, 0.0, -1e-12]), P, tau)
    assert not cut_allowed(P + np.array([tau * 1.001, 0.0, tau]), P, tau)


@pytest.mark.parametrize("tau", [0.0, 0.025, 0.03, float("nan")])
def test_decision_target_refuses_a_bad_tau(tau):
    with pytest.raises(InvalidInputError, match="tau must be > 0"):
        decision_target(tau)


def test_in_target_is_the_closed_box():
    assert in_target(np.array([0.05, -0.05, 0.05]))
    assert not in_target(np.array([0.0501, 0.0, 0.01]))
    assert not in_target(np.array([0.0, 0.0, -1e-9]))


# ----------------------------------------------------------------- New Waypoint
def test_new_waypoint_is_the_surface_point_when_high_enough():
    params = LandingParams.defaults(measure_height=0.3)
    e = Ellipsoid(np.array([0.0, 0.0, 0.0]), np.eye(3) * 2.0)  # radius 0.5
    p = np.array([0.0, 0.0, 2.0])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=params)
    # the segment from p to c leaves the ball at height 0.5, above 0.3 + 0.05
    np.testing.assert_allclose(w, [0.0, 0.0, 0.5], atol=1e-12)
    assert float(np.linalg.norm(e.shapes[0] @ (w - e.centers[0]))) == pytest.approx(1.0)


def test_new_waypoint_is_raised_to_the_measuring_height_and_clamped():
    params = LandingParams.defaults()
    e = Ellipsoid(np.array([2.9, 0.4, 0.0]), np.eye(3) * 20.0)  # radius 0.05
    p = np.array([2.0, 0.4, 1.8])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=params)
    assert w[2] == pytest.approx(params.measure_height + 0.05)
    assert 2.8 < w[0] < 2.9
    far = new_waypoint(
        np.array([0.0, 0.0, 2.9]),
        Ellipsoid(np.array([3.5, 0.0, 0.0]), np.eye(3) * 20.0),
        flight=Flight(buffer_size=1),
        params=params,
    )
    assert far[0] == 3.0  # clamped into the workspace


def test_new_waypoint_inside_the_ellipsoid_keeps_the_position():
    e = Ellipsoid(np.array([0.0, 0.0, 1.0]), np.eye(3) * 0.5)  # radius 2: p is inside
    p = np.array([0.1, 0.0, 1.2])
    w = new_waypoint(p, e, flight=Flight(buffer_size=1), params=LandingParams.defaults())
    np.testing.assert_allclose(w[:2], p[:2])


# ----------------------------------------------------------------- contracts
def _model(calibrated: bool) -> IPCModel:
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=12, y_dim=3, hidden=(4,))))
    if not calibrated:
        return m
    from ipcverify.calibration import GlobalCalibration, network_fingerprint, threshold_scores

    t = threshold_scores(np.linspace(0.1, 1.0, 200), 0.1, 0.1, "marginal")
    return m.with_calibration(
        GlobalCalibration(threshold=t, data_hash="d", network_hash=network_fingerprint(m.network))
    )


def test_learned_contract_refuses_an_uncalibrated_model():
    with pytest.raises(InvalidInputError, match="calibrated IPC"):
        LearnedContract(_model(False))


def test_learned_contract_refuses_the_wrong_dimensions():
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(4,))))
    from ipcverify.calibration import GlobalCalibration, threshold_scores

    t = threshold_scores(np.linspace(0.1, 1.0, 200), 0.1, 0.1, "marginal")
    with pytest.raises(InvalidInputError, match="x_dim=6"):
        LearnedContract(m.with_calibration(GlobalCalibration(threshold=t, data_hash="d", network_hash="h")))


def test_learned_contract_matches_predict_moved_to_the_world():
    model = _model(True)
    contract = LearnedContract(model)
    flight = Flight(buffer_size=1, seed=0)
    flight.reset(hover_state((0.2, -0.1, 1.2), yaw=0.4), Pad((0.0, 0.0, 0.0), yaw=0.9))
    m = flight.measure()
    e = contract.world_ellipsoid(m)
    ref = model.predict(m.x_c, m.yhat_c)
    T = m.world_from_camera
    np.testing.assert_allclose(e.centers[0], T.apply(ref.centers[0]), atol=1e-12)
    # the same set: a point inside in C is inside in W, with the same score
    y_c = ref.centers[0] + 0.5 * np.linalg.solve(ref.shapes[0], np.array([1.0, 0.0, 0.0]))
    assert e.g(T.apply(y_c))[0] == pytest.approx(ref.g(y_c)[0], abs=1e-9)


def test_contracts_need_a_detection():
    flight = Flight(buffer_size=1, seed=0)
    flight.reset(hover_state((2.5, 2.5, 1.0)), Pad((-2.5, -2.5, 0.0), yaw=0.3))  # pad far out of view
    m = flight.measure()
    assert m.yhat_c is None
    with pytest.raises(InvalidInputError, match="detection"):
        TrivialContract().world_ellipsoid(m)
    with pytest.raises(InvalidInputError, match="positive"):
        TrivialContract(precision=0.0)


# ----------------------------------------------------------------- scenarios and legs
def test_scenarios_are_reproducible_and_independent_of_anything_else():
    a = draw_scenario(7, seed=3, params=ScenarioParams.defaults(), config=CFG)
    b = draw_scenario(7, seed=3, params=ScenarioParams.defaults(), config=CFG)
    c = draw_scenario(8, seed=3, params=ScenarioParams.defaults(), config=CFG)
    assert np.array_equal(a.start, b.start) and a.pad.yaw == b.pad.yaw and a.noise_seed == b.noise_seed
    assert not np.array_equal(a.start, c.start)


def test_scenarios_respect_their_ranges_and_keep_pad_edges_off_the_image_axes():
    p = ScenarioParams.defaults()
    for i in range(200):
        sc = draw_scenario(i, seed=0, params=p, config=CFG)
        assert np.all(np.abs(sc.pad.position[:2]) <= p.pad_region)
        assert p.start_distance[0] - 1e-9 <= sc.start_distance <= p.start_distance[1] + 1e-9
        speed = float(np.linalg.norm(sc.start[3:6]))
        assert p.transit_speed[0] - 1e-9 <= speed <= p.transit_speed[1] + 1e-9
        assert (
            np.all(np.abs(sc.start[:2]) <= 3.0)
            and np.linalg.norm(sc.search_point[:2] - sc.pad.position[:2]) <= 0.3
        )
        assert float(alignment_deg(sc.yaw, sc.pad.yaw)) >= p.aligned_margin_deg - 1e-9


def test_stopping_reference_is_smooth_and_stops():
    from case_studies.quad_landing.sim.lqr import Reference

    ref = stopping_reference(Reference((0.0, 0.0, 1.0), (1.5, 0.0, 0.0)), 0.0, 1.5)
    t = np.linspace(0, 3, 301)
    v = np.array([ref(s).velocity[0] for s in t])
    a = np.array([ref(s).acceleration[0] for s in t])
    assert v[0] == pytest.approx(1.5) and v[-1] == 0.0
    assert np.all(np.diff(v) <= 1e-12) and a.min() >= -1.5 - 1e-9 and abs(a[0]) < 1e-9
    with pytest.raises(InvalidInputError, match="deceleration"):
        stopping_reference(Reference((0.0, 0.0, 1.0)), 0.0, 0.0)


def test_fly_leg_checks_its_target():
    flight = Flight(buffer_size=1)
    flight.reset(hover_state((0.0, 0.0, 1.0)))
    with pytest.raises(InvalidInputError, match="outside the workspace"):
        fly_leg(flight, (0.0, 0.0, 3.5), yaw=0.0, timeout=1.0)
    with pytest.raises(InvalidInputError, match="timeout"):
        fly_leg(flight, (0.0, 0.0, 1.0), yaw=0.0, timeout=0.0)


def test_approach_flights_are_the_same_at_every_buffer_size():
    params = ApproachParams.defaults(hover_points=1, dwell=(0.2, 0.2))
    a = fly_approach(Flight(buffer_size=1), 2, seed=5, params=params)
    b = fly_approach(Flight(buffer_size=3), 2, seed=5, params=params)
    n = min(len(a.rows), len(b.rows))
    assert n > 10
    # same states and truths (columns 0..14 = x_C, y_C); the perceived position differs
    np.testing.assert_allclose(a.rows[:n, :15], b.rows[:n, :15])
    assert not np.allclose(a.rows[:n, 15:18], b.rows[:n, 15:18])


def test_collect_approach_checks_its_arguments():
    with pytest.raises(InvalidInputError, match="positive integer"):
        collect_approach(0, buffer_size=1, seed=0, params=ApproachParams.defaults())
    with pytest.raises(InvalidInputError, match="non-negative"):
        collect_approach(5, buffer_size=1, seed=-1, params=ApproachParams.defaults())


def test_mixed_data_hold_no_measurement_with_pad_edges_on_the_image_axes():
    params = ApproachParams.defaults(hover_points=1)
    data = collect_mixed(300, buffer_size=1, seed=1, approach=params)
    paths = data[data["source"] == 0]
    assert len(data) == 300 and len(paths) == 150
    assert alignment_deg(paths["xw_8"].to_numpy(), CFG.pad.yaw).min() >= params.aligned_margin_deg
    assert as_dataset(data).extra["source"].shape == (300,)


def test_a_cached_dataset_records_its_buffer_size_once(tmp_path):
    params = ApproachParams.defaults(hover_points=1)
    path = tmp_path / "d.parquet"
    cfg = CFG.replace(collect={"buffer_size": 4})  # the collect command's default: not this dataset's
    data, cached = cached_mixed(path, 40, buffer_size=1, seed=3, approach=params, config=cfg)
    assert not cached and len(data) == 40

    def keys(obj, name):
        if isinstance(obj, dict):
            return sum((k == name) + keys(v, name) for k, v in obj.items())
        return sum(keys(v, name) for v in obj) if isinstance(obj, list) else 0

    key = json.loads(path.with_suffix(".key.json").read_text())
    assert key["buffer_size"] == 1 and keys(key, "buffer_size") == 1
    assert is_cached(path, 40, buffer_size=1, seed=3, approach=params, config=CFG)
    assert not is_cached(path, 40, buffer_size=2, seed=3, approach=params, config=CFG)


# ----------------------------------------------------------------- runs
@pytest.fixture(scope="module")
def baseline_runs():
    p = load_reproduce_config()
    return [
        run_landing(
            draw_scenario(i, seed=21, params=p.scenario, config=CFG),
            TrivialContract(),
            sim_config=CFG,
            params=p.landing,
        )
        for i in range(6)
    ]


def test_unsafe_runs_have_a_violated_accepted_query(baseline_runs):
    """Corollary 1 on the baseline at the landing buffer size (it lands unsafely often)."""
    assert any(r.outcome is Outcome.UNSAFE for r in baseline_runs)
    for r in baseline_runs:
        assert r.n_queries == 1 and r.queries[0].accepted  # the baseline trusts its first measurement
        if r.outcome is Outcome.UNSAFE:
            assert r.queries[-1].truth_inside is False
        if r.outcome is not Outcome.ABORTED:
            assert r.certificate_verified
            assert cut_allowed(r.cut_position, r.turnoff, 0.005)
            assert (r.outcome is Outcome.SAFE) == in_target(r.offset)


def test_a_run_records_what_the_figures_need(baseline_runs):
    r = baseline_runs[0]
    d = r.to_dict(trajectory=True)
    assert d["outcome"] in {"safe", "unsafe", "aborted"} and len(d["trajectory"]) == len(r.trajectory) > 10
    assert r.queries[0].time > 0 and r.queries[0].half_widths is not None


def test_a_run_that_reaches_the_cap_aborts_and_never_cuts():
    class Huge:
        name = "huge"

        def world_ellipsoid(self, m):
            return Ellipsoid(m.yhat_w, np.eye(3) * 2.0)  # 0.5 m radius: never fits in G

    p = load_reproduce_config()
    sc = draw_scenario(0, seed=21, params=p.scenario, config=CFG)
    run = run_landing(sc, Huge(), sim_config=CFG, params=dataclasses.replace(p.landing, max_measurements=2))
    assert run.outcome is Outcome.ABORTED and run.cut_position is None and "cap of 2" in run.reason
    assert run.n_queries == 2 and not any(q.accepted for q in run.queries)


def test_landing_decision_status_matches_acceptance():
    d = landing_decision(Ellipsoid(np.array([0.0, 0.0, 0.01]), np.eye(3) * 100.0), decision_target(0.005))
    assert d.accept and d.certificate.status is Status.PROVEN


# ----------------------------------------------------------------- certified bound and statistics
def test_certified_bound_formula():
    b = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[2] * 200)
    assert b.union_bound == pytest.approx(0.016)
    ucb = 2 + 8 * np.sqrt(np.log(1000) / 400)
    assert b.mean_queries_upper == pytest.approx(ucb)
    assert b.refined_bound == pytest.approx(0.002 * ucb)
    assert b.refined_confidence == pytest.approx(0.998)
    assert certified_bound(0.2, 0.01, max_queries=8, queries_per_run=[1]).vacuous


def test_certified_bound_checks_its_inputs():
    with pytest.raises(InvalidInputError, match="strictly between"):
        certified_bound(0.0, 0.01, max_queries=3, queries_per_run=[1])
    with pytest.raises(InvalidInputError, match="positive integer"):
        certified_bound(0.01, 0.01, max_queries=0, queries_per_run=[1])
    with pytest.raises(InvalidInputError, match="within"):
        hoeffding_upper([5], 0, 3, 0.1)


def test_hoeffding_upper_covers_the_mean():
    """Coverage of the Hoeffding bound over 2000 seeded repetitions (it is conservative)."""
    rng = np.random.default_rng(0)
    delta, n, reps = 0.05, 50, 2000
    misses = sum(hoeffding_upper(rng.integers(0, 4, n), 0, 3, delta) < 1.5 for _ in range(reps))
    # misses ~ Binomial(reps, p) with p <= delta; 0.05 * 2000 = 100, a 5-sigma margin is ~49
    assert misses <= reps * delta + 5 * np.sqrt(reps * delta * (1 - delta))


def test_closed_loop_violations_and_empirical_vs_certified(baseline_runs):
    loop = closed_loop_violations(baseline_runs, 0.002)
    k = sum(1 for r in baseline_runs if r.queries[0].truth_inside is False)
    assert loop["first"]["n"] == len(baseline_runs) and loop["first"]["violations"] == k
    if k:
        assert loop["first"]["contradicts_epsilon"]  # a 0.1 mm ball misses almost always
    b = certified_bound(0.002, 0.001, max_queries=1, queries_per_run=[1] * len(baseline_runs))
    ev = unsafe_vs_certified(baseline_runs, b)
    n_unsafe = sum(r.outcome is Outcome.UNSAFE for r in baseline_runs)
    assert ev.unsafe == n_unsafe and ev.bound_at_least_rate == (0.002 >= n_unsafe / len(baseline_runs))


def test_claims_and_summary_records_from_real_runs(baseline_runs):
    """The typed results of the reproduction on a few real runs: claims, and summary.json's layout."""
    from case_studies.quad_landing.reproduction.campaign import summarize
    from case_studies.quad_landing.reproduction.claims import evaluate_claims
    from case_studies.quad_landing.reproduction.results import ContractResults, LandingExperiment
    from ipcverify.data import PerceptionDataset

    runs = tuple(baseline_runs)
    bound = certified_bound(0.002, 0.001, max_queries=8, queries_per_run=[r.n_queries for r in runs])
    side = {
        "monte_carlo": summarize(runs),
        "runs": runs,
        "paper": summarize(runs[:3]),
        "paper_runs": runs[:3],
    }
    landing = LandingExperiment(
        buffer_size=3,
        tracking_tolerance=0.005,
        max_measurements=8,
        ipc=ContractResults(**side, certified=bound, empirical_vs_certified=unsafe_vs_certified(runs, bound)),
        baseline=ContractResults(**side),
        closed_loop=closed_loop_violations(runs, 0.002),
        coverage={"shift_detected": False},
    )
    x = np.zeros((20, 12))
    x[:, 2] = 1.0
    table = table1(_model(True), {1: PerceptionDataset(x, np.zeros((20, 3)), np.zeros((20, 3)))})
    claims = evaluate_claims(table, landing)
    n_unsafe = sum(r.outcome is Outcome.UNSAFE for r in runs)
    assert claims["baseline_unsafe_in_most_runs"].holds == (n_unsafe > 0.5 * len(runs))
    assert claims["ipc_safe_all_paper_runs"].holds == all(r.outcome is Outcome.SAFE for r in runs[:3])
    assert claims["table1_buffer1_at_most_1pct"].holds and not claims["table1_buffer1_at_most_1pct"].supported
    assert claims["certified_bound_at_least_empirical"].holds == (bound.union_bound >= n_unsafe / len(runs))
    d = landing.to_dict()
    assert d["ipc"]["certified_unsafe_bound"] == bound.union_bound and "certified" not in d["baseline"]
    assert len(d["ipc"]["runs_detail"]) == len(runs) and len(d["ipc"]["paper_runs"]["runs_detail"]) == 3
    assert d["ipc"]["unsafe"] == n_unsafe and landing.shift_detected is False
    with pytest.raises(InvalidInputError, match="count the runs"):
        ContractResults(**{**side, "runs": runs[:2]})


# ----------------------------------------------------------------- Table I helpers
def test_table1_counts_and_simultaneous_intervals():
    from ipcverify.data import PerceptionDataset

    m = _model(True)
    x = np.zeros((50, 12))
    x[:, 2] = 1.0
    near = PerceptionDataset(x, np.zeros((50, 3)), np.zeros((50, 3)))
    far = PerceptionDataset(x, np.full((50, 3), 1e3), np.zeros((50, 3)))
    rows = table1(m, {2: far, 1: near}, delta=0.1)
    assert rows.buffers == (1, 2)
    assert rows.row(1).violations == 0 and rows.row(2).violations == 50
    assert rows.row(1).confidence == 0.9 and rows.row(1).paper_rate == 0.0019
    assert rows.rising() == RatesRising(strict=True, separated=True)
    assert rows.to_dict()["2"]["violations"] == 50
    with pytest.raises(InvalidInputError, match="no row for buffer size 3"):
        rows.row(3)
    with pytest.raises(InvalidInputError, match="at least one"):
        table1(m, {})


# ----------------------------------------------------------------- settings
def test_reproduce_config_rejects_unknown_keys_and_bad_values(tmp_path):
    with pytest.raises(ConfigError, match="unknown key landing.cap"):
        load_reproduce_config(overrides={"landing": {"cap": 3}})
    with pytest.raises(ConfigError, match="unknown section"):
        load_reproduce_config(overrides={"flight": {}})
    with pytest.raises(ConfigError, match="tracking_tolerance"):
        load_reproduce_config(overrides={"landing": {"tracking_tolerance": 0.03}})
    with pytest.raises(ConfigError, match="must include 1"):
        load_reproduce_config(overrides={"sizes": {"buffers": [2, 3]}})
    with pytest.raises(ConfigError, match="two numbers"):
        load_reproduce_config(overrides={"scenario": {"transit_speed": [1.0]}})
    bad = tmp_path / "bad.toml"
    bad.write_text("[landing\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_reproduce_config(bad)
    good = tmp_path / "good.toml"
    good.write_text("[landing]\nmax_measurements = 4\n[quick.sizes]\nmc_runs = 3\n")
    assert load_reproduce_config(good).landing.max_measurements == 4
    assert load_reproduce_config(good, quick=True).sizes.mc_runs == 3
