"""Monte Carlo campaigns: the same runs whatever the backend, progress, errors, and the Ray path."""

from __future__ import annotations

import numpy as np
import pytest

from case_studies.quad_landing.landing.contracts import TrivialContract
from case_studies.quad_landing.landing.runs import Outcome
from case_studies.quad_landing.reproduction.campaign import CampaignSummary, run_campaign, summarize
from case_studies.quad_landing.reproduction.config import LandingParams, ScenarioParams
from case_studies.quad_landing.sim.config import load_config
from ipcverify.errors import InvalidInputError

CFG = load_config()
SCEN = ScenarioParams.defaults()
LAND = LandingParams.defaults(buffer_size=3)


def _key(runs):
    return [
        (
            r.scenario.index,
            r.outcome,
            r.n_queries,
            None if r.cut_position is None else r.cut_position.tolist(),
        )
        for r in runs
    ]


@pytest.fixture(scope="module")
def sequential():
    return run_campaign(
        TrivialContract(), 4, seed=3, sim_config=CFG, scenario=SCEN, landing=LAND, backend="sequential"
    )


def test_sequential_runs_are_in_order_and_summarized(sequential):
    assert [r.scenario.index for r in sequential] == [0, 1, 2, 3]
    s = summarize(sequential)
    assert s.runs == 4 and s.safe + s.unsafe + s.aborted == 4
    assert s.mean_queries == 1.0  # the baseline trusts its first measurement
    assert s.unsafe_interval is not None and s.unsafe_rate is not None and s.unsafe_upper is not None
    lo, hi = s.unsafe_interval
    assert lo <= s.unsafe_rate <= hi and s.unsafe_upper <= hi


def test_loky_gives_the_same_runs_and_reports_progress(sequential):
    seen = []
    runs = run_campaign(
        TrivialContract(),
        4,
        seed=3,
        sim_config=CFG,
        scenario=SCEN,
        landing=LAND,
        n_jobs=2,
        backend="loky",
        chunks_per_job=2,
        progress=seen.append,
    )
    assert _key(runs) == _key(sequential)
    assert sum(seen) == 4 and len(seen) == 4  # one chunk per run here


def test_campaign_rejects_bad_arguments():
    kw = {"seed": 0, "sim_config": CFG, "scenario": SCEN, "landing": LAND}
    with pytest.raises(InvalidInputError, match="n_runs"):
        run_campaign(TrivialContract(), 0, **kw)
    with pytest.raises(InvalidInputError, match="backend must be one of"):
        run_campaign(TrivialContract(), 1, backend="dask", **kw)
    with pytest.raises(InvalidInputError, match="n_jobs"):
        run_campaign(TrivialContract(), 1, n_jobs=0, **kw)


def test_summarize_counts_outcomes(sequential):
    s = summarize(sequential)
    assert s.unsafe == sum(r.outcome is Outcome.UNSAFE for r in sequential)
    assert s.unsafe_into_pad == sum(r.hit_pad for r in sequential) <= s.unsafe
    with pytest.raises(InvalidInputError, match="into the pad"):
        CampaignSummary(runs=1, safe=1, unsafe=0, aborted=0, confidence=0.95, unsafe_into_pad=1)
    assert s.safe_rate is not None and s.unsafe_rate is not None and s.aborted_rate is not None
    assert np.isclose(s.safe_rate + s.unsafe_rate + s.aborted_rate, 1.0)
    empty = summarize([])
    keys = {"runs", "safe", "unsafe", "aborted", "confidence", "unsafe_into_pad"}
    assert empty.runs == 0 and set(empty.to_dict()) == keys
    assert set(s.to_dict()) > set(empty.to_dict()) and s.to_dict()["unsafe_interval"] == s.unsafe_interval


@pytest.mark.slow
def test_ray_backend_on_a_local_instance_gives_the_same_runs(sequential):
    """Ray is in the dev extra, so this runs in the README's test command (a local instance, 2 CPUs)."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    try:
        runs = run_campaign(
            TrivialContract(), 4, seed=3, sim_config=CFG, scenario=SCEN, landing=LAND, n_jobs=2, backend="ray"
        )
    finally:
        ray.shutdown()
    assert _key(runs) == _key(sequential)


def test_ray_backend_connects_to_the_given_address(monkeypatch):
    """--address (or RAY_ADDRESS) reaches ray.init when Ray is not yet initialised."""
    import ray

    seen = {}

    class StopError(Exception):
        pass

    def fake_init(address=None, **kwargs):
        seen["address"] = address
        raise StopError

    monkeypatch.setattr(ray, "is_initialized", lambda: False)
    monkeypatch.setattr(ray, "init", fake_init)
    kw = {"seed": 0, "sim_config": CFG, "scenario": SCEN, "landing": LAND, "backend": "ray"}
    with pytest.raises(StopError):
        run_campaign(TrivialContract(), 1, address="ray://head:10001", **kw)
    assert seen["address"] == "ray://head:10001"
    monkeypatch.setenv("RAY_ADDRESS", "auto")
    with pytest.raises(StopError):
        run_campaign(TrivialContract(), 1, **kw)
    assert seen["address"] == "auto"


def test_ray_backend_without_ray_says_how_to_install(monkeypatch):
    import builtins

    real_import = builtins.__import__

    def no_ray(name, *args, **kwargs):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("no ray")
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", no_ray)
    with pytest.raises(InvalidInputError, match=r"pip install 'ipcverify\[ray\]'"):
        run_campaign(TrivialContract(), 1, seed=0, sim_config=CFG, scenario=SCEN, landing=LAND, backend="ray")
