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

The claims the issue asks for are evaluated in ``summary["claims"]`` with the statistics
that support them (or do not).
"""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import joblib
import torch
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from case_studies.quad_landing.data.datasets import as_dataset, cached_mixed, is_cached
from case_studies.quad_landing.landing.contracts import LearnedContract, TrivialContract
from case_studies.quad_landing.landing.runs import LandingRun
from case_studies.quad_landing.reproduction.campaign import default_jobs, run_campaign, summarize
from case_studies.quad_landing.reproduction.certified import (
    certified_bound,
    closed_loop_violations,
    coverage_check,
    unsafe_vs_certified,
)
from case_studies.quad_landing.reproduction.config import ReproduceConfig, load_reproduce_config
from case_studies.quad_landing.reproduction.figures import (
    figure_png,
    plot_campaign,
    plot_coverage,
    plot_table1,
    plot_topview,
    plot_trajectories,
)
from case_studies.quad_landing.reproduction.learn import cached_ipc, calibration_summary
from case_studies.quad_landing.reproduction.report_page import render_report
from case_studies.quad_landing.reproduction.table1 import PAPER_TABLE1, rates_rising, table1
from case_studies.quad_landing.sim.config import SimConfig, load_config
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.files import atomic_write, json_data, write_json
from ipcverify.model import IPCModel

__all__ = ["SEEDS", "PAPER_LANDING", "ReproduceResult", "reproduce", "evaluate_claims", "table1_text"]

#: Seeds of the datasets and campaigns (different seeds: disjoint paths, flights, pads).
SEEDS = {"train": 0, "calibration": 1, "test": 2, "paper": 10, "monte_carlo": 11, "buffer1": 12}
#: The paper's landing experiment: 10 pads; the IPC landed safely in all, the baseline failed 9.
PAPER_LANDING = {"runs": 10, "ipc_safe": 10, "baseline_unsafe": 9}
#: Confidence parameter of the reported intervals (two-sided 95 %).
REPORT_DELTA = 0.05
SUMMARY_VERSION = 1


@dataclasses.dataclass(frozen=True)
class ReproduceResult:
    """What :func:`reproduce` wrote: the summary and the paths of the report and summary files."""

    summary: dict[str, Any]
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


def _machine() -> dict[str, Any]:
    return {
        "cpu_count": os.cpu_count(),
        "cores_available": default_jobs(),
        "platform": platform.platform(),
        "python": platform.python_version(),
        "torch": torch.__version__,
    }


def _collect_one(path: Path, n: int, k: int, seed: int, approach: Any, sim: SimConfig) -> int:
    """Collect one dataset into the cache (a joblib task; OpenCV single-threaded per process)."""
    import cv2

    cv2.setNumThreads(1)
    cached_mixed(path, n, buffer_size=k, seed=seed, approach=approach, config=sim)
    return n


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


def _runs_table(runs: list[LandingRun]) -> list[dict[str, Any]]:
    return [
        {
            "index": r.scenario.index,
            "outcome": r.outcome.value,
            "n_queries": r.n_queries,
            "offset": None if r.offset is None else r.offset.tolist(),
            "reason": r.reason,
        }
        for r in runs
    ]


def _side(mc: list[LandingRun], paper: list[LandingRun]) -> dict[str, Any]:
    out = summarize(mc, REPORT_DELTA)
    out["paper_runs"] = summarize(paper, REPORT_DELTA)
    out["paper_runs"]["runs_detail"] = [r.to_dict(trajectory=True) for r in paper]
    out["runs_detail"] = _runs_table(mc)
    return out


def evaluate_claims(summary: dict[str, Any]) -> dict[str, Any]:
    """The issue's acceptance claims, each with ``holds`` (the point statement) and ``supported``
    (what the sample sizes can establish at the report's confidence), and the numbers behind them.
    """
    claims: dict[str, Any] = {}
    t1 = summary["table1"]
    b1 = t1[1] if 1 in t1 else t1["1"]
    claims["table1_buffer1_at_most_1pct"] = {
        "holds": b1["rate"] <= 0.01,
        "supported": b1["upper"] <= 0.01,
        "detail": f"rate {b1['rate']:.4%}, one-sided CP upper bound {b1['upper']:.4%} (n = {b1['n']})",
    }
    rising = summary["table1_rising"]
    claims["table1_rates_rising"] = {
        "holds": rising["strict"],
        "supported": rising["separated"],
        "detail": "point rates strictly increasing; 'supported' = simultaneous CP intervals do not overlap",
    }
    land = summary["landing"]
    ipc, base = land["ipc"], land["baseline"]
    n = ipc["runs"]
    lo_safe = ipc["safe_lower"]
    claims["ipc_safe_99pct_monte_carlo"] = {
        "holds": ipc["safe"] >= 0.99 * n,
        "supported": lo_safe >= 0.99,
        "detail": (
            f"{ipc['safe']}/{n} safe, {ipc['unsafe']} unsafe, {ipc['aborted']} aborted; one-sided 95 % "
            f"lower bound of the safe rate {lo_safe:.4f}"
            + (
                ""
                if lo_safe >= 0.99
                else f" ({n} runs cannot establish >= 99 % unless (nearly) all are safe)"
            )
        ),
    }
    pr = ipc["paper_runs"]
    claims["ipc_safe_all_paper_runs"] = {
        "holds": pr["safe"] == pr["runs"],
        "supported": pr["safe"] == pr["runs"],
        "detail": f"{pr['safe']}/{pr['runs']} safe ({pr['unsafe']} unsafe, {pr['aborted']} aborted)",
    }
    claims["baseline_unsafe_in_most_runs"] = {
        "holds": base["unsafe"] > 0.5 * base["runs"],
        "supported": base["unsafe_lower"] > 0.5,
        "detail": (
            f"{base['unsafe']}/{base['runs']} unsafe, one-sided 95 % lower bound {base['unsafe_lower']:.3f}, "
            f"two-sided interval [{base['unsafe_interval'][0]:.3f}, "
            f"{base['unsafe_interval'][1]:.3f}]; paper runs: {base['paper_runs']['unsafe']}/"
            f"{base['paper_runs']['runs']} unsafe (paper: 9/10)"
        ),
    }
    ev = ipc["empirical_vs_certified"]
    claims["certified_bound_at_least_empirical"] = {
        "holds": ev.get("bound_at_least_rate", False),
        "supported": ev.get("consistent", False),
        "detail": (
            f"certified {ipc['certified_unsafe_bound']:.4g} (refined {ev['certified_refined']:.4g}) "
            "vs empirical "
            f"{ev.get('unsafe_rate', float('nan')):.4g} ({ev['unsafe']}/{ev['runs']}); 'supported' = "
            "the CP lower "
            "bound of the unsafe rate does not exceed the refined bound"
        ),
    }
    return claims


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
    """
    t_start = time.perf_counter()
    cfg = config or load_reproduce_config(quick=quick)
    sim = sim_config or load_config()
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise InvalidInputError(f"--out {out_dir} exists and is not a directory; choose a directory")
    for sub in ("data", "models", "certificates", "figures"):
        (out_dir / sub).mkdir(parents=True, exist_ok=True)
    sizes, ipc_p, land = cfg.sizes, cfg.ipc, cfg.landing
    K = land.buffer_size
    stages = _Stages(progress, console)

    specs = [(f"test_k{b}", sizes.n_test, b, SEEDS["test"]) for b in sorted({*sizes.buffers, K})]
    for k in sorted({1, K}):
        specs += [
            (f"train_k{k}", sizes.n_train, k, SEEDS["train"]),
            (f"calibration_k{k}", sizes.n_calibration, k, SEEDS["calibration"]),
        ]
    path = {name: out_dir / "data" / f"{name}.parquet" for name, *_ in specs}
    jobs = 1 if backend == "sequential" else (n_jobs or default_jobs())

    def data(name: str) -> PerceptionDataset:
        n, k, seed = next((n, k, seed) for nm, n, k, seed in specs if nm == name)
        df, _ = cached_mixed(path[name], n, buffer_size=k, seed=seed, approach=cfg.approach, config=sim)
        return as_dataset(df, source=f"{name}.parquet")

    with stages.progress:
        todo = [
            sp
            for sp in specs
            if not is_cached(
                path[sp[0]], sp[1], buffer_size=sp[2], seed=sp[3], approach=cfg.approach, config=sim
            )
        ]
        todo.sort(key=lambda sp: -sp[1])  # largest first: better balance across workers
        with stages.stage(f"collect {len(todo)} datasets ({jobs} jobs)", sum(sp[1] for sp in todo)) as bar:
            tasks = (
                joblib.delayed(_collect_one)(path[name], n, k, seed, cfg.approach, sim)
                for name, n, k, seed in todo
            )
            parallel = joblib.Parallel(n_jobs=min(jobs, max(1, len(todo))), return_as="generator_unordered")
            for done in parallel(tasks):
                bar(done)
        tests = {b: data(f"test_k{b}") for b in sorted({*sizes.buffers, K})}
        models: dict[int, IPCModel] = {}
        certificates: dict[int, dict[str, Any]] = {}
        calibration_sets: dict[int, PerceptionDataset] = {}
        for k in sorted({1, K}):
            train, cal = data(f"train_k{k}"), data(f"calibration_k{k}")
            with stages.stage(f"train + calibrate IPC k={k}", 1):
                models[k], _ = cached_ipc(out_dir / "models" / f"ipc_k{k}.pt", train, cal, ipc_p)
            with stages.stage(f"certify IPC k={k}", 1):
                certificates[k] = _certify(models[k], tests[k], out_dir / "certificates" / f"ipc_k{k}")
            calibration_sets[k] = cal
        rows = table1(models[1], {b: tests[b] for b in sizes.buffers}, REPORT_DELTA)

        def campaign(name: str, contract: Any, n: int, seed: int, buffer_size: int) -> list[LandingRun]:
            lp = dataclasses.replace(land, buffer_size=buffer_size)
            with stages.stage(name, n) as bar:
                return run_campaign(
                    contract,
                    n,
                    seed=seed,
                    sim_config=sim,
                    scenario=cfg.scenario,
                    landing=lp,
                    n_jobs=n_jobs,
                    backend=backend,
                    progress=bar,
                )

        ipc_c, base_c = LearnedContract(models[K]), TrivialContract()
        paper_ipc = campaign("paper runs: IPC", ipc_c, sizes.paper_runs, SEEDS["paper"], K)
        paper_base = campaign("paper runs: baseline", base_c, sizes.paper_runs, SEEDS["paper"], K)
        mc_ipc = campaign("Monte Carlo: IPC", ipc_c, sizes.mc_runs, SEEDS["monte_carlo"], K)
        mc_base = campaign("Monte Carlo: baseline", base_c, sizes.mc_runs, SEEDS["monte_carlo"], K)
        b1: dict[str, Any] | None = None
        if sizes.buffer1_runs and K != 1:
            b1_ipc = campaign(
                "buffer 1: IPC", LearnedContract(models[1]), sizes.buffer1_runs, SEEDS["buffer1"], 1
            )
            b1_base = campaign("buffer 1: baseline", base_c, sizes.buffer1_runs, SEEDS["buffer1"], 1)
            b1 = {
                "buffer_size": 1,
                "ipc": summarize(b1_ipc, REPORT_DELTA),
                "baseline": summarize(b1_base, REPORT_DELTA),
            }

        with stages.stage("certified bound and coverage", 1):
            cal_info = calibration_summary(models[K])
            eps = cal_info["certified_epsilon"]
            bound = certified_bound(
                eps,
                ipc_p.delta,
                max_queries=land.max_measurements,
                queries_per_run=[sum(q.detected for q in r.queries) for r in mc_ipc],
            )
            coverage = coverage_check(
                models[K],
                calibration_sets[K],
                tests[K],
                [*mc_ipc, *paper_ipc],
                quantile=ipc_p.coverage_quantile,
                delta=REPORT_DELTA,
            )
            loop = closed_loop_violations(mc_ipc, eps, REPORT_DELTA)

        ipc_side = _side(mc_ipc, paper_ipc)
        ipc_side["certified_unsafe_bound"] = bound["union_bound"]
        ipc_side["certified"] = bound
        ipc_side["empirical_vs_certified"] = unsafe_vs_certified(mc_ipc, bound, REPORT_DELTA)
        cov_public = {k: v for k, v in coverage.items() if k != "distances"}
        summary: dict[str, Any] = {
            "format": "quad-landing-reproduction",
            "version": SUMMARY_VERSION,
            "quick": cfg.quick,
            "settings": cfg.as_dict(),
            "seeds": SEEDS,
            "paper": {"table1": PAPER_TABLE1, "landing": PAPER_LANDING},
            "ipc": {
                f"k{k}": {
                    "buffer_size": k,
                    "calibration": calibration_summary(models[k]),
                    "certificate": certificates[k],
                    "n_parameters": models[k].n_parameters,
                }
                for k in models
            },
            "table1": rows,
            "table1_rising": rates_rising(rows),
            "landing": {
                "buffer_size": K,
                "tracking_tolerance": land.tracking_tolerance,
                "max_measurements": land.max_measurements,
                "ipc": ipc_side,
                "baseline": _side(mc_base, paper_base),
                "closed_loop": loop,
                "coverage": cov_public,
            },
            "landing_buffer1": b1,
            "machine": _machine(),
            "jobs": n_jobs or default_jobs(),
            "backend": backend,
        }
        summary["claims"] = evaluate_claims(summary)
        with stages.stage("figures and report", 1):
            figs = {
                "topview": figure_png(plot_topview(paper_ipc, paper_base)),
                "campaign": figure_png(plot_campaign(mc_ipc, mc_base)),
                "table1": figure_png(plot_table1(rows)),
                "trajectories": figure_png(plot_trajectories(paper_ipc, paper_base)),
                "coverage": figure_png(plot_coverage(coverage)),
            }
            for name, png in figs.items():
                atomic_write(out_dir / "figures" / f"{name}.png", lambda fh, b=png: fh.write(b))
    summary["stage_seconds"] = stages.seconds
    summary["runtime_seconds"] = round(time.perf_counter() - t_start, 1)
    summary = json_data(summary)
    summary_path, report_path = out_dir / "summary.json", out_dir / "report.html"
    write_json(summary_path, summary, indent=1)
    page = render_report(summary, figs)
    atomic_write(report_path, lambda fh: fh.write(page), "w")
    return ReproduceResult(summary, report_path, summary_path)


def table1_text(summary: dict[str, Any]) -> str:
    """Table I of a summary as a Markdown table beside the paper's row (for the README).

    Examples
    --------
    >>> s = {"table1": {"1": {"n": 10, "violations": 0, "rate": 0.0, "interval": [0.0, 0.3]}}}
    >>> print(table1_text(s).splitlines()[2])
    | this reproduction | 0.00 % (0/10; [0.00, 30.00] %) |
    """
    rows = summary["table1"]
    keys = sorted(rows, key=int)
    head = "| buffer size | " + " | ".join(str(k) for k in keys) + " |"
    sep = "|---|" + "---|" * len(keys)
    ours = (
        "| this reproduction | "
        + " | ".join(
            f"{100 * rows[k]['rate']:.2f} % ({rows[k]['violations']}/{rows[k]['n']}; "
            f"[{100 * rows[k]['interval'][0]:.2f}, {100 * rows[k]['interval'][1]:.2f}] %)"
            for k in keys
        )
        + " |"
    )
    paper = (
        "| paper | "
        + " | ".join(f"{100 * PAPER_TABLE1[int(k)]:.2f} %" if int(k) in PAPER_TABLE1 else "—" for k in keys)
        + " |"
    )
    lines = [head, sep, ours]
    if any(int(k) in PAPER_TABLE1 for k in keys):
        lines.append(paper)
    return "\n".join(lines)
