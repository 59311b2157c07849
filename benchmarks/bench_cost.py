"""Cost of the pipeline steps: training, calibration, certification, containment batches, SDP proofs.

Training and calibration times are taken from the tightness runs of the default recipe
("tight": 5 low-rank-head networks (64, 64) trained together, N = 5000, at most 60 epochs
with early stopping, batch 128). Certification calls :func:`ipcverify.certification.certify`
with the training data (Theorem 1 included: its training statistics and the sound Lipschitz
bound of the default ensemble).
Containment: the vectorised float landing check and the closed
form over a batch of 10^5 ellipsoids, and the compiled S-lemma SDP per problem
(:mod:`benchmarks.bench_containment`).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from benchmarks.bench_containment import bench_closed_form_batch, bench_sdp
from benchmarks.common import spread
from benchmarks.datasets import Splits
from case_studies.quad_landing.landing.state_machine import LandingParams
from ipcverify.contract import IPCModel
from ipcverify.decision._landing_float import landing_accept_float

__all__ = ["bench_cost"]


def _certify_seconds(model: IPCModel, splits: Splits, repeats: int) -> dict[str, Any]:
    try:
        from ipcverify.certification import certify
    except ImportError as exc:  # certify.py is being finished by another engineer
        return {"skipped": f"ipcverify.certification._certify not importable: {exc}"}
    times = []
    status = None
    for _ in range(repeats):
        t0 = time.perf_counter()
        try:
            res = certify(model, splits.test, train_data=splits.train)
        except Exception as exc:  # noqa: BLE001 - report whatever stops it, do not hide it
            return {"skipped": f"certify failed: {type(exc).__name__}: {exc}"}
        times.append(time.perf_counter() - t0)
        status = res.certificate.status.name
    return {"seconds": spread(times), "status": status, "with_train_data": True}


def bench_cost(
    model: IPCModel, splits: Splits, tightness_ipc: dict[str, Any], repeats: int = 3, sdp_count: int = 60
) -> dict[str, Any]:
    """Pipeline costs for one (calibrated) model on one dataset; see the module docstring."""
    rng = np.random.default_rng(20240601)
    sets = model.predict_unguarded(splits.test.x, splits.test.yhat)
    landing = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        landing_accept_float(sets, LandingParams.defaults().target)
        landing.append(time.perf_counter() - t0)
    return {
        "training_seconds": tightness_ipc["spread"]["train_seconds"],
        "training_setting": f"recipe tight, N = {len(splits.train)}: 5 networks (64, 64), <= 60 epochs",
        "calibration_seconds": tightness_ipc["spread"]["calibrate_seconds"],
        "certification": _certify_seconds(model, splits, repeats),
        "landing_accept_float_batch": {"batch": len(sets), "seconds": spread(landing)},
        "containment_closed_form_batch": bench_closed_form_batch(rng, b=100_000, repeats=repeats),
        "sdp_proof_per_problem": bench_sdp(rng, count=sdp_count),
    }
