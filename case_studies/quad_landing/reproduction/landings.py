"""The landing steps of a reproduction: campaigns of both contracts, the certified bound beside them.

:func:`fly_campaigns` flies the paper-style and Monte Carlo runs of the learned IPC and of the
trivial baseline at one buffer size (:class:`Flights`), :func:`judge_landing` puts the IPC's
certified bound, the closed loop's own violations and the coverage check beside them
(:class:`~.experiments.LandingExperiment`), and :func:`paper_contracts` /
:func:`contract_summary` do the same for each contract of the comparison (:mod:`.contracts`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from case_studies.quad_landing.landing.contracts import Contract, LearnedContract, TrivialContract
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.landing.state_machine import decision_target
from case_studies.quad_landing.reproduction.campaign import run_campaign, summarize
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.contracts import (
    CONTRACTS,
    ContractSummary,
    contract_claims,
    hover_half_widths,
)
from case_studies.quad_landing.reproduction.coverage import CoverageCheck, coverage_check
from case_studies.quad_landing.reproduction.experiments import ContractResults, LandingExperiment
from case_studies.quad_landing.reproduction.learn import calibration_summary, certified_epsilon
from case_studies.quad_landing.reproduction.paper_ipc import cached_paper_ipc
from case_studies.quad_landing.reproduction.run import REPORT_DELTA, SEEDS, Run, certify_ipc
from case_studies.quad_landing.reproduction.table1 import Table1, table1
from ipcverify.contract import IPCModel
from ipcverify.data import PerceptionDataset

__all__ = [
    "Flights",
    "fly_campaign",
    "fly_campaigns",
    "judge_landing",
    "fly_contract",
    "contract_summary",
    "paper_contracts",
]


@dataclass(frozen=True)
class Flights:
    """The landing runs at one buffer size: paper-style and Monte Carlo, both contracts."""

    buffer_size: int
    paper_ipc: tuple[LandingRun, ...]
    paper_baseline: tuple[LandingRun, ...]
    mc_ipc: tuple[LandingRun, ...]
    mc_baseline: tuple[LandingRun, ...]


def fly_campaign(
    run: Run, name: str, contract: Contract, n: int, seed: int, buffer_size: int
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


def fly_campaigns(run: Run, model: IPCModel, k: int, mc_runs: int) -> Flights:
    """Step 4: paper-style and Monte Carlo runs of both contracts at buffer size ``k``."""
    sizes, ipc, base = run.cfg.sizes, LearnedContract(model), TrivialContract()
    at = f" (buffer {k})"
    return Flights(
        buffer_size=k,
        paper_ipc=fly_campaign(run, "paper runs: IPC" + at, ipc, sizes.paper_runs, SEEDS["paper"], k),
        paper_baseline=fly_campaign(
            run, "paper runs: baseline" + at, base, sizes.paper_runs, SEEDS["paper"], k
        ),
        mc_ipc=fly_campaign(run, "Monte Carlo: IPC" + at, ipc, mc_runs, SEEDS["monte_carlo"], k),
        mc_baseline=fly_campaign(run, "Monte Carlo: baseline" + at, base, mc_runs, SEEDS["monte_carlo"], k),
    )


def judge_landing(
    run: Run, model: IPCModel, data: dict[str, PerceptionDataset], flights: Flights
) -> tuple[LandingExperiment, CoverageCheck]:
    """Step 5: both contracts' landings with the certified bound beside the IPC's.

    Returns the landing experiment and its coverage check (whose distances the coverage
    figure draws).
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
        coverage=coverage,
    )
    return landing, coverage


def fly_contract(
    run: Run, contract: Contract, k: int
) -> tuple[tuple[LandingRun, ...], tuple[LandingRun, ...]]:
    """The paper-style and Monte Carlo runs of one contract at buffer size ``k``."""
    sizes, at = run.cfg.sizes, f" (buffer {k})"
    paper = fly_campaign(
        run, f"paper runs: {contract.name}" + at, contract, sizes.paper_runs, SEEDS["paper"], k
    )
    mc = fly_campaign(
        run, f"Monte Carlo: {contract.name}" + at, contract, sizes.mc_runs, SEEDS["monte_carlo"], k
    )
    return paper, mc


def contract_summary(
    run: Run,
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


def paper_contracts(run: Run, data: dict[str, PerceptionDataset]) -> dict[str, ContractSummary]:
    """The paper's IPC trained the paper's way at buffer size 1, raw and calibrated (:mod:`.paper_ipc`)."""
    params, sizes, k = run.cfg.paper, run.cfg.sizes, run.landing_buffer
    with run.stages.stage("train + calibrate the paper's IPC", 1):
        models, _ = cached_paper_ipc(run.out_dir / "models", data["train_k1"], data["calibration_k1"], params)
    with run.stages.stage("certify the paper's IPC", 1):
        certificate = certify_ipc(
            models.calibrated, data["test_k1"], run.out_dir / "certificates" / "paper_calibrated"
        )
    pilots = {b: data[f"pilot_k{b}"] for b in sizes.buffers}
    selection = models.raw.metadata.get("selection")
    raw_flown = None
    if params.fly_uncalibrated:
        raw_flown = fly_contract(run, LearnedContract(models.raw, "paper_raw", uncalibrated=True), k)
    why = (
        None if params.fly_uncalibrated else "not flown: no guarantee (reproduce --fly-uncalibrated flies it)"
    )
    cal_flown = fly_contract(run, LearnedContract(models.calibrated, "paper_calibrated"), k)
    extras: dict[str, dict[str, Any]] = {
        "paper_raw": {"not_flown": why},
        "paper_calibrated": {"certificate": certificate},
    }
    return {
        name: contract_summary(
            run, name, model, table1(model, pilots, REPORT_DELTA), flown, selection=selection, **extras[name]
        )  # fmt: skip
        for name, model, flown in (
            ("paper_raw", models.raw, raw_flown),
            ("paper_calibrated", models.calibrated, cal_flown),
        )
    }
