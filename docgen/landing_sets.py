"""Make ``tests/data/landing_sets.npz``: 10^4 landing decisions of a trained IPC on the case study's flights.

The containment problems of Proposition 1 as the quadrotor poses them. Three mixed datasets of
the case study (exploration paths and approach flights, :func:`collect_mixed`, camera buffer 1,
different seeds: different flights) train and calibrate an IPC with the reproduction's recipe
(:func:`learn_ipc`, fewer epochs) and supply the queries. Every query goes through the landing's
own path (:meth:`LandingQuery.decide` with the measurement's camera pose ``T_WC``, as
:class:`case_studies.quad_landing.landing.contracts.LearnedContract` does): the calibrated set in
the camera frame, moved to the world frame, decided against ``G_tau`` (the paper's ``G`` shrunk
by the tracking tolerance, :func:`decision_target`). The file keeps the world-frame sets
exactly (float64), the target and the landing's verdicts; the containment problem of each
decision is ``landing_decision(Ellipsoid(c, C), G_tau)``'s (``E`` against ``{P} ⊕ (-G_tau)``).

Run ``python -m docgen.landing_sets`` (about three minutes on two cores; it overwrites the
file). ``tests/ipcverify/decision/containment/test_landing_sdp.py`` reads it.
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from case_studies.quad_landing.data.approach import ApproachParams
from case_studies.quad_landing.data.columns import X_COLUMNS, XW_COLUMNS, YHAT_COLUMNS, YHATW_COLUMNS
from case_studies.quad_landing.data.datasets import as_dataset, collect_mixed
from case_studies.quad_landing.landing.state_machine import LandingParams, decision_target
from case_studies.quad_landing.reproduction.config import IpcParams
from case_studies.quad_landing.reproduction.learn import learn_ipc
from case_studies.quad_landing.sim.camera import Camera
from case_studies.quad_landing.sim.config import load_config
from case_studies.quad_landing.sim.frames import transform_ellipsoid
from ipcverify.data._files import atomic_write
from ipcverify.decision import IPCQuery, LandingQuery

OUT = Path(__file__).resolve().parents[1] / "tests" / "data" / "landing_sets.npz"
N_QUERIES = 10_000
SIZES = {"train": 3000, "calibration": 3000}
SEEDS = {"train": 911, "calibration": 912, "queries": 913}


def main() -> None:
    t0 = time.perf_counter()
    config = load_config()
    approach = ApproachParams.defaults()
    frames = {
        name: collect_mixed(n, buffer_size=1, seed=SEEDS[name], approach=approach, config=config)
        for name, n in (*SIZES.items(), ("queries", N_QUERIES))
    }
    print(f"collected in {time.perf_counter() - t0:.0f} s")
    params = IpcParams.defaults(epochs=20, epsilon=0.01)
    model = learn_ipc(as_dataset(frames["train"]), as_dataset(frames["calibration"]), params)
    print(f"trained and calibrated in {time.perf_counter() - t0:.0f} s")
    landing = LandingParams.defaults()
    target = decision_target(landing.tracking_tolerance, landing.target)
    query = LandingQuery(IPCQuery(model), target)
    camera = Camera(config.camera)
    q = frames["queries"]
    x, yhat = q[list(X_COLUMNS)].to_numpy(float), q[list(YHAT_COLUMNS)].to_numpy(float)
    xw, yhatw = q[list(XW_COLUMNS)].to_numpy(float), q[list(YHATW_COLUMNS)].to_numpy(float)
    centers, shapes = np.empty((N_QUERIES, 3)), np.empty((N_QUERIES, 3, 3))
    accept, in_domain = np.empty(N_QUERIES, bool), np.empty(N_QUERIES, bool)
    for i in range(N_QUERIES):
        pose = camera.world_from_camera(xw[i])
        if not np.allclose(pose.apply(yhat[i]), yhatw[i], rtol=0.0, atol=1e-9):
            raise RuntimeError(f"row {i}: the camera pose does not reproduce the dataset's yhat_W")
        d = query.decide(x[i], yhat[i], transform=lambda c, C, pose=pose: transform_ellipsoid(c, C, pose))
        centers[i], shapes[i], accept[i], in_domain[i] = d.center, d.shape, d.accept, d.in_domain
    info = {
        "made_by": "python -m docgen.landing_sets",
        "seeds": SEEDS,
        "sizes": {**SIZES, "queries": N_QUERIES},
        "ipc": {
            "recipe": params.recipe,
            "hidden": list(params.hidden),
            "epochs": params.train.epochs,
            "epsilon": params.epsilon,
            "delta": params.delta,
        },  # fmt: skip
        "target": "decision_target(tracking_tolerance, G) of LandingParams.defaults()",
        "accepted": int(accept.sum()),
        "outside_domain": int((~in_domain).sum()),
    }
    atomic_write(
        OUT,
        lambda f: np.savez_compressed(
            f,
            centers=centers,
            shapes=shapes,
            accept=accept,
            in_domain=in_domain,
            target_lower=target.lower,
            target_upper=target.upper,
            info=np.array(json.dumps(info)),
        ),  # fmt: skip
    )
    print(json.dumps(info, indent=1))
    print(f"wrote {OUT} ({OUT.stat().st_size / 1e6:.2f} MB) in {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
