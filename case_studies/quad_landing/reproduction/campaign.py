"""Monte Carlo landing campaigns on the local cores (joblib) or a Ray cluster.

:func:`run_campaign` flies scenarios ``0 .. n - 1`` of a seeded campaign
(:func:`.scenario.draw_scenario`) with one contract and returns the runs in index
order. The scenarios are cut into chunks; each chunk is one joblib task that builds one
simulator and flies its scenarios one after another. The result does not depend on the
backend, the number of jobs or the chunking: scenario ``i`` is the same pad, start and
sensor noise wherever it runs.

Backends
--------
* ``"loky"`` (default): processes on this machine, ``n_jobs`` of them (default: all cores).
* ``"sequential"``: in this process (debugging, tiny campaigns).
* ``"ray"``: the same tasks through joblib's Ray backend (``pip install 'ipcverify[ray]'``).
  :func:`run_campaign` connects to the cluster at ``address`` (or ``RAY_ADDRESS``, e.g.
  ``ray://head:10001`` or ``auto``) unless Ray is already initialised, and starts a local
  instance when neither is given. Each task needs the ``ipcverify`` package (with
  ``case_studies``) importable on the workers: install it in the cluster's image or pass
  ``runtime_env={"py_modules": [...]}`` to ``ray.init``. See ``docs/ray.md``.

Examples
--------
>>> from case_studies.quad_landing.sim.config import load_config
>>> from case_studies.quad_landing.landing.contracts import TrivialContract
>>> from case_studies.quad_landing.landing.scenario import ScenarioParams
>>> from case_studies.quad_landing.landing.state_machine import LandingParams
>>> runs = run_campaign(TrivialContract(), 2, seed=5, sim_config=load_config(),
...                     scenario=ScenarioParams.defaults(),
...                     landing=LandingParams.defaults(buffer_size=1), backend="sequential")
>>> [r.scenario.index for r in runs], summarize(runs).runs
([0, 1], 2)
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import joblib
import numpy as np

from case_studies.quad_landing.landing.contracts import Contract
from case_studies.quad_landing.landing.runs import LandingRun, Outcome
from case_studies.quad_landing.landing.scenario import ScenarioParams, draw_scenario
from case_studies.quad_landing.landing.state_machine import LandingParams, run_landing
from case_studies.quad_landing.sim.config import SimConfig
from case_studies.quad_landing.sim.flight import Flight
from ipcverify.calibration._bounds import (
    clopper_pearson_interval,
    clopper_pearson_lower,
    clopper_pearson_upper,
)
from ipcverify.errors import InvalidInputError

__all__ = ["BACKENDS", "CampaignSummary", "run_campaign", "summarize", "default_jobs"]

#: Supported joblib backends.
BACKENDS = ("loky", "sequential", "ray")


def default_jobs() -> int:
    """Cores available to this process (``os.sched_getaffinity``), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def _fly_chunk(
    indices: Sequence[int],
    contract: Contract,
    seed: int,
    sim_config: SimConfig,
    scenario: ScenarioParams,
    landing: LandingParams,
) -> list[LandingRun]:
    """One task: one simulator, the chunk's scenarios in order (runs in a worker)."""
    import cv2
    import torch

    cv2.setNumThreads(1)
    torch.set_num_threads(1)
    flight = Flight(sim_config, buffer_size=landing.buffer_size)
    out = []
    for i in indices:
        sc = draw_scenario(int(i), seed=seed, params=scenario, config=sim_config)
        out.append(run_landing(sc, contract, sim_config=sim_config, params=landing, flight=flight))
    return out


def _ray_backend(address: str | None) -> None:
    try:
        import ray
        from ray.util.joblib import register_ray
    except ImportError:
        raise InvalidInputError(
            "the Ray backend needs Ray: pip install 'ipcverify[ray]' (or pip install 'ray[default]')"
        ) from None
    register_ray()
    if not ray.is_initialized():
        ray.init(
            address=address or os.environ.get("RAY_ADDRESS"), include_dashboard=False, log_to_driver=False
        )


