"""``reproduce``: the paper's application study end to end, with certified bounds.

:func:`reproduce` runs, with progress bars:

1. **Data** (cached in ``OUT/data``, collected in parallel processes): training and
   calibration sets at buffer size 1 and at the landing buffer size, and test sets at every
   Table I buffer size on shared paths (:mod:`.datasets`: exploration paths plus approach
   flights).
2. **IPCs** (cached in ``OUT/models``): the paper's network trained at buffer size 1 (Table I)
   and at the landing buffer size, each PAC-calibrated on its own calibration set
   (:mod:`.learn`) and certified on its test set (:func:`ipcverify.certify.certify`,
   written to ``OUT/certificates``).
3. **Table I** (:mod:`.table1`).
4. **Landing**: the paper-style runs (10 random pads) and the Monte Carlo campaign, each with
   the learned IPC and with the trivial baseline on the same scenarios (:mod:`.campaign`),
   and the buffer-1 control experiment.
5. **Certified vs empirical** (:mod:`.certified`): the bound on the unsafe-landing probability,
   the empirical rate with its interval, the closed loop's own violations and coverage.
6. ``OUT/summary.json`` and the self-contained ``OUT/report.html`` (:mod:`.report_page`),
   figures also as ``OUT/figures/*.png``.

The claims the issue asks for are evaluated (:mod:`.claims`) with the statistics that
support them (or do not). The results are frozen dataclasses (:mod:`.results`);
``summary.json`` is :meth:`.results.ReproductionSummary.to_dict`.

:func:`reproduce` is a short pipeline; each step is a function of its own:
:func:`_collect_datasets`, :func:`_learn_ipcs`, :func:`.table1.table1`,
:func:`_fly_campaigns`, :func:`_judge_landing`, :func:`_draw_figures`, then
:func:`_summarize` and :func:`_write`.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import joblib
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from case_studies.quad_landing.data.approach import ApproachParams
from case_studies.quad_landing.data.datasets import as_dataset, cached_mixed, is_cached
from case_studies.quad_landing.landing.contracts import Contract, LearnedContract, TrivialContract
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.reproduction.campaign import default_jobs, run_campaign, summarize
from case_studies.quad_landing.reproduction.certified import (
    CertifiedBound,
    certified_bound,
    closed_loop_violations,
    coverage_check,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.claims import evaluate_claims
from case_studies.quad_landing.reproduction.config import ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.figures import (
    figure_png,
    plot_campaign,
    plot_coverage,
    plot_table1,
    plot_topview,
    plot_trajectories,
)
from case_studies.quad_landing.reproduction.learn import cached_ipc, calibration_summary, certified_epsilon
from case_studies.quad_landing.reproduction.report_page import render_report
from case_studies.quad_landing.reproduction.results import (
    PAPER_LANDING,
    ContractResults,
    ControlExperiment,
    IpcSummary,
    LandingExperiment,
    ReproductionSummary,
)
from case_studies.quad_landing.reproduction.table1 import Table1, table1
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.files import atomic_write, json_data, write_json
from ipcverify.model import IPCModel

__all__ = ["SEEDS", "PAPER_LANDING", "REPORT_DELTA", "ReproduceResult", "reproduce"]

#: Seeds of the datasets and campaigns (different seeds: disjoint paths, flights, pads).
SEEDS = {"train": 0, "calibration": 1, "test": 2, "paper": 10, "monte_carlo": 11, "buffer1": 12}
#: Confidence parameter of the reported intervals (two-sided 95 %).
REPORT_DELTA = 0.05


@dataclass(frozen=True)
class ReproduceResult:
    """What :func:`reproduce` wrote: the summary and the paths of the report and summary files."""

    summary: ReproductionSummary
    report: Path
    summary_path: Path


class _Stages:
    """Progress bars and timings of the pipeline's stages."""

    def __init__(self, show: bool, console: Console | None) -> None:
        self.progress = Progress(
            TextColumn("{task.description:<34}"),
            BarColumn(),
            MofNCompleteColumn(),
            TimeElapsedColumn(),
            console=console or Console(stderr=True),
            disable=not show,
        )
        self.seconds: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str, total: int) -> Iterator[Callable[[int], None]]:
        task = self.progress.add_task(name, total=total)
        t0 = time.perf_counter()
        try:
            yield lambda k: self.progress.advance(task, k)
        finally:
            self.progress.update(task, completed=total)
            self.seconds[name] = round(time.perf_counter() - t0, 2)


