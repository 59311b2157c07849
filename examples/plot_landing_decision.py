"""
A landing decision with its proof
=================================

A landing controller measures the pad, gets the IPC's calibrated ellipsoid, and lands only when
it can prove that every position in the ellipsoid keeps the vehicle inside the target box ``G``
at the turn-off point (the paper's Proposition 1). :class:`~ipcverify.decision.LandingQuery` takes one
query (state, estimate) through the model, the calibration scale and the domain test, and
answers ACCEPT (with a proof), REJECT (measure again) or OUTSIDE_DOMAIN (never accepted).

Kept small: 3,000 rows of the toy data, 10 epochs of training; ``G`` is a 30 cm wide box.
"""

import matplotlib.pyplot as plt
import numpy as np

from ipcverify import Box, Ellipsoid, IPCQuery, LandingQuery, calibrate, example, train
from ipcverify.decision import check_landing
from ipcverify.training import TrainConfig

log = example(3000, seed=0).data
parts = log.split((0.4, 0.3, 0.3), seed=0)
model = train(parts.train, train_config=TrainConfig(epochs=10)).model
contract = calibrate(model, parts.calibration, epsilon=0.01, delta=0.01)

G = Box([-0.15, -0.15, 0.0], [0.15, 0.15, 0.1])  # where the vehicle may end up, around P
query = LandingQuery(IPCQuery(contract), G)
decisions = [query.decide(x, yhat) for x, yhat in zip(parts.test.x, parts.test.yhat, strict=True)]
verdicts = [d.verdict.name for d in decisions]
print({v: verdicts.count(v) for v in sorted(set(verdicts))})

# %%
# Every accept is proven. Its proof is the exact containment certificate of Proposition 1, and
# anyone can check it again in exact rational arithmetic.

accepted = next(d for d in decisions if d.accept)
proof = accepted.proof
print("turn-off point P:", np.round(proof.turnoff, 4).tolist())
print("certificate:", proof.certificate.status.name, "re-checked:", check_landing(proof).status.name)

# %%
# The accepted query's ellipsoid seen from above, and the box of positions it must lie in,
# ``{P} - G``: the proof says the first lies inside the second. With ``P_y = (C^T C)^{-1}``,
# the ellipsoid's shadow on the ground plane is the ellipse of the top-left 2 x 2 block of ``P_y``.

C = Ellipsoid(accepted.center, accepted.shape).shapes[0]
top = np.linalg.cholesky(np.linalg.inv(C.T @ C)[:2, :2])
angles = np.linspace(0.0, 2 * np.pi, 200)
rim = accepted.center[:2] + (top @ np.vstack([np.cos(angles), np.sin(angles)])).T
lo, up = proof.turnoff - G.upper, proof.turnoff - G.lower
fig, ax = plt.subplots(figsize=(6.5, 4))
ax.plot(rim[:, 0], rim[:, 1], label="calibrated set (top view)")
ax.add_patch(
    plt.Rectangle((lo[0], lo[1]), up[0] - lo[0], up[1] - lo[1], fill=False, ls="--", label="{P} - G")
)
ax.set_aspect("equal")
ax.autoscale_view()
ax.set_xlabel("y_0 (m)")
ax.set_ylabel("y_1 (m)")
ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0))
fig.tight_layout()
