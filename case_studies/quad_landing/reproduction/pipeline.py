"""``reproduce``: the paper's application study end to end, with certified bounds.

:func:`reproduce` runs, with progress bars:

1. **Data** (cached in ``OUT/data``, collected in parallel processes, each flight flown once
   and measured with every camera that needs it, :mod:`.collection`): training, calibration
   and held-out test sets at buffer size 1 (and at the extra landing buffer size), the pilot
   test sets of Table I at every buffer size, and the same for every camera variant of the
   ablation (:mod:`.variants`).
2. **IPCs** (cached in ``OUT/models``): the ``[ipc]`` recipe trained and PAC-calibrated at buffer
   size 1 (:mod:`.learn`) and certified on its held-out test set
   (:func:`ipcverify.certification.certify`, written to ``OUT/certificates``); likewise at the extra
   landing buffer size.
3. **Table I** on the pilot test flights (:mod:`.table1`), and the **ablation**: Table I of every
   camera variant, each with its own buffer-1 IPC (:mod:`.variants`).
4. **Landing at buffer size 1** (the paper's setting): the paper-style runs (10 random pads) and
   the Monte Carlo campaign, each with the learned IPC and with the trivial baseline on the
   same scenarios (:mod:`.campaign`); the same at the extra buffer size if asked for.
5. **Certified vs empirical** (:mod:`.certified`): the bound on the unsafe-landing probability,
   the empirical rate with its interval, the closed loop's own violations and coverage.
6. ``OUT/summary.json`` and the self-contained ``OUT/report.html`` (:mod:`.report_page`),
   figures also as ``OUT/figures/*.png``.

The claims the issue asks for are evaluated (:mod:`.claims`) with the statistics that
support them (or do not). The results are frozen dataclasses (:mod:`.results`);
``summary.json`` is :meth:`.results.ReproductionSummary.to_dict`.
"""

from __future__ import annotations

import dataclasses
import os
import platform
import resource
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from case_studies.quad_landing.data.datasets import DatasetSpec
from case_studies.quad_landing.landing.contracts import Contract, LearnedContract, TrivialContract
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.landing.state_machine import decision_target
from case_studies.quad_landing.reproduction.campaign import default_jobs, run_campaign, summarize
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    coverage_check,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.claims import evaluate_claims
from case_studies.quad_landing.reproduction.collection import DatasetPlan, collect_plan, spec_path
from case_studies.quad_landing.reproduction.config import ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.contract_figures import plot_contracts
from case_studies.quad_landing.reproduction.contracts import (
    CONTRACTS,
    ContractSummary,
    contract_claims,
    hover_half_widths,
)
from case_studies.quad_landing.reproduction.experiments import (
    PAPER_LANDING,
    ContractResults,
    ControlExperiment,
    IpcSummary,
    LandingExperiment,
)
from case_studies.quad_landing.reproduction.figures import draw_figures, figure_png
from case_studies.quad_landing.reproduction.learn import (
    cached_ipc,
    calibration_summary,
    certified_epsilon,
    flight_level_check,
)
from case_studies.quad_landing.reproduction.paper_ipc import cached_paper_ipc
from case_studies.quad_landing.reproduction.report_page import render_report
from case_studies.quad_landing.reproduction.results import ReproductionSummary
from case_studies.quad_landing.reproduction.table1 import Table1, table1
from case_studies.quad_landing.reproduction.timing_stats import camera_timing_summary, table1_protocol
from case_studies.quad_landing.reproduction.variants import (
    Variant,
    VariantStudy,
    ablation_variants,
    plan_variants,
    variant_tables,
)
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset, atomic_write, json_data, write_json
from ipcverify.errors import InvalidInputError

__all__ = ["SEEDS", "PAPER_LANDING", "REPORT_DELTA", "ReproduceResult", "reproduce"]

#: Seeds of the datasets and campaigns (different seeds: disjoint paths, flights, pads).
SEEDS = {"train": 0, "calibration": 1, "test": 2, "pilot": 3, "paper": 10, "monte_carlo": 11}
#: Confidence parameter of the reported intervals (two-sided 95 %).
REPORT_DELTA = 0.05
#: Name prefix of the ablation's datasets and models.
ABLATION_PREFIX = "abl-"


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
            TextColumn("{task.description:<38}"),
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
    def jobs(self) -> int:
        """Worker processes for collection, ablation and campaigns."""
        return 1 if self.backend == "sequential" else (self.n_jobs or default_jobs())

    @property
    def landing_buffer(self) -> int:
        """The buffer size of the landing runs (``[landing] buffer_size``: the paper's 1)."""
        return self.cfg.landing.buffer_size

    @property
    def extra_buffer(self) -> int | None:
        """The extra landing experiment's buffer size, or None when it is skipped."""
        sizes = self.cfg.sizes
        if not sizes.extra_landing_runs or sizes.extra_landing_buffer == self.landing_buffer:
            return None
        return sizes.extra_landing_buffer

    @property
    def ipc_buffers(self) -> list[int]:
        """Buffer sizes an IPC is learned at: 1 (Table I), the landing's, the extra one's."""
        extra = {self.extra_buffer} if self.extra_buffer is not None else set()
        return sorted({1, self.landing_buffer} | extra)