@dataclass(frozen=True)
class _Run:
    """What every step of one reproduction shares: settings, output directory, workers, stages."""

    cfg: ReproduceConfig
    sim: SimConfig
    out_dir: Path
    n_jobs: int | None
    backend: str
    stages: _Stages

    @property
    def landing_buffer(self) -> int:
        """The buffer size of the landing runs (``[landing] buffer_size``)."""
        return self.cfg.landing.buffer_size

    @property
    def ipc_buffers(self) -> list[int]:
        """Buffer sizes an IPC is learned at: 1 (Table I) and the landing's."""
        return sorted({1, self.landing_buffer})

    @property
    def test_buffers(self) -> list[int]:
        """Buffer sizes with a test set: Table I's and the landing's."""
        return sorted({*self.cfg.sizes.buffers, self.landing_buffer})


@dataclass(frozen=True)
class _DatasetSpec:
    """One dataset of the reproduction: name, size, buffer size and seed."""

    name: str
    n: int
    buffer_size: int
    seed: int

    def path(self, out_dir: Path) -> Path:
        return out_dir / "data" / f"{self.name}.parquet"


@dataclass(frozen=True)
class _Flights:
    """The landing runs of every campaign (the buffer-1 ones None when skipped)."""

    paper_ipc: tuple[LandingRun, ...]
    paper_baseline: tuple[LandingRun, ...]
    mc_ipc: tuple[LandingRun, ...]
    mc_baseline: tuple[LandingRun, ...]
    buffer1_ipc: tuple[LandingRun, ...] | None
    buffer1_baseline: tuple[LandingRun, ...] | None


