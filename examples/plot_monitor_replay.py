"""
Monitor a replay
================

A certificate holds for queries like the calibration data. The online monitor notices when
that stops being true: it replays a labelled log, in order, through an anytime-valid test of
"the violation rate is at most the certified rate", and alarms the first time the evidence
reaches ``1/delta`` -- a contract that keeps its promise alarms falsely with probability at most
``delta``, however long the log.

Here the first half of the replay is drawn like the calibration data, and in the second half
the estimator's error triples. Kept small: 3,000 rows, 10 epochs of training.
"""

import matplotlib.pyplot as plt
import numpy as np

from ipcverify import PerceptionDataset, calibrate, example, train
from ipcverify.contract import monitor_log
from ipcverify.training import TrainConfig

log = example(3000, seed=0).data
parts = log.split((0.4, 0.6, 0.0), seed=0)
model = train(parts.train, train_config=TrainConfig(epochs=10)).model
contract = calibrate(model, parts.calibration, epsilon=0.05, delta=0.01)

fresh = example(2000, seed=1).data  # the deployment log, with its ground truth
yhat = fresh.yhat.copy()
yhat[1000:] = fresh.y[1000:] + 3.0 * (fresh.yhat[1000:] - fresh.y[1000:])  # the shift
replay = PerceptionDataset(fresh.x, fresh.y, yhat)

watch = monitor_log(contract, replay)
alarm = watch.result.alarm_index
print(f"tested rate {watch.epsilon:.4f}, false alarms at most {watch.delta}")
print("alarm at row", alarm)

# %%
# The evidence against the certified rate (log of the e-value) as the replay goes on; the
# alarm threshold is ``log(1/delta)``.

fig, ax = plt.subplots(figsize=(6, 3))
ax.plot(watch.result.index, watch.result.log_e_value)
ax.axhline(np.log(1 / watch.delta), color="k", ls="--", lw=1, label="alarm threshold")
ax.axvline(1000, color="tab:red", lw=1, label="the shift begins")
ax.set_xlabel("row of the replay")
ax.set_ylabel("log e-value")
ax.legend()
fig.tight_layout()
