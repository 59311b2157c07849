"""
Ingest trajectories and calibrate by runs
=========================================

A robot log is a few runs, and the rows of one run are correlated: the runs, not the rows, are
the independent units. This example writes twelve short flights as TUM trajectory files (truth
and estimate), turns them into a perception log with :func:`ipcverify.io.ingest.ingest_trajectories`,
splits it by run, and calibrates with the runs as the units. ``plan_runs`` says first what the
calibration runs can support: no claim about a new run goes below ``1 - delta**(1/G)`` from
``G`` runs, however many rows each holds.

Kept small: 12 flights of 20 s, 10 epochs of training.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from scipy.spatial.transform import Rotation

from ipcverify import DomainSpec, Grouped, PerceptionDataset, calibrate, certify, train
from ipcverify.calibration import plan_runs
from ipcverify.io.ingest import ingest_trajectories
from ipcverify.training import TrainConfig

folder = Path(tempfile.mkdtemp())
rng = np.random.default_rng(0)
truth_files, estimate_files = [], []
for run in range(12):
    t = np.arange(0.0, 20.0, 0.02)
    w = 2 * np.pi / rng.uniform(6.0, 12.0)
    p = np.column_stack([np.sin(w * t), 0.6 * np.sin(2 * w * t), 1.0 + 0.1 * np.sin(w * t)])
    step = np.diff(p, axis=0, prepend=p[:1])
    heading = np.unwrap(np.arctan2(step[:, 1], step[:, 0]))
    tilt = 0.1 * np.sin(np.column_stack([w * t, 2 * w * t]))  # the body tilts as it turns
    quat = Rotation.from_euler("ZYX", np.column_stack([heading, tilt])).as_quat()  # qx qy qz qw
    # the estimate drifts: a per-run scale error of the velocity and noise on every step
    drift = (1.0 + rng.normal(0.0, 0.03)) * step + rng.normal(0.0, 2e-4, step.shape)
    estimate = p[0] + np.cumsum(drift, axis=0)
    truth_files.append(folder / f"truth_{run:02d}.txt")
    estimate_files.append(folder / f"flight_{run:02d}.txt")
    np.savetxt(truth_files[-1], np.column_stack([t, p, quat]))  # TUM: t x y z qx qy qz qw
    np.savetxt(estimate_files[-1], np.column_stack([t, estimate, quat])[::3])  # at a third of the rate

frame = ingest_trajectories(truth_files, estimate_files)  # one run per estimate file
log = PerceptionDataset.from_frame(frame)
print(f"{len(frame)} rows, runs: {sorted(set(frame['run']))[:3]} ...")

# %%
# Split whole runs to each part, then ask what the calibration runs allow.

parts = log.split((0.4, 0.6, 0.0), seed=0, group_column="run")
runs = len(set(parts.calibration.extra["run"].tolist()))
plan = plan_runs(runs, delta=0.05)
print(f"{runs} calibration runs; no claim about a new run below {plan.floor:.3f}")
for claim in plan.claims:
    print(f"  {claim.guarantee}: the smallest rate it can certify is {claim.smallest}")

# %%
# Calibrate with the runs as the units (the default when the data name their runs; written out
# here). The domain-of-validity test is fitted by run too, which needs at least ``1/r - 1`` runs
# for a flag rate ``r``: 0.15 here.

model = train(parts.train, train_config=TrainConfig(epochs=10)).model
contract = calibrate(
    model,
    parts.calibration,
    epsilon=0.4,
    delta=0.05,
    method=Grouped(column="run"),
    domain=DomainSpec(flag_rate=0.15),
)
print(certify(contract).certificate.summary.claim)  # from the model alone: UNTESTED

# %%
# The displacement over 0.5 s that ingestion writes: the truth against the estimate, for one run.

one = frame[frame["run"] == frame["run"].iloc[0]]
fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(one["t"], one["y_0"], label="truth")
ax.plot(one["t"], one["yhat_0"], label="estimate", ls="--")
ax.set_xlabel("time (s)")
ax.set_ylabel("forward displacement over 0.5 s (m)")
ax.legend()
fig.tight_layout()