def _chunks(n: int, n_tasks: int) -> list[list[int]]:
    size = max(1, math.ceil(n / n_tasks))
    return [list(range(i, min(n, i + size))) for i in range(0, n, size)]


def run_campaign(
    contract: Contract,
    n_runs: int,
    *,
    seed: int,
    sim_config: SimConfig,
    scenario: ScenarioParams,
    landing: LandingParams,
    n_jobs: int | None = None,
    backend: str = "loky",
    chunks_per_job: int = 4,
    progress: Callable[[int], None] | None = None,
    address: str | None = None,
) -> list[LandingRun]:
    """Fly scenarios ``0 .. n_runs - 1`` of campaign ``seed`` with ``contract``.

    Parameters
    ----------
    contract : Contract
        A learned IPC or the trivial baseline (sent to the workers by pickling).
    n_runs : int
        Number of runs.
    seed : int
        Campaign seed (with the index, fixes each scenario).
    sim_config : SimConfig
        The simulator.
    scenario, landing : ScenarioParams, LandingParams
        Scenario ranges and state-machine settings.
    n_jobs : int, optional
        Parallel workers (default: :func:`default_jobs`; for Ray, the cluster's CPUs).
    backend : {"loky", "sequential", "ray"}
        joblib backend.
    chunks_per_job : int
        Tasks per worker (smaller tasks balance better; each builds a simulator).
    progress : callable, optional
        Called with the number of runs finished, as chunks complete.
    address : str, optional
        Ray only: the cluster to connect to (default ``RAY_ADDRESS``; neither: a local instance).

    Returns
    -------
    list of LandingRun
        In scenario order.

    Raises
    ------
    InvalidInputError
        For a bad count, backend or job number, or a missing Ray installation.
    """
    if isinstance(n_runs, bool) or int(n_runs) != n_runs or n_runs < 1:
        raise InvalidInputError(f"n_runs must be a positive integer, got {n_runs!r}")
    if backend not in BACKENDS:
        raise InvalidInputError(f"backend must be one of {', '.join(BACKENDS)}; got {backend!r}")
    if n_jobs is not None and (isinstance(n_jobs, bool) or int(n_jobs) != n_jobs or n_jobs < 1):
        raise InvalidInputError(f"n_jobs must be a positive integer, got {n_jobs!r}")
    jobs = 1 if backend == "sequential" else (n_jobs or default_jobs())
    args = (contract, int(seed), sim_config, scenario, landing)
    chunks = _chunks(int(n_runs), max(1, jobs * chunks_per_job))
    results: list[LandingRun] = []

    def consume(parts: Iterator[list[LandingRun]]) -> None:
        for part in parts:
            results.extend(part)
            if progress is not None:
                progress(len(part))

    if backend == "sequential":
        consume(_fly_chunk(c, *args) for c in chunks)
    else:
        if backend == "ray":
            _ray_backend(address)
        # joblib's Ray backend cannot stream results: progress then arrives at the end
        return_as = "list" if backend == "ray" else "generator_unordered"
        with joblib.parallel_backend(backend, n_jobs=jobs):
            parallel = joblib.Parallel(return_as=return_as)
            consume(iter(parallel(joblib.delayed(_fly_chunk)(c, *args) for c in chunks)))
    results.sort(key=lambda r: r.scenario.index)
    return results


