"""The benchmark suite in one command: speed and tightness of ipcverify against its peers.

Run from the repository root (about 9 minutes on 2 shared cores; the first run also
flies the quad-landing data, about 1 minute, cached in ``benchmarks/.cache/``)::

    pip install -e ".[bench,onnx]"
    python -m benchmarks.run

It writes ``benchmarks/results.json`` (every number), ``benchmarks/results.md`` (the
tables), ``docs/img/bench_tightness.png`` and ``docs/img/bench_throughput.png``. ``--quick`` runs
everything on tiny sizes (a smoke test of the harness; its numbers mean nothing) and writes to ``--out``.

Sections: ``tightness`` (:mod:`benchmarks.bench_tightness`: every method against MAPIE and,
on the known-oracle data, the oracle; with the volume diagnosis), ``shift``
(:mod:`benchmarks.bench_shift`: violation rates of the old and new default under covariate
shift and on held-out runs / time segments of the real log), ``latency``
(:mod:`benchmarks.bench_latency`), ``cost`` (:mod:`benchmarks.bench_cost`), ``startup``
(:mod:`benchmarks.bench_startup`: the command line's start-up against a bare Python) and ``targets``
(the issues' targets, computed from the numbers above, never typed in). About 9 minutes
on 2 shared cores.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import torch

from benchmarks.bench_cost import bench_cost
from benchmarks.bench_latency import BATCH_SIZES, Workload, bench_latency
from benchmarks.bench_shift import bench_shift
from benchmarks.bench_startup import bench_startup
from benchmarks.bench_tightness import bench_tightness
from benchmarks.common import blas_single_thread, machine_info, write_json
from benchmarks.datasets import CACHE, DATASETS, Splits, load_splits, quad_flights
from benchmarks.report import render_markdown, targets
from ipcverify.calibration import Global
from ipcverify.contract import calibrate
from ipcverify.errors import InvalidInputError
from ipcverify.guard import DomainSpec

__all__ = ["RunConfig", "latency_workloads", "run", "main"]

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True, kw_only=True)
class RunConfig:
    """Sizes and repeats of one benchmark run (defaults: the full run)."""

    n_train: int = 5000
    n_calibration: int = 5000
    n_test: int = 5000
    seeds: int = 3
    mapie_seeds: int = 2
    mapie_epochs: int = 60
    epsilon: float = 0.01
    delta: float = 0.001
    latency_rounds: int = 5
    latency_calls: int = 2000
    batch_sizes: tuple[int, ...] = BATCH_SIZES
    cost_repeats: int = 3
    sdp_count: int = 60
    shift_n: int = 5000
    shift_seeds: int = 2
    shift_real_log: bool = True
    startup_repeats: int = 9
    startup_epochs: int = 5

    def __post_init__(self) -> None:
        if min(self.n_train, self.n_calibration, self.n_test, self.seeds, self.mapie_seeds) < 1:
            raise InvalidInputError("sizes and repeats must be positive")

    @classmethod
    def quick(cls) -> RunConfig:
        """Tiny sizes for a smoke test of the harness."""
        return cls(
            n_train=400,
            n_calibration=800,
            n_test=200,
            seeds=1,
            mapie_seeds=1,
            mapie_epochs=1,
            epsilon=0.05,
            delta=0.05,
            latency_rounds=1,
            latency_calls=50,
            batch_sizes=(1, 100),
            cost_repeats=1,
            sdp_count=3,
            shift_n=300,
            shift_seeds=1,
            shift_real_log=False,
            startup_repeats=1,
            startup_epochs=1,
        )


def latency_workloads(models: dict[str, tuple[Any, Splits, float]], cfg: RunConfig) -> list[Workload]:
    """The latency benchmark's workloads: in-distribution first (the numbers of record), then out of domain.

    * ``quad_flights``: the quad IPC calibrated on 120 exploration flights sampled sparsely
      (:func:`benchmarks.datasets.quad_flights`, about 5,000 rows), its domain fitted by flight;
      queries: 80 more flights drawn exactly like them;
    * ``synthetic``: the synthetic IPC calibrated on its calibration split (row-level domain);
      queries: its test split, an independent draw of the same law;
    * ``quad_out_of_domain``: the quad IPC calibrated on the quad calibration split (12 flights,
      every 2nd frame; row-level domain); queries: the quad test split, 12 unseen flights, most of
      them outside the domain (the workload the benchmark used before).

    As a user gets them: :func:`~ipcverify.contract.calibrate` fits the domain of validity by
    default, so the decision of record runs its domain test.
    """
    eps, delta = cfg.epsilon, cfg.delta

    def on_splits(key: str, name: str, what: str) -> Workload:
        """Model ``key`` calibrated on its calibration split (row-level domain), queried on its test split."""
        ipc, splits, _ = models[key]
        calibrated = calibrate(ipc, splits.calibration, eps, delta, Global(mode="pac"), recalibrate=True)
        return Workload(name, calibrated, splits.test, what)

    out = []
    if "quad_landing" in models:
        ipc, splits, _ = models["quad_landing"]
        cal, test = quad_flights()
        out.append(
            Workload(
                "quad_flights",
                calibrate(
                    ipc,
                    cal,
                    eps,
                    delta,
                    Global(mode="pac"),
                    domain=DomainSpec(group_column="path"),
                    recalibrate=True,
                ),
                test,
                f"quad landing: calibrated on {len(cal)} rows of 120 exploration flights (every 20th frame), "
                f"domain fitted by flight; queries: {len(test)} rows of 80 held-out flights drawn like them",
            )
        )
    if "synthetic" in models:
        out.append(
            on_splits(
                "synthetic",
                "synthetic",
                "synthetic (hetlag): calibrated on its calibration split, row-level domain; queries: the "
                "test split (an independent draw of the same law)",
            )
        )
    if "quad_landing" in models:
        out.append(
            on_splits(
                "quad_landing",
                "quad_out_of_domain",
                "quad landing, out of domain: calibrated on the 12 flights of the calibration split (every "
                "2nd frame), row-level domain; queries: the 12 unseen flights of the test split",
            )
        )
    if not out:  # another dataset alone: its own test split
        name = next(iter(models))
        what = f"{name}: calibrated on its calibration split; queries: its test split"
        out.append(on_splits(name, name, what))
    return out


def run(
    cfg: RunConfig, out_dir: Path, figure: Path | None, datasets: tuple[str, ...] = DATASETS
) -> dict[str, Any]:
    """Run every section, write ``results.json`` and ``results.md`` in ``out_dir`` (and the figure)."""
    t_start = time.perf_counter()
    torch.set_num_threads(1)
    blas_single_thread()
    results: dict[str, Any] = {
        "command": "python -m benchmarks.run",
        "date_utc": datetime.now(UTC).isoformat(timespec="seconds"),
        "machine": machine_info(),
        "settings": {
            **{k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(cfg).items()},
            "mode": "pac",
            "torch_threads": 1,
            "blas_threads": "1 (threadpoolctl), except the path engine_arrays_blas_default_threads",
            "quad_cache": str(CACHE.relative_to(ROOT)) if CACHE.is_relative_to(ROOT) else str(CACHE),
        },
        "tightness": {},
        "cost": {},
    }
    models = {}
    for name in datasets:
        t0 = time.perf_counter()
        splits = load_splits(name, cfg.n_train, cfg.n_calibration, cfg.n_test)
        load_s = time.perf_counter() - t0
        tight, ipc = bench_tightness(
            splits,
            cfg.epsilon,
            cfg.delta,
            "pac",
            seeds=cfg.seeds,
            mapie_epochs=cfg.mapie_epochs,
            mapie_seeds=cfg.mapie_seeds,
        )
        results["tightness"][name] = tight
        models[name] = (ipc, splits, load_s)
        print(f"[{time.perf_counter() - t_start:6.1f} s] tightness on {name} done", flush=True)
    results["shift"] = bench_shift(cfg.shift_n, cfg.shift_seeds, cfg.shift_real_log, cfg.epsilon, cfg.delta)
    print(f"[{time.perf_counter() - t_start:6.1f} s] shift study done", flush=True)
    workloads = latency_workloads(models, cfg)
    results["latency"] = {
        "dataset": "quad_landing" if "quad_landing" in models else workloads[0].name,
        "model": "the IPC of the first training seed of the tightness run, calibrated as calibrate() does "
        "(PAC, with its domain of validity); queries = the workload's held-out queries, in order",
        **bench_latency(workloads, None, cfg.latency_rounds, cfg.latency_calls, cfg.batch_sizes),
    }
    print(f"[{time.perf_counter() - t_start:6.1f} s] latency done", flush=True)
    for name, (ipc, splits, load_s) in models.items():
        results["cost"][name] = {
            "data_seconds": load_s,
            **bench_cost(ipc, splits, results["tightness"][name]["ipc"], cfg.cost_repeats, cfg.sdp_count),
        }
    print(f"[{time.perf_counter() - t_start:6.1f} s] cost done", flush=True)
    results["startup"] = bench_startup(
        cfg.startup_repeats, n_train=min(cfg.n_train, 2000), epochs=cfg.startup_epochs
    )
    print(f"[{time.perf_counter() - t_start:6.1f} s] start-up done", flush=True)
    results["targets"] = targets(results)
    results["runtime_seconds"] = time.perf_counter() - t_start
    out_dir.mkdir(parents=True, exist_ok=True)
    write_json(out_dir / "results.json", results)
    md = render_markdown(results)
    (out_dir / "results.md").write_text(md)
    if figure is not None:
        from benchmarks.report import plot_throughput, plot_tightness

        plot_tightness(results, figure)
        plot_throughput(results, figure.with_name("bench_throughput.png"))
    print(md)
    return results


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test, numbers mean nothing")
    parser.add_argument("--out", type=Path, default=None, help="output folder (default: benchmarks/)")
    parser.add_argument(
        "--figure", type=Path, default=None, help="plot path (default: docs/img/bench_tightness.png)"
    )
    parser.add_argument("--datasets", nargs="+", default=list(DATASETS), choices=list(DATASETS))
    args = parser.parse_args(argv)
    cfg = RunConfig.quick() if args.quick else RunConfig()
    if args.quick and args.out is None:
        parser.error("--quick needs --out (do not overwrite the real results with smoke-test numbers)")
    out = args.out or Path(__file__).resolve().parent
    figure = args.figure or (None if args.quick else ROOT / "docs" / "img" / "bench_tightness.png")
    return run(cfg, out, figure, tuple(args.datasets))


if __name__ == "__main__":
    main()
