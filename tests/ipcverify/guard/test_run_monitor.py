"""The monitor of a claim about runs: one observation per completed run, whose null is the claim.

Runs of ``ROWS`` rows whose estimates carry a per-run offset and an AR(1) drift (so that a run's
violations come in bursts) are replayed through :func:`monitor_log`. With a contract calibrated by
runs on many runs, the claim holds, and the run monitor raises a false alarm in at most ``DELTA``
of the replays (a one-sided binomial test at ``LEVEL``); the row-by-row monitor of a row-level
contract on the same replays alarms far more often, because its null ("every row violates with
probability at most epsilon given the rows before it") is broken by the bursts. Proofs:
proofs/run_claims.md section 6. Every p-value is compared with ``LEVEL = ALPHA / N_CHECKS``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import torch
from scipy import stats

from ipcverify.calibration import Global, Grouped
from ipcverify.contract._calibrate import calibrate
from ipcverify.contract._model import IPCModel, IPCNetwork
from ipcverify.contract._prediction import monitor_log
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.guard import DomainSpec
from ipcverify.network._architecture import ModelConfig

ALPHA = 1e-3
N_CHECKS = 2
LEVEL = ALPHA / N_CHECKS
ROWS, DELTA, REPLAYS = 100, 0.05, 200


def _runs(n_runs: int, seed: int, shift: float = 0.0, far: float = 0.0) -> PerceptionDataset:
    """``n_runs`` runs: a per-run offset of the estimate and an AR(1) drift within each run (y + shift)."""
    base = make_lagged_perception(n_runs * ROWS, seed=seed)
    rng = np.random.default_rng(seed + 10_000)
    drift = rng.normal(size=(n_runs, ROWS, 3))
    for i in range(1, ROWS):
        drift[:, i] = 0.9 * drift[:, i - 1] + math.sqrt(1 - 0.81) * drift[:, i]
    offset = 0.1 * (rng.normal(size=(n_runs, 1, 3)) + drift).reshape(-1, 3)
    x = base.x + np.r_[0, 0, 0, 0, far, 0]
    run = np.repeat(np.arange(n_runs), ROWS)
    return PerceptionDataset(x, base.y + shift, base.yhat + offset, source=f"runs {seed}", extra={"run": run})


@pytest.fixture(scope="module")
def contracts():
    torch.manual_seed(3)
    net = IPCModel(IPCNetwork(ModelConfig.recipe("v1", x_dim=6, y_dim=3, hidden=(8,))))
    cal = _runs(400, seed=1)
    return {
        "runs": calibrate(net, cal, 0.1, DELTA, Grouped(column="run"), domain=DomainSpec(flag_rate=0.1)),
        "rows": calibrate(net, cal, 0.1, DELTA, Global(), domain=None),
    }


def test_the_run_monitor_observes_each_run_once_with_the_claim_as_its_null(contracts):
    data = _runs(30, seed=2)
    res = monitor_log(contracts["runs"], data)
    assert len(res.violated) == 30 and res.labels == tuple(str(i) for i in range(30))
    assert res.unit == "groups of run (share of rows outside)" and res.epsilon == 0.1
    assert "each new group's expected share of rows outside at most 0.1" in res.null
    assert res.domain_rate == 0.1 and "out-of-domain test raised no alarm" in res.sentence()
    d = res.to_dict()
    assert d["null"] == res.null and d["domain_rate"] == 0.1 and d["domain_alarm"] is False
    rows = monitor_log(contracts["rows"], data)
    assert len(rows.violated) == 30 * ROWS and "each row violating with probability at most" in rows.null


@pytest.mark.slow
def test_run_monitor_false_alarms_at_most_delta_where_the_row_monitor_fails(contracts):
    run_alarms = row_alarms = 0
    for r in range(REPLAYS):
        data = _runs(30, seed=100 + r)
        run_alarms += monitor_log(contracts["runs"], data).alarm_index is not None
        row_alarms += monitor_log(contracts["rows"], data).alarm_index is not None
    assert stats.binom.sf(run_alarms - 1, REPLAYS, DELTA) >= LEVEL, f"{run_alarms}/{REPLAYS} run alarms"
    # power of the check: the row monitor's null is broken by bursts within runs
    assert stats.binom.sf(row_alarms - 1, REPLAYS, DELTA) < LEVEL, f"only {row_alarms}/{REPLAYS} row alarms"


def test_a_shifted_log_alarms_after_a_few_runs_and_far_inputs_raise_the_domain_alarm(contracts):
    bad = monitor_log(contracts["runs"], _runs(30, seed=3, shift=0.6))
    assert bad.alarm_index is not None and bad.alarm_index < 15
    assert bad.sentence().startswith(f"ALARM at group '{bad.labels[bad.alarm_index]}'")
    far = monitor_log(contracts["runs"], _runs(30, seed=4, far=40.0))
    assert far.domain_alarm_index is not None and "DOMAIN ALARM at group" in far.sentence()
