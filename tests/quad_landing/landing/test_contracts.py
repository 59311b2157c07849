"""The perception contracts: calibrated IPCs (raw only when asked), moved to the world frame; the baseline."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing import Flight, Pad, hover_state
from case_studies.quad_landing.landing.contracts import LearnedContract, TrivialContract
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.sets._box import Box
from ipcverify.sets._ellipsoid import Ellipsoid

G = Box([-0.05, -0.05, 0.0], [0.05, 0.05, 0.05])


def test_learned_contract_refuses_an_uncalibrated_model(make_ipc):
    with pytest.raises(InvalidInputError, match="the model is not calibrated"):
        LearnedContract(make_ipc(False))


def test_an_uncalibrated_contract_is_flown_only_when_asked_and_only_raw(make_ipc):
    """The paper's protocol flies the network as trained: that needs ``uncalibrated=True`` (no
    guarantee), and a calibrated model is refused with it (its calibration would be ignored)."""
    raw = make_ipc(False)
    contract = LearnedContract(raw, "paper_raw", uncalibrated=True)
    flight = Flight(buffer_size=1, seed=0)
    flight.reset(hover_state((0.2, -0.1, 1.2), yaw=0.4), Pad((0.0, 0.0, 0.0), yaw=0.9))
    m = flight.measure()
    d = contract.decide(m, G)
    ref = raw.predict_raw(m.x_c, m.yhat_c)
    np.testing.assert_allclose(d.center, m.world_from_camera.apply(ref.centers[0]), atol=1e-12)
    with pytest.raises(InvalidInputError, match="carries a calibration"):
        LearnedContract(make_ipc(True), uncalibrated=True)


def test_learned_contract_refuses_the_wrong_dimensions():
    m = IPCModel(IPCNetwork(ModelConfig(x_dim=6, y_dim=3, hidden=(4,), param="cholesky")))
    from ipcverify.calibration._global_scale import GlobalCalibration
    from ipcverify.calibration._threshold import threshold_scores

    t = threshold_scores(np.linspace(0.1, 1.0, 200), 0.1, 0.1, "marginal")
    with pytest.raises(InvalidInputError, match="x_dim=6"):
        LearnedContract(m.with_calibration(GlobalCalibration(threshold=t, data_hash="d", network_hash="h")))


def test_learned_contract_matches_predict_moved_to_the_world(make_ipc):
    model = make_ipc(True)
    contract = LearnedContract(model)
    flight = Flight(buffer_size=1, seed=0)
    flight.reset(hover_state((0.2, -0.1, 1.2), yaw=0.4), Pad((0.0, 0.0, 0.0), yaw=0.9))
    m = flight.measure()
    d = contract.decide(m, G)
    e = Ellipsoid(d.center, d.shape)
    ref = model.predict_unguarded(m.x_c, m.yhat_c)
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
        TrivialContract().decide(m, G)
    with pytest.raises(InvalidInputError, match="positive"):
        TrivialContract(precision=0.0)


def test_both_contracts_answer_through_the_same_landing_rule(make_ipc):
    """The learned IPC goes through IPCQuery; the baseline through the same LandingRule."""
    flight = Flight(buffer_size=1, seed=0)
    # not exactly centred: OpenCV's unrefined corners of a centred, level pad are symmetric
    # integers on which IPPE_SQUARE gives no pose (docs/case_study.md)
    flight.reset(hover_state((0.05, -0.03, 1.0)), Pad((0.0, 0.0, 0.0), yaw=0.3))
    m = flight.measure()
    base = TrivialContract().decide(m, G)
    assert base.accept and base.proven and base.proof is not None
    np.testing.assert_array_equal(base.center, m.yhat_w)
    contract = LearnedContract(make_ipc(True))
    d = contract.decide(m, G)
    assert contract.query(G) is contract.query(Box(G.lower, G.upper))  # built once per target
    assert d.accept == (d.proof is not None and d.proof.accept)