@dataclass(frozen=True)
class _Flights:
    """The landing runs at one buffer size: paper-style and Monte Carlo, both contracts."""

    buffer_size: int
    paper_ipc: tuple[LandingRun, ...]
    paper_baseline: tuple[LandingRun, ...]
    mc_ipc: tuple[LandingRun, ...]
    mc_baseline: tuple[LandingRun, ...]


def _machine(load_start: tuple[float, float, float]) -> dict[str, Any]:
    """Where it ran, and how busy the machine was (other work slows every stage down)."""
    return {
        "cpu_count": os.cpu_count(),
        "cores_available": default_jobs(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "torch": torch.__version__,
        "load_average_start": list(load_start),
        "load_average_end": list(os.getloadavg()),
    }


def _cpu_seconds() -> float:
    """CPU time of this process and of its finished worker processes (the reusable pool is shut down)."""
    from joblib.externals.loky import get_reusable_executor

    get_reusable_executor().shutdown(wait=True)
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return round(own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime, 1)


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


def _plan(run: _Run) -> DatasetPlan:
    """Every dataset: the IPCs' training, calibration and test sets, Table I's pilot sets, the ablation's."""
    plan, sizes, out = DatasetPlan(), run.cfg.sizes, run.out_dir

    def add(kind: str, part: str, n: int, k: int) -> None:
        name = f"{part}_k{k}"
        plan.add(kind, SEEDS[part], DatasetSpec(name, run.sim, k, n, spec_path(out, name)))

    for k in run.ipc_buffers:
        add("mixed", "train", sizes.n_train, k)
        add("mixed", "calibration", sizes.n_calibration, k)
        add("mixed", "test", sizes.n_test, k)
    for b in sizes.buffers:
        add("pilot", "pilot", sizes.n_pilot, b)
    plan_variants(plan, _ablation_variants(run), prefix=ABLATION_PREFIX, sizes=run.cfg.ablation,
                  buffers=sizes.buffers, seeds=SEEDS, out_dir=out)  # fmt: skip
    return plan


def _collect_datasets(run: _Run) -> tuple[dict[str, PerceptionDataset], dict[str, pd.DataFrame]]:
    """Step 1: collect the datasets not yet cached (flights flown once per task), then load all."""
    plan = _plan(run)
    total = sum(s.n for s in plan.specs)
    with run.stages.stage(f"collect {len(plan.specs)} datasets ({run.jobs} jobs)", total) as bar:
        return collect_plan(plan, approach=run.cfg.approach, pilot=run.cfg.pilot, config=run.sim,
                            jobs=run.jobs, progress=bar)  # fmt: skip


def _certify(model: IPCModel, test: PerceptionDataset, out_dir: Path) -> dict[str, Any]:
    from ipcverify.certification import certify, write_certificate

    # the test samples come from a few dozen flights: also count violations per flight
    result = certify(model, test, group_column="flight")
    write_certificate(result, out_dir)
    cert = result.certificate
    return {
        "status": cert.status.name,
        "statement": cert.statement,
        "test": None if cert.test is None else cert.test.to_dict(),
        "group_test": None if cert.group_test is None else cert.group_test.to_dict(),
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
            flights = flight_level_check(models[k], cal, run.cfg.ipc.epsilon)
        summaries[k] = IpcSummary(
            buffer_size=k,
            calibration=calibration_summary(models[k]),
            certificate=certificate,
            n_parameters=models[k].n_parameters,
            flight_level=flights,
        )
    return models, summaries


def _ablation_variants(run: _Run) -> list[Variant]:
    """The ablation's configurations: ``[ablation] variants`` of them, or all if it is empty."""
    every = ablation_variants(run.sim)
    wanted = run.cfg.ablation.variants
    unknown = sorted(set(wanted) - {v.name for v in every})
    if unknown:
        known = ", ".join(v.name for v in every)
        raise InvalidInputError(f"ablation.variants names unknown configurations {unknown}; known: {known}")
    return [v for v in every if not wanted or v.name in wanted]


def _ablation(run: _Run, data: dict[str, PerceptionDataset], frames: dict[str, pd.DataFrame]) -> VariantStudy:
    """Step 3b: Table I of every camera variant, each with its own buffer-1 IPC."""
    variants = _ablation_variants(run)
    with run.stages.stage(f"ablation: {len(variants)} IPCs + Table I", len(variants)):
        return variant_tables(
            variants, prefix=ABLATION_PREFIX, datasets=data, frames=frames, ipc=run.cfg.ipc,
            sizes=run.cfg.ablation, buffers=run.cfg.sizes.buffers, out_dir=run.out_dir, jobs=run.jobs,
            delta=REPORT_DELTA,
        )  # fmt: skip


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


def _fly_campaigns(run: _Run, model: IPCModel, k: int, mc_runs: int) -> _Flights:
    """Step 4: paper-style and Monte Carlo runs of both contracts at buffer size ``k``."""
    sizes, ipc, base = run.cfg.sizes, LearnedContract(model), TrivialContract()
    at = f" (buffer {k})"
    return _Flights(
        buffer_size=k,
        paper_ipc=_campaign(run, "paper runs: IPC" + at, ipc, sizes.paper_runs, SEEDS["paper"], k),
        paper_baseline=_campaign(run, "paper runs: baseline" + at, base, sizes.paper_runs, SEEDS["paper"], k),
        mc_ipc=_campaign(run, "Monte Carlo: IPC" + at, ipc, mc_runs, SEEDS["monte_carlo"], k),
        mc_baseline=_campaign(run, "Monte Carlo: baseline" + at, base, mc_runs, SEEDS["monte_carlo"], k),
    )


def _judge_landing(
    run: _Run, model: IPCModel, data: dict[str, PerceptionDataset], flights: _Flights
) -> tuple[LandingExperiment, dict[str, Any]]:
    """Step 5: both contracts' landings with the certified bound beside the IPC's.

    Returns the landing experiment and the full coverage check (with the distances the
    coverage figure draws).
    """
    k, delta = flights.buffer_size, REPORT_DELTA
    with run.stages.stage(f"certified bound and coverage (buffer {k})", 1):
        eps = certified_epsilon(model)
        queries = [sum(q.detected for q in r.queries) for r in flights.mc_ipc]
        bound = certified_bound(eps, run.cfg.ipc.delta, max_queries=run.cfg.landing.max_measurements,
                                queries_per_run=queries)  # fmt: skip
        coverage = coverage_check(model, data[f"calibration_k{k}"], data[f"test_k{k}"],
                                  [*flights.mc_ipc, *flights.paper_ipc], delta=delta)  # fmt: skip
        loop = closed_loop_violations(flights.mc_ipc, eps, delta)
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
        buffer_size=k,
        tracking_tolerance=run.cfg.landing.tracking_tolerance,
        max_measurements=run.cfg.landing.max_measurements,
        ipc=ipc,
        baseline=baseline,
        closed_loop=loop,
        coverage={key: v for key, v in coverage.items() if key != "distances"},
    )
    return landing, coverage


def _flown(run: _Run, contract: Contract, k: int) -> tuple[tuple[LandingRun, ...], tuple[LandingRun, ...]]:
    """The paper-style and Monte Carlo runs of one contract at buffer size ``k``."""
    sizes, at = run.cfg.sizes, f" (buffer {k})"
    paper = _campaign(run, f"paper runs: {contract.name}" + at, contract, sizes.paper_runs, SEEDS["paper"], k)
    mc = _campaign(
        run, f"Monte Carlo: {contract.name}" + at, contract, sizes.mc_runs, SEEDS["monte_carlo"], k
    )
    return paper, mc


def _contract(
    run: _Run,
    name: str,
    model: IPCModel,
    table: Table1,
    flown: tuple[tuple[LandingRun, ...], tuple[LandingRun, ...]] | None,
    **extra: Any,
) -> ContractSummary:
    """One contract's summary: Table I, its landings, its hover sets, its certified bound and claims."""
    info, delta = CONTRACTS[name], REPORT_DELTA
    target = decision_target(run.cfg.landing.tracking_tolerance, run.cfg.landing.target)
    paper = mc = hover = bound = versus = None
    if flown is not None:
        paper_runs, mc_runs = flown
        paper, mc = summarize(paper_runs, delta), summarize(mc_runs, delta)
        hover = hover_half_widths([*paper_runs, *mc_runs], target)
        if info.calibrated:
            queries = [sum(q.detected for q in r.queries) for r in mc_runs]
            eps, cal_delta = certified_epsilon(model), model.require_calibration().summary().delta
            bound = certified_bound(eps, cal_delta, max_queries=run.cfg.landing.max_measurements,
                                    queries_per_run=queries)  # fmt: skip
            versus = unsafe_vs_certified(mc_runs, bound, delta)
    return ContractSummary(
        info=info, n_parameters=model.n_parameters, table1=table, monte_carlo=mc, paper=paper, hover=hover,
        certified=bound, empirical_vs_certified=versus, claims=contract_claims(table, mc, paper, versus),
        calibration=calibration_summary(model) if info.calibrated else None, **extra,
    )  # fmt: skip


def _paper_contracts(run: _Run, data: dict[str, PerceptionDataset]) -> dict[str, ContractSummary]:
    """The paper's IPC trained the paper's way at buffer size 1, raw and calibrated (:mod:`.paper_ipc`)."""
    params, sizes, k = run.cfg.paper, run.cfg.sizes, run.landing_buffer
    with run.stages.stage("train + calibrate the paper's IPC", 1):
        models, _ = cached_paper_ipc(run.out_dir / "models", data["train_k1"], data["calibration_k1"], params)
    with run.stages.stage("certify the paper's IPC", 1):
        certificate = _certify(
            models.calibrated, data["test_k1"], run.out_dir / "certificates" / "paper_calibrated"
        )
    pilots = {b: data[f"pilot_k{b}"] for b in sizes.buffers}
    selection = models.raw.metadata.get("selection")
    raw_flown = None
    if params.fly_uncalibrated:
        raw_flown = _flown(run, LearnedContract(models.raw, "paper_raw", uncalibrated=True), k)
    why = (
        None if params.fly_uncalibrated else "not flown: no guarantee (reproduce --fly-uncalibrated flies it)"
    )
    cal_flown = _flown(run, LearnedContract(models.calibrated, "paper_calibrated"), k)
    extras: dict[str, dict[str, Any]] = {
        "paper_raw": {"not_flown": why},
        "paper_calibrated": {"certificate": certificate},
    }
    return {
        name: _contract(
            run, name, model, table1(model, pilots, REPORT_DELTA), flown, selection=selection, **extras[name]
        )  # fmt: skip
        for name, model, flown in (
            ("paper_raw", models.raw, raw_flown),
            ("paper_calibrated", models.calibrated, cal_flown),
        )
    }


def _write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda fh: fh.write(data))


