"""The guard at scale: how the domain test's costs grow, and ``ipcverify predict`` on 10^6 rows.

Run ``python -m benchmarks.bench_guard`` (about 5 minutes on 2 cores; ``--quick`` for a smoke
test). It writes ``benchmarks/guard_results.json`` and ``docs/img/guard_scale.png``:

* **Calibration size** (``calibration``): the domain test fitted on 10^3 to 10^6 calibration
  rows of the synthetic law (9 inputs; :func:`benchmarks.oracle_data.make_hetlag`). Fit seconds
  (whitening, the reference subset, the leave-one-out threshold), the index's build seconds,
  the references kept (at most :data:`ipcverify.guard.MAX_REFERENCE`), and per query of an
  independent in-distribution draw: the batch test, the single-query test, the exact distance;
  the share flagged in distribution and under a subtle and a strong shift (states scaled by
  1.1 and 1.5).
* **Reference cap** (``reference_cap``): 2 x 10^5 calibration rows, the reference capped at
  10^3, 10^4 and 10^5: what the cap costs in time and in the test's power; the false-alarm
  guarantee holds at every cap (a random subset of exchangeable inputs is exchangeable with
  the query; ``proofs/domain.md``).
* **Batch size** (``batches``): the quad IPC (15 inputs) calibrated on 120 flights, its domain
  fitted by flight, on its 80 held-out flights tiled to 10^2 ... 10^6 rows: the guarded
  ``predict_sets``, the same without its domain test, and the bare torch forward (one thread;
  chunks of 10^5 rows above that, as a user would run it).
* **The command** (``cli_predict``): ``ipcverify predict`` on 10^6 rows of those queries
  (Parquet), in a fresh process, with one BLAS thread (``OPENBLAS_NUM_THREADS=1``, the
  setting docs/benchmarks.md recommends on small machines) and with NumPy's default of one
  BLAS thread per core: wall and CPU seconds, and the in-process split (read, sets and domain
  test, distances, write).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import torch

from benchmarks.common import blas_single_thread, machine_info, save_figure, write_json
from benchmarks.datasets import load_splits, quad_flights
from benchmarks.oracle_data import make_hetlag
from benchmarks.timing import run_child
from ipcverify.calibration import Global
from ipcverify.contract import IPCModel, calibrate
from ipcverify.contract._prediction import predict_sets, write_predictions
from ipcverify.data import PerceptionInputs
from ipcverify.data._files import atomic_write
from ipcverify.guard import DomainModel, DomainSpec
from ipcverify.io import load_model, save_model
from ipcverify.io._modelio import load_inputs_for_model
from ipcverify.training import TrainConfig, train

__all__ = ["batches", "calibration_sizes", "cli_predict", "main", "plot", "reference_cap"]

ROOT = Path(__file__).resolve().parent.parent
OUT = Path(__file__).with_name("guard_results.json")
FIGURE = ROOT / "docs" / "img" / "guard_scale.png"
#: The shifted queries: the states scaled by these factors (a subtle and a strong shift).
SHIFTS = (1.1, 1.5)


def _timed(fn: Callable[[], Any], repeats: int = 3) -> tuple[float, float]:
    """Median wall and CPU seconds of ``repeats`` calls (after one warm-up call)."""
    fn()
    wall, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu))


def _xy(n: int, seed: int, shift: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    data, _ = make_hetlag(n, seed, "gauss")
    return data.x * shift, data.yhat


def _per_query(dom: DomainModel, n_queries: int) -> dict[str, Any]:
    """Per-query costs and flagged shares of one fitted test (in-distribution and shifted queries)."""
    x, y = _xy(n_queries, 7)
    z = np.hstack([x, y])[: min(2000, n_queries)]

    def one() -> None:
        for row in z:
            dom.contains_one(row)

    out: dict[str, Any] = {}
    for name, fn, count in (
        ("batch_test", lambda: dom.contains(x, y), n_queries),
        ("single_query_test", one, len(z)),
        ("exact_distance", lambda: dom.distance(x, y), n_queries),
    ):
        wall, cpu = _timed(fn, 2)
        out[f"{name}_us"] = {"wall": wall / count * 1e6, "cpu": cpu / count * 1e6}
    out["flagged_in_distribution"] = float(1.0 - dom.contains(x, y).mean())
    for shift in SHIFTS:
        xs, ys = _xy(n_queries, 8, shift=shift)
        out[f"flagged_states_x{shift:g}"] = float(1.0 - dom.contains(xs, ys).mean())
    return out


def calibration_sizes(sizes: tuple[int, ...], n_queries: int) -> list[dict[str, Any]]:
    """The default test fitted on ``sizes`` calibration rows: fit and build time, query costs."""
    rows = []
    for n in sizes:
        x, y = _xy(n, 11)
        t0, c0 = time.perf_counter(), time.process_time()
        dom = DomainModel.fit(x, y)
        fit = (time.perf_counter() - t0, time.process_time() - c0)
        t0 = time.perf_counter()
        index = dom.index()
        build = time.perf_counter() - t0
        rows.append(
            {
                "calibration_rows": n,
                "references": dom.n,
                "inputs": len(dom.mean),
                "threshold": dom.threshold,
                "fit_seconds": {"wall": fit[0], "cpu": fit[1]},
                "index_build_seconds": build,
                "index": index.prune_stats(),
                **_per_query(dom, n_queries),
            }
        )
        print(f"  calibration {n:,}: {rows[-1]['batch_test_us']['wall']:.2f} us/query", flush=True)
    return rows


def reference_cap(n: int, caps: tuple[int, ...], n_queries: int) -> list[dict[str, Any]]:
    """``n`` calibration rows, the reference capped at each of ``caps``."""
    x, y = _xy(n, 12)
    rows = []
    for cap in caps:
        t0 = time.perf_counter()
        dom = DomainModel.fit(x, y, max_reference=cap)
        fit = time.perf_counter() - t0
        t0 = time.perf_counter()
        dom.index()
        rows.append(
            {
                "calibration_rows": n,
                "cap": cap,
                "references": dom.n,
                "threshold": dom.threshold,
                "fit_seconds": fit,
                "index_build_seconds": time.perf_counter() - t0,
                **_per_query(dom, n_queries),
            }
        )
        print(f"  cap {cap:,}: flagged (states x1.1) {rows[-1]['flagged_states_x1.1']:.3f}", flush=True)
    return rows


def _quad_contract(quick: bool) -> tuple[IPCModel, PerceptionInputs]:
    """The quad IPC (default recipe), calibrated on 120 flights by flight, and its held-out queries."""
    if quick:
        data, _ = make_hetlag(1500, 3, "gauss")
        model = train(data, train_config=TrainConfig.recipe("tight", seed=0, epochs=2)).model
        cal, _ = make_hetlag(1000, 4, "gauss")
        test, _ = make_hetlag(500, 5, "gauss")
        contract = calibrate(model, cal, 0.05, 0.05, Global(mode="pac"))
        return contract, PerceptionInputs(test.x, test.yhat)
    splits = load_splits("quad_landing", 5000, 5000, 5000)
    model = train(splits.train, train_config=TrainConfig.recipe("tight", seed=0)).model
    cal, test = quad_flights()
    contract = calibrate(model, cal, 0.01, 0.001, Global(mode="pac"), domain=DomainSpec(group_column="path"))
    return contract, PerceptionInputs(test.x, test.yhat)


def _tile(q: PerceptionInputs, n: int) -> PerceptionInputs:
    reps = -(-n // len(q.x))
    return PerceptionInputs(np.tile(q.x, (reps, 1))[:n], np.tile(q.yhat, (reps, 1))[:n])


def batches(model: IPCModel, queries: PerceptionInputs, sizes: tuple[int, ...]) -> list[dict[str, Any]]:
    """Queries per second of the guarded path, the same without its domain, and bare torch, per size."""
    bare_model = model.with_calibration(model.calibration, None)
    body = model.network.body
    eng = model.engine
    assert model.domain is not None  # noqa: S101 - calibrate() fits one
    model.domain.prepare()
    rows = []
    for n in sizes:
        q = _tile(queries, n)
        z = torch.from_numpy(((np.hstack([q.x, q.yhat]) - eng.in_mean) * eng.in_scale).astype(np.float32))

        def bare(z: torch.Tensor = z) -> None:
            with torch.inference_mode():
                for start in range(0, len(z), 100_000):
                    body(z[start : start + 100_000])

        repeats = 1 if n >= 1_000_000 else 3
        row: dict[str, Any] = {"queries": n}
        for name, fn in (
            ("bare_torch_forward", bare),
            ("predict_sets", lambda q=q: predict_sets(model, q)),
            ("predict_sets_without_domain", lambda q=q: predict_sets(bare_model, q)),
            ("domain_contains", lambda q=q: model.domain.contains(q.x, q.yhat)),  # type: ignore[union-attr]
        ):
            wall, cpu = _timed(fn, repeats)
            row[name] = {"queries_per_second": n / wall, "cpu_seconds": cpu, "wall_seconds": wall}
        row["guarded_ratio_to_bare_forward"] = (
            row["predict_sets"]["queries_per_second"] / row["bare_torch_forward"]["queries_per_second"]
        )
        rows.append(row)
        print(f"  batch {n:,}: guarded / bare = {row['guarded_ratio_to_bare_forward']:.2f}", flush=True)
    return rows


def cli_predict(model: IPCModel, queries: PerceptionInputs, n: int) -> dict[str, Any]:
    """``ipcverify predict`` on ``n`` rows in a fresh process (default threads), and its split in-process."""
    q = _tile(queries, n)
    frame = pd.DataFrame(
        np.hstack([q.x, q.yhat]),
        columns=[f"x_{i}" for i in range(q.x.shape[1])] + [f"yhat_{i}" for i in range(q.yhat.shape[1])],
    )
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        save_model(model, folder / "model.pt")
        atomic_write(folder / "queries.parquet", lambda f: frame.to_parquet(f, index=False))
        env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
        env["PYTHONPATH"] = str(ROOT)
        cmd = [sys.executable, "-m", "ipcverify", "predict", str(folder / "model.pt"),
               str(folder / "queries.parquet"), "--out", str(folder / "sets.npz"), "--force"]  # fmt: skip
        subprocess.run([sys.executable, "-c", "import ipcverify.cli"], env=env, check=True)  # warm file cache
        runs: dict[str, Any] = {}
        one = {"OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        for name, extra in (("one_blas_thread", one), ("default_threads", {})):
            proc = run_child(cmd, env=env | extra, check=True)
            wall = proc.wall_s
            runs[name] = {
                "wall_seconds": wall,
                "cpu_seconds": proc.cpu_s,
                "environment": extra or "no *_NUM_THREADS set: NumPy's BLAS with one thread per core",
            }
            print(f"  {name}: {wall:.1f} s wall, {runs[name]['cpu_seconds']:.1f} s CPU", flush=True)
        with np.load(folder / "sets.npz") as npz:
            in_domain = npz["in_domain"]
            finite = bool(np.isfinite(npz["domain_distance"]).all())
        split: dict[str, float] = {}
        t0 = time.perf_counter()
        m = load_model(folder / "model.pt")
        inputs = load_inputs_for_model(folder / "queries.parquet", m)
        split["read_model_and_queries"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        pred = predict_sets(m, inputs)
        split["sets_and_domain_test"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        _ = pred.distance
        split["exact_distances"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        write_predictions(pred, folder / "again.npz")
        split["write_npz"] = time.perf_counter() - t0
    return {
        "rows": n,
        "command": "ipcverify predict MODEL queries.parquet --out sets.npz",
        **runs["one_blas_thread"],
        "runs": runs,
        "outside_fraction": float(1.0 - in_domain.mean()),
        "distances_finite": finite,
        "stdout": proc.stdout.strip().splitlines()[:3],
        "in_process_seconds_one_blas_thread": split,
    }


def plot(results: dict[str, Any], path: Path) -> None:
    """Three panels: cost against calibration size and the reference cap; throughput against batch size."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(14.5, 4.2))
    cal = results["calibration"]
    n = [r["calibration_rows"] for r in cal]
    ax = axes[0]
    for key, label, style in (
        ("batch_test_us", "batch test (µs / query)", "o-"),
        ("single_query_test_us", "one query (µs)", "s-"),
        ("exact_distance_us", "exact distance (µs / query)", "^-"),
    ):
        ax.plot(n, [r[key]["wall"] for r in cal], style, label=label)
    ax.plot(n, [r["fit_seconds"]["wall"] * 1e3 for r in cal], "x--", color="grey", label="fit (ms)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"calibration rows (references kept: at most {max(r['references'] for r in cal):,})")
    ax.set_title("Cost against calibration size (synthetic, 9 inputs)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[1]
    cap = results["reference_cap"]
    refs = [r["references"] for r in cap]
    ax.plot(refs, [r["batch_test_us"]["wall"] for r in cap], "o-", label="batch test (µs / query)")
    ax.plot(refs, [r["exact_distance_us"]["wall"] for r in cap], "^-", label="exact distance (µs / query)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel(f"references kept of {cap[0]['calibration_rows']:,} calibration rows")
    ax2 = ax.twinx()
    ax2.plot(
        refs,
        [100 * r["flagged_states_x1.1"] for r in cap],
        "d:",
        color="#b42318",
        label="states x1.1 flagged (%)",
    )
    ax2.plot(refs, [100 * r["flagged_in_distribution"] for r in cap], "d:", color="#4c72b0",
             label="in-distribution flagged (%)")  # fmt: skip
    ax2.set_ylabel("queries flagged (%)")
    ax.set_title("The reference cap: time against power", fontsize=9)
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], fontsize=7, loc="center left")
    ax.grid(True, which="both", alpha=0.3)

    ax = axes[2]
    bt = results["batches"]
    sizes = [r["queries"] for r in bt]
    for key, label, style in (
        ("predict_sets", "predict_sets (guarded)", "D-"),
        ("predict_sets_without_domain", "predict_sets without domain", "o--"),
        ("bare_torch_forward", "bare torch forward", "^-"),
    ):
        ax.plot(sizes, [r[key]["queries_per_second"] for r in bt], style, label=label)
    ax.plot(sizes, [0.8 * r["bare_torch_forward"]["queries_per_second"] for r in bt], ":", color="grey",
            label="0.8 x bare forward")  # fmt: skip
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("batch size (held-out quad flights, tiled)")
    ax.set_ylabel("queries per second (1 thread)")
    ax.set_title("Throughput against batch size (quad, 15 inputs)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(True, which="both", alpha=0.3)
    save_figure(fig, path)


def main(argv: list[str] | None = None) -> dict[str, Any]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="tiny sizes: a smoke test, numbers mean nothing")
    ap.add_argument(
        "--out", type=Path, default=None, help="folder for the JSON and the figure (default: the repo's)"
    )
    a = ap.parse_args(argv)
    if a.quick and a.out is None:
        ap.error("--quick needs --out (do not overwrite the real results with smoke-test numbers)")
    torch.set_num_threads(1)
    blas_single_thread()
    t0 = time.perf_counter()
    q = 500 if a.quick else 10_000
    results: dict[str, Any] = {"command": "python -m benchmarks.bench_guard", "machine": machine_info()}
    print("calibration sizes", flush=True)
    results["calibration"] = calibration_sizes(
        (300, 1000) if a.quick else (1_000, 10_000, 100_000, 1_000_000), q
    )
    print("reference cap", flush=True)
    results["reference_cap"] = reference_cap(*((3000, (300, 1000, 3000)) if a.quick else
                                               (200_000, (1_000, 10_000, 100_000))), q)  # fmt: skip
    model, queries = _quad_contract(a.quick)
    print("batch sizes", flush=True)
    results["batches"] = batches(
        model, queries, (100, 1000) if a.quick else (100, 1_000, 10_000, 100_000, 1_000_000)
    )
    print("ipcverify predict", flush=True)
    results["cli_predict"] = cli_predict(model, queries, 2_000 if a.quick else 1_000_000)
    results["runtime_seconds"] = time.perf_counter() - t0
    out = (a.out / "guard_results.json") if a.out else OUT
    write_json(out, results)
    plot(results, (a.out / "guard_scale.png") if a.out else FIGURE)
    cli = results["cli_predict"]
    print(
        f"ipcverify predict on {cli['rows']:,} rows: {cli['wall_seconds']:.1f} s wall, "
        f"{cli['cpu_seconds']:.1f} s CPU"
    )
    return results


if __name__ == "__main__":
    main()
