"""
Certify a model
===============

Train an IPC, calibrate it on held-out data (PAC: at most 5 % of new truths outside their sets,
with confidence 99 %), and certify it on fresh test data. The certificate states the claim,
checks it against the test data with an exact Clopper-Pearson bound, and says what it does not
cover.

Kept small so that it runs in seconds: 3,000 rows of the toy data and 10 epochs of the default
recipe (``tight``), where a real run uses the recipe's 60.
"""

import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from ipcverify import calibrate, certify, example, train
from ipcverify.certification import write_certificate
from ipcverify.training import TrainConfig

log = example(3000, seed=0).data
parts = log.split((0.4, 0.3, 0.3), seed=0)  # train, calibration, test: disjoint
model = train(parts.train, train_config=TrainConfig(epochs=10)).model
contract = calibrate(model, parts.calibration, epsilon=0.05, delta=0.01)

result = certify(contract, parts.test)
summary = result.certificate.summary
print(summary.verdict_text())
print(summary.claim)

# %%
# The certificate and its report are two files: ``certificate.json`` (the numbers) and a
# self-contained ``report.html`` whose top is the summary a reviewer signs.

out = Path(tempfile.mkdtemp()) / "certificate"
write_certificate(result, out)
print(sorted(p.name for p in out.iterdir()))

# %%
# Each test truth's score ``g = ||C (y - c)||`` is at most 1 exactly when it lies inside its
# calibrated set. The guarded ``predict`` gives the sets and, for each query, whether it lies in
# the domain of validity that calibration fitted: the guarantee covers those.

p = contract.predict(parts.test.x, parts.test.yhat)
scores = p.sets.g(parts.test.y)
fig, ax = plt.subplots(figsize=(6, 3))
ax.hist(np.log10(scores), bins=60, color="tab:blue")
ax.axvline(0.0, color="k", lw=1)
ax.set_xlabel("log10 score of the test truths (right of the line: outside its set)")
ax.set_ylabel("test rows")
ax.set_title(f"{(scores > 1).mean():.1%} outside; {(~p.in_domain).sum()} queries outside the domain")
fig.tight_layout()