def _machine() -> dict[str, Any]:
    return {
        "cpu_count": os.cpu_count(),
        "cores_available": default_jobs(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "torch": torch.__version__,
    }


def _start(
    out: str | os.PathLike[str],
    cfg: ReproduceConfig,
    sim: SimConfig,
    n_jobs: int | None,
    backend: str,
    stages: _Stages,
) -> _Run:
    """Check and create the output directory (``data``, ``models``, ``certificates``, ``figures``)."""
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise InvalidInputError(f"--out {out_dir} exists and is not a directory; choose a directory")
    for sub in ("data", "models", "certificates", "figures"):
        (out_dir / sub).mkdir(parents=True, exist_ok=True)
    return _Run(cfg, sim, out_dir, n_jobs, backend, stages)


def _dataset_specs(run: _Run) -> list[_DatasetSpec]:
    """Test sets at every test buffer size; training and calibration sets at every IPC's."""
    sizes = run.cfg.sizes
    specs = [_DatasetSpec(f"test_k{b}", sizes.n_test, b, SEEDS["test"]) for b in run.test_buffers]
    for k in run.ipc_buffers:
        specs += [
            _DatasetSpec(f"train_k{k}", sizes.n_train, k, SEEDS["train"]),
            _DatasetSpec(f"calibration_k{k}", sizes.n_calibration, k, SEEDS["calibration"]),
        ]
    return specs


def _collect_one(path: Path, n: int, k: int, seed: int, approach: ApproachParams, sim: SimConfig) -> int:
    """Collect one dataset into the cache (a joblib task; OpenCV single-threaded per process)."""
    import cv2

    cv2.setNumThreads(1)
    cached_mixed(path, n, buffer_size=k, seed=seed, approach=approach, config=sim)
    return n


def _collect_datasets(run: _Run) -> dict[str, PerceptionDataset]:
    """Step 1: collect the datasets not yet cached (in parallel, largest first), then load all."""
    specs, approach, sim = _dataset_specs(run), run.cfg.approach, run.sim
    todo = [
        s
        for s in specs
        if not is_cached(
            s.path(run.out_dir), s.n, buffer_size=s.buffer_size, seed=s.seed, approach=approach, config=sim
        )
    ]
    todo.sort(key=lambda s: -s.n)  # largest first: better balance across workers
    jobs = 1 if run.backend == "sequential" else (run.n_jobs or default_jobs())
    with run.stages.stage(f"collect {len(todo)} datasets ({jobs} jobs)", sum(s.n for s in todo)) as bar:
        tasks = (
            joblib.delayed(_collect_one)(s.path(run.out_dir), s.n, s.buffer_size, s.seed, approach, sim)
            for s in todo
        )
        parallel = joblib.Parallel(n_jobs=min(jobs, max(1, len(todo))), return_as="generator_unordered")
        for done in parallel(tasks):
            bar(done)
    data = {}
    for s in specs:
        df, _ = cached_mixed(
            s.path(run.out_dir), s.n, buffer_size=s.buffer_size, seed=s.seed, approach=approach, config=sim
        )
        data[s.name] = as_dataset(df, source=f"{s.name}.parquet")
    return data


def _certify(model: IPCModel, test: PerceptionDataset, out_dir: Path) -> dict[str, Any]:
    from ipcverify.certify import certify, write_certificate

    result = certify(model, test)
    write_certificate(result, out_dir)
    cert = result.certificate
    return {
        "status": cert.status.name,
        "statement": cert.statement,
        "test": cert.test.to_dict(),
        "files": str(out_dir),
    }


def _learn_ipcs(
    run: _Run, data: dict[str, PerceptionDataset]
) -> tuple[dict[int, IPCModel], dict[int, IpcSummary]]:
    """Step 2: train, calibrate (cached) and certify an IPC at each of :attr:`_Run.ipc_buffers`."""
    models: dict[int, IPCModel] = {}
    summaries: dict[int, IpcSummary] = {}
    for k in run.ipc_buffers:
        train, cal = data[f"train_k{k}"], data[f"calibration_k{k}"]
        with run.stages.stage(f"train + calibrate IPC k={k}", 1):
            models[k], _ = cached_ipc(run.out_dir / "models" / f"ipc_k{k}.pt", train, cal, run.cfg.ipc)
        with run.stages.stage(f"certify IPC k={k}", 1):
            certificate = _certify(models[k], data[f"test_k{k}"], run.out_dir / "certificates" / f"ipc_k{k}")
        summaries[k] = IpcSummary(
            buffer_size=k,
            calibration=calibration_summary(models[k]),
            certificate=certificate,
            n_parameters=models[k].n_parameters,
        )
    return models, summaries


def _campaign(
    run: _Run, name: str, contract: Contract, n: int, seed: int, buffer_size: int
) -> tuple[LandingRun, ...]:
    """One campaign of ``n`` runs at ``buffer_size``, with a progress bar."""
    landing = dataclasses.replace(run.cfg.landing, buffer_size=buffer_size)
    with run.stages.stage(name, n) as bar:
        runs = run_campaign(
            contract,
            n,
            seed=seed,
            sim_config=run.sim,
            scenario=run.cfg.scenario,
            landing=landing,
            n_jobs=run.n_jobs,
            backend=run.backend,
            progress=bar,
        )
    return tuple(runs)


def _fly_campaigns(run: _Run, models: dict[int, IPCModel]) -> _Flights:
    """Step 4: paper-style and Monte Carlo runs of both contracts, and the buffer-1 control."""
    sizes, k = run.cfg.sizes, run.landing_buffer
    ipc, base = LearnedContract(models[k]), TrivialContract()
    paper_ipc = _campaign(run, "paper runs: IPC", ipc, sizes.paper_runs, SEEDS["paper"], k)
    paper_base = _campaign(run, "paper runs: baseline", base, sizes.paper_runs, SEEDS["paper"], k)
    mc_ipc = _campaign(run, "Monte Carlo: IPC", ipc, sizes.mc_runs, SEEDS["monte_carlo"], k)
    mc_base = _campaign(run, "Monte Carlo: baseline", base, sizes.mc_runs, SEEDS["monte_carlo"], k)
    b1_ipc = b1_base = None
    if sizes.buffer1_runs and k != 1:
        b1_ipc = _campaign(
            run, "buffer 1: IPC", LearnedContract(models[1]), sizes.buffer1_runs, SEEDS["buffer1"], 1
        )
        b1_base = _campaign(run, "buffer 1: baseline", base, sizes.buffer1_runs, SEEDS["buffer1"], 1)
    return _Flights(paper_ipc, paper_base, mc_ipc, mc_base, b1_ipc, b1_base)


def _landing_checks(
    run: _Run, model: IPCModel, data: dict[str, PerceptionDataset], flights: _Flights
) -> tuple[CertifiedBound, dict[str, Any], dict[str, Any]]:
    """The certified bound on unsafe landings, the coverage check and the closed loop's violations."""
    k, delta = run.landing_buffer, REPORT_DELTA
    with run.stages.stage("certified bound and coverage", 1):
        eps = certified_epsilon(model)
        queries = [sum(q.detected for q in r.queries) for r in flights.mc_ipc]
        max_queries = run.cfg.landing.max_measurements
        bound = certified_bound(eps, run.cfg.ipc.delta, max_queries=max_queries, queries_per_run=queries)
        coverage = coverage_check(
            model,
            data[f"calibration_k{k}"],
            data[f"test_k{k}"],
            [*flights.mc_ipc, *flights.paper_ipc],
            delta=delta,
        )
        loop = closed_loop_violations(flights.mc_ipc, eps, delta)
    return bound, coverage, loop


def _judge_landing(
    run: _Run, model: IPCModel, data: dict[str, PerceptionDataset], flights: _Flights
) -> tuple[LandingExperiment, dict[str, Any]]:
    """Step 5: both contracts' landings with the certified bound beside the IPC's.

    Returns the landing experiment and the full coverage check (with the distances the
    coverage figure draws).
    """
    bound, coverage, loop = _landing_checks(run, model, data, flights)
    delta = REPORT_DELTA
    ipc = ContractResults(
        monte_carlo=summarize(flights.mc_ipc, delta),
        runs=flights.mc_ipc,
        paper=summarize(flights.paper_ipc, delta),
        paper_runs=flights.paper_ipc,
        certified=bound,
        empirical_vs_certified=unsafe_vs_certified(flights.mc_ipc, bound, delta),
    )
    baseline = ContractResults(
        monte_carlo=summarize(flights.mc_baseline, delta),
        runs=flights.mc_baseline,
        paper=summarize(flights.paper_baseline, delta),
        paper_runs=flights.paper_baseline,
    )
    landing = LandingExperiment(
        buffer_size=run.landing_buffer,
        tracking_tolerance=run.cfg.landing.tracking_tolerance,
        max_measurements=run.cfg.landing.max_measurements,
        ipc=ipc,
        baseline=baseline,
        closed_loop=loop,
        coverage={key: v for key, v in coverage.items() if key != "distances"},
    )
    return landing, coverage


def _control(flights: _Flights) -> ControlExperiment | None:
    """The buffer-1 control experiment, if it was flown."""
    if flights.buffer1_ipc is None or flights.buffer1_baseline is None:
        return None
    return ControlExperiment(
        buffer_size=1,
        ipc=summarize(flights.buffer1_ipc, REPORT_DELTA),
        baseline=summarize(flights.buffer1_baseline, REPORT_DELTA),
    )


def _write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda fh: fh.write(data))


