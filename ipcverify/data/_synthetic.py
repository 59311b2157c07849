"""A synthetic lagged-perception model, written for ipcverify's demo and tests.

An observer at position ``p`` moving with velocity ``v`` (the state
``x = [p, v]``) looks at a target on the ground. The truth ``y`` is the target's
position relative to the observer. The perception module sees an image that lags
by ``tau`` seconds (``tau`` random around one frame at 30 fps), so it reports the
relative position from ``tau`` seconds ago, ``y + v * tau``, plus pixel noise that
grows with range. The error therefore depends on the state: large when the observer
moves fast or is far away, small when it hovers close -- the situation in which an
IPC beats a single global error ellipsoid.
"""

from __future__ import annotations

import numpy as np

from ipcverify._wording._spelling import option
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError

#: Nominal lag, one frame at 30 fps (seconds).
FRAME_TIME = 1.0 / 30.0


def make_lagged_perception(
    n: int, seed: int = 0, lag_frames: float = 1.0, noise: float = 0.004
) -> PerceptionDataset:
    """Draw ``n`` i.i.d. samples of the synthetic lagged-perception model.

    Parameters
    ----------
    n : int
        Number of samples (>= 1).
    seed : int
        Seed of the random generator; equal seeds give equal data.
    lag_frames : float
        Mean lag in frames of 1/30 s (the lag is uniform on [0.5, 1.5] times this).
    noise : float
        Standard deviation of the range-proportional noise per metre of range.

    Returns
    -------
    PerceptionDataset
        ``x`` (n, 6) = [p_x, p_y, p_z, v_x, v_y, v_z]; ``y``, ``yhat`` (n, 3).

    Examples
    --------
    >>> ds = make_lagged_perception(100, seed=1)
    >>> ds.x.shape, ds.y.shape
    ((100, 6), (100, 3))
    """
    if n < 1:
        raise InvalidInputError(f"the number of samples ({option('n')}) must be >= 1; got {n}")
    if lag_frames < 0 or noise < 0:
        raise InvalidInputError("lag_frames and noise must be >= 0")
    rng = np.random.default_rng(seed)
    p = np.column_stack([rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(0.5, 3.0, n)])
    speed_scale = rng.choice([0.1, 0.5, 1.5], size=(n, 1), p=[0.4, 0.35, 0.25])
    v = rng.standard_normal((n, 3)) * speed_scale
    target = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), np.zeros(n)])
    y = target - p
    tau = FRAME_TIME * lag_frames * rng.uniform(0.5, 1.5, (n, 1))
    rng_ = np.linalg.norm(y, axis=1, keepdims=True)
    yhat = y + v * tau + noise * rng_ * rng.standard_normal((n, 3))
    return PerceptionDataset(x=np.hstack([p, v]), y=y, yhat=yhat, source="synthetic")