def _write(run: _Run, summary: ReproductionSummary, figures: dict[str, bytes]) -> ReproduceResult:
    """``OUT/summary.json`` (the library's JSON encoder), the figures and the report page."""
    for name, png in figures.items():
        _write_bytes(run.out_dir / "figures" / f"{name}.png", png)
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
        Parallel workers (default: all cores).
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
    started, load_start = time.perf_counter(), os.getloadavg()
    cpu_start = _cpu_seconds()
    cfg = config or load_reproduce_config(quick=quick)
    run = _start(out, cfg, sim_config or load_config(), n_jobs, backend, _Stages(progress, console))
    delta, sizes = REPORT_DELTA, cfg.sizes
    with run.stages.progress:
        data, frames = _collect_datasets(run)
        models, ipcs = _learn_ipcs(run, data)
        table = table1(models[1], {b: data[f"pilot_k{b}"] for b in sizes.buffers}, delta)
        ablation = _ablation(run, data, frames)
        k = run.landing_buffer
        flights = _fly_campaigns(run, models[k], k, sizes.mc_runs)
        landing, coverage = _judge_landing(run, models[k], data, flights)
        extra = None
        if run.extra_buffer is not None:
            e = run.extra_buffer
            extra_flights = _fly_campaigns(run, models[e], e, sizes.extra_landing_runs)
            extra, _ = _judge_landing(run, models[e], data, extra_flights)
        contracts = _paper_contracts(run, data)
        contracts["default_calibrated"] = _contract(
            run,
            "default_calibrated",
            models[k],
            table,
            (flights.paper_ipc, flights.mc_ipc),
            certificate=ipcs[1].certificate,
        )
        with run.stages.stage("figures and report", 1):
            figures = draw_figures(table, ablation, flights.paper_ipc, flights.paper_baseline, flights.mc_ipc,
                                   flights.mc_baseline, coverage, frames, sizes.buffers)  # fmt: skip
            figures["contracts"] = figure_png(plot_contracts(contracts, landing.baseline.monte_carlo))
    summary = ReproductionSummary(
        quick=cfg.quick,
        settings=cfg,
        seeds=SEEDS,
        ipcs=ipcs,
        table1=table,
        landing=landing,
        landing_buffer1=ControlExperiment(
            buffer_size=k, ipc=landing.ipc.monte_carlo, baseline=landing.baseline.monte_carlo
        )
        if k == 1
        else None,  # fmt: skip
        landing_buffer3=extra,
        ablation=ablation,
        camera_timing=camera_timing_summary(run.sim, frames, sizes.buffers),
        table1_protocol=table1_protocol(cfg, frames),
        claims=evaluate_claims(table, landing),
        contracts=contracts,
        machine=_machine(load_start),
        jobs=run.jobs,
        backend=run.backend,
        stage_seconds=dict(run.stages.seconds),
        runtime_seconds=round(time.perf_counter() - started, 1),
        cpu_seconds=round(_cpu_seconds() - cpu_start, 1),
    )
    return _write(run, summary, figures)
