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

import os
import time
from dataclasses import dataclass
from pathlib import Path

import pandas as pd
from rich.console import Console

from case_studies.quad_landing.data.datasets import DatasetSpec
from case_studies.quad_landing.reproduction.claims import evaluate_claims
from case_studies.quad_landing.reproduction.collection import DatasetPlan, collect_plan, spec_path
from case_studies.quad_landing.reproduction.config import ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.contract_figures import plot_contracts
from case_studies.quad_landing.reproduction.experiments import PAPER_LANDING, ControlExperiment, IpcSummary
from case_studies.quad_landing.reproduction.figures import draw_figures, figure_png
from case_studies.quad_landing.reproduction.landings import (
    contract_summary,
    fly_campaigns,
    judge_landing,
    paper_contracts,
)
from case_studies.quad_landing.reproduction.learn import cached_ipc, calibration_summary, flight_level_check
from case_studies.quad_landing.reproduction.report_page import render_report
from case_studies.quad_landing.reproduction.results import ReproductionSummary
from case_studies.quad_landing.reproduction.run import (
    ABLATION_PREFIX,
    REPORT_DELTA,
    SEEDS,
    Run,
    Stages,
    certify_ipc,
    cpu_seconds,
    machine_info,
    start_run,
)
from case_studies.quad_landing.reproduction.table1 import table1
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
from ipcverify.data import PerceptionDataset
from ipcverify.data._files import atomic_write, json_data, write_json
from ipcverify.errors import InvalidInputError

__all__ = ["SEEDS", "PAPER_LANDING", "REPORT_DELTA", "ReproduceResult", "reproduce"]


@dataclass(frozen=True)
class ReproduceResult:
    """What :func:`reproduce` wrote: the summary and the paths of the report and summary files."""

    summary: ReproductionSummary
    report: Path
    summary_path: Path


def _plan(run: Run) -> DatasetPlan:
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


def _collect_datasets(run: Run) -> tuple[dict[str, PerceptionDataset], dict[str, pd.DataFrame]]:
    """Step 1: collect the datasets not yet cached (flights flown once per task), then load all."""
    plan = _plan(run)
    total = sum(s.n for s in plan.specs)
    with run.stages.stage(f"collect {len(plan.specs)} datasets ({run.jobs} jobs)", total) as bar:
        return collect_plan(plan, approach=run.cfg.approach, pilot=run.cfg.pilot, config=run.sim,
                            jobs=run.jobs, progress=bar)  # fmt: skip


def _learn_ipcs(
    run: Run, data: dict[str, PerceptionDataset]
) -> tuple[dict[int, IPCModel], dict[int, IpcSummary]]:
    """Step 2: train, calibrate (cached) and certify an IPC at each of :attr:`Run.ipc_buffers`."""
    models: dict[int, IPCModel] = {}
    summaries: dict[int, IpcSummary] = {}
    for k in run.ipc_buffers:
        train, cal = data[f"train_k{k}"], data[f"calibration_k{k}"]
        with run.stages.stage(f"train + calibrate IPC k={k}", 1):
            models[k], _ = cached_ipc(run.out_dir / "models" / f"ipc_k{k}.pt", train, cal, run.cfg.ipc)
        with run.stages.stage(f"certify IPC k={k}", 1):
            certificate = certify_ipc(
                models[k], data[f"test_k{k}"], run.out_dir / "certificates" / f"ipc_k{k}"
            )
            flights = flight_level_check(models[k], cal, run.cfg.ipc.epsilon)
        summaries[k] = IpcSummary(
            buffer_size=k,
            calibration=calibration_summary(models[k]),
            certificate=certificate,
            n_parameters=models[k].n_parameters,
            flight_level=flights,
        )
    return models, summaries


def _ablation_variants(run: Run) -> list[Variant]:
    """The ablation's configurations: ``[ablation] variants`` of them, or all if it is empty."""
    every = ablation_variants(run.sim)
    wanted = run.cfg.ablation.variants
    unknown = sorted(set(wanted) - {v.name for v in every})
    if unknown:
        known = ", ".join(v.name for v in every)
        raise InvalidInputError(f"ablation.variants names unknown configurations {unknown}; known: {known}")
    return [v for v in every if not wanted or v.name in wanted]


def _ablation(run: Run, data: dict[str, PerceptionDataset], frames: dict[str, pd.DataFrame]) -> VariantStudy:
    """Step 3b: Table I of every camera variant, each with its own buffer-1 IPC."""
    variants = _ablation_variants(run)
    with run.stages.stage(f"ablation: {len(variants)} IPCs + Table I", len(variants)):
        return variant_tables(
            variants, prefix=ABLATION_PREFIX, datasets=data, frames=frames, ipc=run.cfg.ipc,
            sizes=run.cfg.ablation, buffers=run.cfg.sizes.buffers, out_dir=run.out_dir, jobs=run.jobs,
            delta=REPORT_DELTA,
        )  # fmt: skip


def _write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda fh: fh.write(data))


def _write(run: Run, summary: ReproductionSummary, figures: dict[str, bytes]) -> ReproduceResult:
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
    cpu_start = cpu_seconds()
    cfg = config or load_reproduce_config(quick=quick)
    run = start_run(out, cfg, sim_config or load_config(), n_jobs, backend, Stages(progress, console))
    delta, sizes = REPORT_DELTA, cfg.sizes
    with run.stages.progress:
        data, frames = _collect_datasets(run)
        models, ipcs = _learn_ipcs(run, data)
        table = table1(models[1], {b: data[f"pilot_k{b}"] for b in sizes.buffers}, delta)
        ablation = _ablation(run, data, frames)
        k = run.landing_buffer
        flights = fly_campaigns(run, models[k], k, sizes.mc_runs)
        landing, coverage = judge_landing(run, models[k], data, flights)
        extra = None
        if run.extra_buffer is not None:
            e = run.extra_buffer
            extra_flights = fly_campaigns(run, models[e], e, sizes.extra_landing_runs)
            extra, _ = judge_landing(run, models[e], data, extra_flights)
        contracts = paper_contracts(run, data)
        contracts["default_calibrated"] = contract_summary(
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
        machine=machine_info(load_start),
        jobs=run.jobs,
        backend=run.backend,
        stage_seconds=dict(run.stages.seconds),
        runtime_seconds=round(time.perf_counter() - started, 1),
        cpu_seconds=round(cpu_seconds() - cpu_start, 1),
    )
    return _write(run, summary, figures)