@dataclass(frozen=True, kw_only=True)
class CampaignSummary:
    """Outcome counts of a set of landing runs, with exact binomial bounds.

    (Not :class:`~case_studies.quad_landing.sim.flight.LandingResult`, which is one motor
    cut of the simulator.)

    Attributes
    ----------
    runs, safe, unsafe, aborted : int
        Counts (``safe + unsafe + aborted == runs``).
    confidence : float
        Confidence ``1 - delta`` of every interval and bound.
    safe_rate, unsafe_rate, aborted_rate : float or None
        The rates (None for no runs, as are the fields below).
    unsafe_interval, safe_interval : (float, float) or None
        Two-sided Clopper--Pearson intervals.
    unsafe_upper, unsafe_lower, safe_lower : float or None
        One-sided Clopper--Pearson bounds.
    mean_queries : float or None
        Mean number of Measuring steps per run; ``max_queries`` the largest.
    wall_time_per_run : float or None
        Mean real seconds per run.
    reasons : tuple of str or None
        Why the aborted runs aborted (distinct, sorted).
    unsafe_into_pad : int
        How many of the unsafe runs drove the vehicle into the pad (a pad perceived below its
        surface; ``state_machine.into_pad``) rather than cutting the motors outside ``G``.
    """

    runs: int
    safe: int
    unsafe: int
    aborted: int
    confidence: float
    safe_rate: float | None = None
    unsafe_rate: float | None = None
    aborted_rate: float | None = None
    unsafe_interval: tuple[float, float] | None = None
    unsafe_upper: float | None = None
    unsafe_lower: float | None = None
    safe_interval: tuple[float, float] | None = None
    safe_lower: float | None = None
    mean_queries: float | None = None
    max_queries: int | None = None
    wall_time_per_run: float | None = None
    reasons: tuple[str, ...] | None = None
    unsafe_into_pad: int = 0

    def __post_init__(self) -> None:
        if (
            self.safe + self.unsafe + self.aborted != self.runs
            or min(self.safe, self.unsafe, self.aborted) < 0
            or not 0 <= self.unsafe_into_pad <= self.unsafe
        ):
            raise InvalidInputError(
                "safe + unsafe + aborted must equal runs (and unsafe_into_pad lie in [0, unsafe]), got "
                f"{self.safe} + {self.unsafe} + {self.aborted} vs {self.runs}, "
                f"{self.unsafe_into_pad} into the pad"
            )

    def to_dict(self) -> dict[str, Any]:
        """Plain data for ``summary.json``; the rates and bounds only when there are runs."""
        return {f.name: v for f in dataclasses.fields(self) if (v := getattr(self, f.name)) is not None}


def summarize(runs: Sequence[LandingRun], delta: float = 0.05) -> CampaignSummary:
    """Counts and exact binomial intervals of a set of runs (:class:`CampaignSummary`).

    Examples
    --------
    >>> summarize([]).runs, summarize([]).unsafe_rate is None
    (0, True)
    """
    n = len(runs)
    counts = {o: sum(1 for r in runs if r.outcome is o) for o in Outcome}
    s, u, a = counts[Outcome.SAFE], counts[Outcome.UNSAFE], counts[Outcome.ABORTED]
    if not n:
        return CampaignSummary(runs=0, safe=0, unsafe=0, aborted=0, confidence=1 - delta)
    return CampaignSummary(
        runs=n,
        safe=s,
        unsafe=u,
        aborted=a,
        confidence=1 - delta,
        safe_rate=s / n,
        unsafe_rate=u / n,
        aborted_rate=a / n,
        unsafe_interval=clopper_pearson_interval(u, n, delta),
        unsafe_upper=clopper_pearson_upper(u, n, delta),
        unsafe_lower=clopper_pearson_lower(u, n, delta),
        safe_interval=clopper_pearson_interval(s, n, delta),
        safe_lower=clopper_pearson_lower(s, n, delta),
        mean_queries=float(np.mean([r.n_queries for r in runs])),
        max_queries=int(max(r.n_queries for r in runs)),
        wall_time_per_run=float(np.mean([r.wall_time for r in runs])),
        reasons=tuple(sorted({r.reason for r in runs if r.outcome is Outcome.ABORTED})),
        unsafe_into_pad=sum(1 for r in runs if r.hit_pad),
    )
