"""Benchmark: ``ipcverify certify`` on 10,000 test samples, plus the synthetic acceptance numbers.

Run ``python -m benchmarks.bench_certify``. Target: certify on 10,000 test
samples, Lipschitz computations included, in <= 10 s on 2 CPU cores. Two timings are
recorded: the library call :func:`ipcverify.certification.certify_files` in a warm process
(load files, certify with Theorem 1 and both Lipschitz constants, write JSON and HTML)
and the full CLI command in a fresh process (interpreter start and imports included).

It also records, on the bundled synthetic data (recipe "v1", ipcverify's earlier Cholesky head: N = 5000
training samples, (64, 128) network, 20 epochs; n_cal = 5000, epsilon = 0.01, delta = 0.001;
the default ensemble's Theorem 1 is measured by :mod:`benchmarks.bench_theorem1`):
the calibrated IPC's violation rate on 200,000 fresh samples, its mean log-volume next
to a global Mahalanobis ellipsoid and a Bonferroni box calibrated the same way, and the
Theorem 1 numbers. Writes ``benchmarks/certify_results.json``.
"""

from __future__ import annotations

import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.common import machine_info
from benchmarks.timing import run_child
from ipcverify.calibration._bounds import clopper_pearson_upper
from ipcverify.certification._baselines import fit_bonferroni_box, fit_global_mahalanobis
from ipcverify.certification._certify import certify_files
from ipcverify.contract import calibrate
from ipcverify.data import save_dataset
from ipcverify.data._synthetic import make_lagged_perception
from ipcverify.io import save_model
from ipcverify.training import TrainConfig, train

OUT = Path(__file__).with_name("certify_results.json")
EPS, DELTA = 0.01, 0.001
TARGET = 10.0


def main(repeats: int = 3) -> dict[str, object]:
    work = Path(tempfile.mkdtemp(prefix="bench_certify_"))
    train_data = make_lagged_perception(5000, seed=100)
    cal_data = make_lagged_perception(5000, seed=101)
    test_data = make_lagged_perception(10_000, seed=102)
    big_test = make_lagged_perception(200_000, seed=103)
    for name, ds in (("train", train_data), ("test", test_data)):
        save_dataset(ds, work / f"{name}.csv")
    model = train(train_data, train_config=TrainConfig.recipe("v1", seed=0), recipe="v1").model
    cal_model = calibrate(model, cal_data, EPS, DELTA)
    save_model(cal_model, work / "calibrated.pt")

    results: dict[str, object] = {
        "machine": machine_info(),
        "target_seconds": TARGET,
        "n_test": len(test_data),
        "n_train": len(train_data),
        "n_parameters": model.n_parameters,
    }

    # --- timing: library call in a warm process
    lib_times = []
    res = None
    for i in range(repeats):
        t0 = time.perf_counter()
        res = certify_files(
            work / "calibrated.pt", work / "test.csv", work / f"out{i}", train_path=work / "train.csv"
        )
        lib_times.append(time.perf_counter() - t0)
    # --- timing: the CLI in a fresh process
    cli_times, cli_cpu = [], []
    exe = [sys.executable, "-m", "ipcverify"]
    for i in range(repeats):
        cmd = [*exe, "certify", str(work / "calibrated.pt"), "--data", str(work / "test.csv")]
        cmd += ["--train-data", str(work / "train.csv"), "--out", str(work / f"cli{i}")]
        run = run_child(cmd, check=True)
        cli_times.append(run.wall_s)
        cli_cpu.append(run.cpu_s)
    results["certify_library_seconds"] = {
        "median": statistics.median(lib_times),
        "min": min(lib_times),
        "max": max(lib_times),
    }
    results["certify_cli_seconds"] = {
        "median": statistics.median(cli_times),
        "min": min(cli_times),
        "max": max(cli_times),
    }
    results["certify_cli_cpu_seconds"] = {"median": statistics.median(cli_cpu)}
    results["recipe"] = "v1"
    results["meets_target"] = statistics.median(cli_times) <= TARGET
    print(f"certify (library, warm): median {statistics.median(lib_times):.2f} s")
    print(
        f"certify (CLI, fresh process): median {statistics.median(cli_times):.2f} s, "
        f"{statistics.median(cli_cpu):.2f} CPU-s"
    )

    # --- acceptance numbers
    assert res is not None
    cert = res.certificate.to_dict()
    sets = cal_model.predict_unguarded(big_test.x, big_test.yhat)
    k = int((~sets.contains(big_test.y)).sum())
    maha = fit_global_mahalanobis(train_data).calibrate(cal_data, EPS, DELTA)
    msets = maha.predict(big_test.x, big_test.yhat)
    box = fit_bonferroni_box(train_data).calibrate(cal_data, EPS, DELTA)
    bsets = box.predict(big_test.x, big_test.yhat)
    ipc_lv = float(np.mean(sets.log_volume()))
    results["synthetic"] = {
        "epsilon": EPS,
        "delta": DELTA,
        "n_calibration": len(cal_data),
        "calibration_k": cal_model.calibration.threshold.k,
        "calibration_scale": cal_model.calibration.threshold.scale,
        "big_test_n": len(big_test),
        "ipc_violation_rate": k / len(big_test),
        "ipc_violation_upper_bound_999": clopper_pearson_upper(k, len(big_test), 1e-3),
        "ipc_mean_log_volume": ipc_lv,
        "mahalanobis_violation_rate": float(np.mean(~msets.contains(big_test.y))),
        "mahalanobis_mean_log_volume": float(np.mean(msets.log_volume())),
        "box_violation_rate": float(np.mean(~bsets.contains(big_test.y))),
        "box_mean_log_volume": float(np.mean(bsets.log_volume())),
        "volume_ratio_mahalanobis_over_ipc_geometric_mean": float(
            np.exp(np.mean(msets.log_volume()) - ipc_lv)
        ),
    }
    results["certificate_10k"] = {
        "status": cert["status"],
        "test": cert["test"],
        "volume": cert["volume"],
        "theorem1": {
            k2: cert["theorem1"][k2]
            for k2 in (
                "bound",
                "vacuous",
                "n_needed",
                "lipschitz_empirical",
                "lipschitz_sound",
                "lipschitz_radius",
                "empirical_term",
                "complexity_term_sound",
                "complexity_term_empirical",
                "confidence_term",
                "bound_with_empirical_lipschitz",
                "n_needed_with_empirical_lipschitz",
            )
        },
    }
    print(json.dumps(results["synthetic"], indent=2))
    print(json.dumps(results["certificate_10k"]["theorem1"], indent=2))
    OUT.write_text(json.dumps(results, indent=2) + "\n")
    return results


if __name__ == "__main__":
    main()