def _draw_figures(run: _Run, table: Table1, flights: _Flights, coverage: dict[str, Any]) -> dict[str, bytes]:
    """Step 6: the figures as PNG bytes, also written to ``OUT/figures``."""
    with run.stages.stage("figures and report", 1):
        figs = {
            "topview": figure_png(plot_topview(flights.paper_ipc, flights.paper_baseline)),
            "campaign": figure_png(plot_campaign(flights.mc_ipc, flights.mc_baseline)),
            "table1": figure_png(plot_table1(table)),
            "trajectories": figure_png(plot_trajectories(flights.paper_ipc, flights.paper_baseline)),
            "coverage": figure_png(plot_coverage(coverage)),
        }
        for name, png in figs.items():
            _write_bytes(run.out_dir / "figures" / f"{name}.png", png)
    return figs


def _summarize(
    run: _Run,
    ipcs: dict[int, IpcSummary],
    table: Table1,
    landing: LandingExperiment,
    control: ControlExperiment | None,
    started: float,
) -> ReproductionSummary:
    """Everything found, with the claims and the timings (:class:`.results.ReproductionSummary`)."""
    return ReproductionSummary(
        quick=run.cfg.quick,
        settings=run.cfg,
        seeds=SEEDS,
        ipcs=ipcs,
        table1=table,
        landing=landing,
        landing_buffer1=control,
        claims=evaluate_claims(table, landing),
        machine=_machine(),
        jobs=run.n_jobs or default_jobs(),
        backend=run.backend,
        stage_seconds=dict(run.stages.seconds),
        runtime_seconds=round(time.perf_counter() - started, 1),
    )


