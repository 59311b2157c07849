"""A generator of perception logs made of runs, with known truth: ipcverify's own, for the validity benchmark.

A log is ``n_runs`` runs of ``rows`` rows. Within a run the state drifts smoothly (a speed between
0.5 and 3 m/s, a range to the target between 2 and 12 m, a heading), the truth ``y`` is the
target's position in the body frame, and the estimate's error is

    e_t = sigma(x_t) * c_run * z_t,      sigma(x) = 0.02 + 0.015 * speed + 0.004 * range,

with ``z_t`` a 3-D AR(1) series of unit variance (coefficient ``rho``: how slowly the error drifts
within a run) and ``c_run = exp(cond * N(0, 1) - cond^2 / 2)`` a per-run factor (the run's
conditions: light, wind, a sensor's bias) of mean 1. ``SETTINGS`` names the strengths used:
no dependence at all (the errors are independent given the state), autocorrelation only, mild
autocorrelation and conditions, and strong both. The same seed gives the same log.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.signal import lfilter

from ipcverify.data import PerceptionDataset

__all__ = ["SETTINGS", "Setting", "make_run_log"]


@dataclass(frozen=True)
class Setting:
    """How correlated the rows of a run are.

    Attributes
    ----------
    name : str
        A short name for tables.
    rho : float
        The AR(1) coefficient of the error within a run (0: independent given the state).
    cond : float
        The standard deviation of the log of a run's error factor (0: no per-run conditions).
    """

    name: str
    rho: float
    cond: float


#: The settings of the validity benchmark, from none to strong within-run dependence.
SETTINGS = (
    Setting("independent", 0.0, 0.0),
    Setting("autocorrelated", 0.95, 0.0),
    Setting("mild", 0.8, 0.1),
    Setting("strong", 0.95, 0.3),
)


def _smooth(rng: np.random.Generator, n_runs: int, rows: int, lo: float, hi: float) -> np.ndarray:
    """A slowly varying signal per run in ``[lo, hi]`` (a random walk through a sine)."""
    walk = np.cumsum(rng.normal(0.0, 0.08, size=(n_runs, rows)), axis=1) + rng.uniform(
        0, 2 * np.pi, (n_runs, 1)
    )
    return lo + (hi - lo) * 0.5 * (1.0 + np.sin(walk))


def make_run_log(
    n_runs: int, rows: int, setting: Setting, seed: int, error_scale: float = 1.0, start: int = 0
) -> PerceptionDataset:
    """A log of ``n_runs`` runs of ``rows`` rows in ``setting`` (see the module docstring).

    Parameters
    ----------
    n_runs, rows : int
        Runs and rows per run.
    setting : Setting
        The within-run dependence.
    seed : int
        The log's seed.
    error_scale : float
        Multiplies every error (1: in distribution; above 1: a shifted, worse estimator).
    start : int
        The first run's label (runs are labelled ``start, start + 1, ...``).

    Examples
    --------
    >>> log = make_run_log(3, 50, SETTINGS[3], seed=0)
    >>> len(log), log.x_dim, log.y_dim, sorted(set(log.extra["run"].tolist()))
    (150, 4, 3, [0, 1, 2])
    """
    rng = np.random.default_rng(seed)
    speed = _smooth(rng, n_runs, rows, 0.5, 3.0)
    rng_range = _smooth(rng, n_runs, rows, 2.0, 12.0)
    heading = _smooth(rng, n_runs, rows, -np.pi, np.pi)
    height = _smooth(rng, n_runs, rows, 1.0, 4.0)
    y = np.stack([rng_range * np.cos(heading), rng_range * np.sin(heading), -height], axis=-1)
    sigma = 0.02 + 0.015 * speed + 0.004 * rng_range
    z = rng.normal(size=(n_runs, rows, 3))
    if setting.rho > 0:  # each run starts in the stationary law (its first row is N(0, 1))
        b, a = [math.sqrt(1.0 - setting.rho**2)], [1.0, -setting.rho]
        z[:, 1:] = lfilter(b, a, z[:, 1:], axis=1, zi=setting.rho * z[:, :1])[0]
    factor = np.exp(setting.cond * rng.normal(size=(n_runs, 1, 1)) - setting.cond**2 / 2)
    error = error_scale * sigma[..., None] * factor * z
    x = np.stack([speed, rng_range, np.cos(heading), np.sin(heading)], axis=-1)
    run = np.repeat(np.arange(start, start + n_runs), rows)
    return PerceptionDataset(
        x.reshape(-1, 4),
        y.reshape(-1, 3),
        (y + error).reshape(-1, 3),
        source=f"{setting.name} log {seed}",
        extra={"run": run},
    )
