"""Fixtures shared by the quad-landing case study's tests (``tests/quad_landing/...``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest
import torch

from case_studies.quad_landing.landing.contracts import TrivialContract
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.landing.scenario import draw_scenario
from case_studies.quad_landing.landing.state_machine import run_landing
from case_studies.quad_landing.reproduction.config import load_reproduce_config
from case_studies.quad_landing.sim.config import load_config
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.network._architecture import ModelConfig


@pytest.fixture
def make_ipc() -> Callable[[bool], IPCModel]:
    """A factory of small untrained IPCs on ``x_C`` (12) and ``yhat_C`` (3), calibrated or not."""

    def make(calibrated: bool) -> IPCModel:
        # seeded: the untrained weights (and so which rows a test's sets contain) must not depend
        # on which tests ran before in the same process
        with torch.random.fork_rng():
            torch.manual_seed(0)
            m = IPCModel(IPCNetwork(ModelConfig(x_dim=12, y_dim=3, hidden=(4,), param="cholesky")))
        if not calibrated:
            return m
        from ipcverify.calibration._global_scale import GlobalCalibration
        from ipcverify.calibration._threshold import threshold_scores
        from ipcverify.contract._model import network_fingerprint

        t = threshold_scores(np.linspace(0.1, 1.0, 200), 0.1, 0.1, "marginal")
        return m.with_calibration(
            GlobalCalibration(threshold=t, data_hash="d", network_hash=network_fingerprint(m.network))
        )

    return make


@pytest.fixture(scope="session")
def baseline_runs() -> list[LandingRun]:
    """Six landing runs of the trivial baseline with five camera buffers (it lands unsafely often)."""
    cfg, p = load_config(), load_reproduce_config()
    landing = dataclasses.replace(p.landing, buffer_size=5)
    return [
        run_landing(
            draw_scenario(i, seed=21, params=p.scenario, config=cfg),
            TrivialContract(),
            sim_config=cfg,
            params=landing,
        )
        for i in range(6)
    ]