def _write(run: _Run, summary: ReproductionSummary, figures: dict[str, bytes]) -> ReproduceResult:
    """``OUT/summary.json`` (the library's JSON encoder) and the report page rendered from it."""
    summary_path, report_path = run.out_dir / "summary.json", run.out_dir / "report.html"
    content = json_data(summary)
    write_json(summary_path, content, indent=1)
    page = render_report(content, figures)
    atomic_write(report_path, lambda fh: fh.write(page), "w")
    return ReproduceResult(summary, report_path, summary_path)


def reproduce(
    out: str | os.PathLike[str],
    *,
    quick: bool = False,
    config: ReproduceConfig | None = None,
    sim_config: SimConfig | None = None,
    n_jobs: int | None = None,
    backend: str = "loky",
    progress: bool = True,
    console: Console | None = None,
) -> ReproduceResult:
    """Run the whole reproduction and write ``OUT/report.html`` and ``OUT/summary.json``.

    Parameters
    ----------
    out : path-like
        Output directory (created); datasets and models are cached in it, so a rerun
        with the same settings skips collection and training.
    quick : bool
        Use the ``[quick]`` sizes of ``reproduce.toml`` (same pipeline, minutes less).
    config : ReproduceConfig, optional
        Settings (default: ``reproduce.toml``, with the quick overlay if ``quick``).
    sim_config : SimConfig, optional
        The simulator (default: ``defaults.toml``).
    n_jobs : int, optional
        Parallel workers for the landing campaigns (default: all cores).
    backend : {"loky", "sequential", "ray"}
        joblib backend of the campaigns (:mod:`.campaign`).
    progress : bool
        Show progress bars (on stderr).
    console : rich.console.Console, optional
        Where the progress bars go.

    Returns
    -------
    ReproduceResult
        The :class:`.results.ReproductionSummary` and the paths of the files written.
    """
    started = time.perf_counter()
    cfg = config or load_reproduce_config(quick=quick)
    run = _start(out, cfg, sim_config or load_config(), n_jobs, backend, _Stages(progress, console))
    with run.stages.progress:
        data = _collect_datasets(run)
        models, ipcs = _learn_ipcs(run, data)
        table = table1(models[1], {b: data[f"test_k{b}"] for b in cfg.sizes.buffers}, REPORT_DELTA)
        flights = _fly_campaigns(run, models)
        landing, coverage = _judge_landing(run, models[run.landing_buffer], data, flights)
        figures = _draw_figures(run, table, flights, coverage)
    summary = _summarize(run, ipcs, table, landing, _control(flights), started)
    return _write(run, summary, figures)
