"""Synthetic lagged-perception data whose conditional law ``y | (x, yhat)`` is known exactly.

With the law known, the smallest set with coverage ``q`` at every input -- the **oracle**
-- is known too, and any method's calibrated sets can be measured against it
(:mod:`benchmarks.diagnose_tightness`, :mod:`benchmarks.bench_tightness`).

:func:`make_hetlag` -- heteroscedastic lagged perception, the benchmark's ``synthetic``
dataset (Gaussian) and its non-Gaussian variant ``law="t4"``:

* state ``x = [p_x, p_y, d, v_x, v_y, v_z]``: lateral position ``p ~ U[-2, 2]^2``, depth
  ``d ~ U[0.5, 3]`` (m), velocity ``v = s * N(0, I)`` with speed scale ``s`` in
  {0.1, 0.5, 1.5} (probabilities 0.4, 0.35, 0.25);
* prior ``y | x ~ N((-p_x, -p_y, -d), diag(0.3, 0.3, 0.05)^2)`` (the target relative to
  the camera, near the point under it);
* perception ``yhat | y, x ~ N(y + tau0 v, R(x))`` with
  ``R(x) = sigma0^2 d^4 diag(1, 1, 9) + tau_sd^2 v v^T``: a lag of ``tau ~ N(tau0, tau_sd^2)``
  (``tau0 = 1/30`` s, ``tau_sd = 1/100`` s) moves the estimate by ``tau v`` -- a bias linear in
  the state and a rank-one random part along the velocity -- and pixel / stereo noise grows
  with depth squared (``sigma0 = 0.002``, three times larger in depth);
* hence ``y | (x, yhat) ~ N(mu, Sigma)``, ``Sigma = (P^-1 + R^-1)^-1``,
  ``mu = Sigma (P^-1 m + R^-1 (yhat - tau0 v))`` (the Kalman update), exactly.

``law="t4"`` keeps ``(x, yhat)`` and draws ``y = mu + chol(Sigma) u`` with ``u`` a
multivariate Student t with 4 degrees of freedom scaled to unit covariance: elliptical,
heavy tailed, its oracle known by construction.

:func:`make_fresh_lagged` -- a second generator with different functional forms (a
line-of-sight state, noise rotated into the line of sight, a rotational lag term, an
altitude-dependent prior, nuisance inputs). It was written and committed before the default
recipe was tuned (research branch ``research/tightness``, commit a602459) and is used for
nothing but the final check of the default on data no tuning has seen.

``shift > 0`` moves the state law of either generator (deeper / longer range, faster
motion): covariate shift for :mod:`benchmarks.bench_shift`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import stats

from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.sets import Ellipsoid
from ipcverify.sets._ellipsoid import unit_ball_log_volume

__all__ = ["Oracle", "make_hetlag", "make_fresh_lagged"]

FloatArray = NDArray[np.float64]
LAWS = ("gauss", "t4")


@dataclass(frozen=True)
class Oracle:
    """The exact conditional law ``y = mean + chol @ u`` of each sample, ``u`` spherical with unit covariance.

    Attributes
    ----------
    mean : array (N, n)
    chol : array (N, n, n)
        Lower-triangular ``S`` with ``Sigma = S S^T`` the covariance of ``y``.
    law : {"gauss", "t4"}
        Gaussian ``u``, or a unit-covariance multivariate t with 4 degrees of freedom.

    Examples
    --------
    >>> ds, orc = make_hetlag(50, seed=0)
    >>> round(orc.radius(0.99) ** 2, 4)  # chi-squared with 3 degrees of freedom
    11.3449
    """

    mean: FloatArray
    chol: FloatArray
    law: str = "gauss"

    def __post_init__(self) -> None:
        if self.law not in LAWS:
            raise InvalidInputError(f"law must be one of {', '.join(LAWS)}; got {self.law!r}")

    @property
    def n(self) -> int:
        """Dimension of ``y``."""
        return int(self.mean.shape[1])

    @property
    def nu(self) -> float | None:
        """Degrees of freedom of the t law (None for the Gaussian)."""
        return None if self.law == "gauss" else float(self.law[1:])

    def radius(self, q: float) -> float:
        """The exact ``q``-quantile of ``||u||``."""
        if self.nu is None:
            return float(math.sqrt(stats.chi2.ppf(q, self.n)))
        nu = self.nu
        return float(math.sqrt(self.n * (nu - 2.0) / nu * stats.f.ppf(q, self.n, nu)))

    def sample_u(self, rng: np.random.Generator, shape: tuple[int, ...]) -> FloatArray:
        """Draws of ``u`` with shape ``(*shape, n)``."""
        z = rng.standard_normal((*shape, self.n))
        if self.nu is None:
            return z
        w = rng.chisquare(self.nu, shape)[..., None]
        return z * np.sqrt((self.nu - 2.0) / w)

    def sets(self, scale: float) -> Ellipsoid:
        """The oracle's ellipsoids ``{y : ||S^-1 (y - mean)|| <= scale}``."""
        return Ellipsoid(self.mean, np.linalg.inv(self.chol) / scale)

    def log_volume(self, q: float) -> FloatArray:
        """Exact log volume of each oracle set at coverage ``q`` (closed form, no Monte Carlo)."""
        logdet = np.log(np.abs(np.diagonal(self.chol, axis1=1, axis2=2))).sum(1)
        return unit_ball_log_volume(self.n) + self.n * math.log(self.radius(q)) + logdet

    def scores(self, y: FloatArray) -> FloatArray:
        """The oracle's own conformity scores ``||S^-1 (y - mean)||``."""
        return np.linalg.norm(np.linalg.solve(self.chol, (y - self.mean)[..., None])[..., 0], axis=1)

    def subset(self, rows: Any) -> Oracle:
        """The oracle of the selected samples."""
        return Oracle(self.mean[rows], self.chol[rows], self.law)


def _outer(v: FloatArray) -> FloatArray:
    return np.einsum("bi,bj->bij", v, v)


def make_hetlag(
    n: int, seed: int, law: str = "gauss", shift: float = 0.0
) -> tuple[PerceptionDataset, Oracle]:
    """``n`` samples of the known-oracle heteroscedastic lagged-perception law, and their oracle.

    Examples
    --------
    >>> ds, orc = make_hetlag(100, seed=0)
    >>> ds.x.shape, orc.chol.shape
    ((100, 6), (100, 3, 3))
    """
    if law not in LAWS:
        raise InvalidInputError(f"law must be one of {', '.join(LAWS)}; got {law!r}")
    rng = np.random.default_rng(seed)
    p = rng.uniform(-2, 2, (n, 2))
    d = rng.uniform(0.5, 3.0 + 1.5 * shift, n)
    speed = rng.choice([0.1, 0.5, 1.5], size=(n, 1), p=[0.4, 0.35, 0.25]) * (1.0 + shift)
    v = rng.standard_normal((n, 3)) * speed
    tau0, tau_sd, sigma0 = 1.0 / 30.0, 1.0 / 100.0, 0.002
    m = np.column_stack([-p[:, 0], -p[:, 1], -d])
    P = np.diag([0.3**2, 0.3**2, 0.05**2])
    R = (sigma0**2 * d[:, None, None] ** 4) * np.diag([1.0, 1.0, 9.0])[None] + tau_sd**2 * _outer(v)
    Pinv, Rinv = np.linalg.inv(P), np.linalg.inv(R)
    Sigma = np.linalg.inv(Pinv[None] + Rinv)
    Sigma = 0.5 * (Sigma + Sigma.transpose(0, 2, 1))
    S = np.linalg.cholesky(Sigma)
    y0 = m + rng.standard_normal((n, 3)) * np.sqrt(np.diag(P))
    yhat = y0 + tau0 * v + np.einsum("bij,bj->bi", np.linalg.cholesky(R), rng.standard_normal((n, 3)))
    mu = np.einsum("bij,bj->bi", Sigma, m @ Pinv.T + np.einsum("bij,bj->bi", Rinv, yhat - tau0 * v))
    orc = Oracle(mean=mu, chol=S, law=law)
    # the forward draw y0 is a draw from N(mu, Sigma) given (x, yhat); the t law redraws y
    y = y0 if law == "gauss" else mu + np.einsum("bij,bj->bi", S, orc.sample_u(rng, (n,)))
    ds = PerceptionDataset(
        x=np.column_stack([p, d, v]), y=y, yhat=yhat, source=f"hetlag(law={law}, seed={seed}, shift={shift})"
    )
    return ds, orc


def _skew(w: FloatArray) -> FloatArray:
    """Cross-product matrices ``[w]_x`` (N, 3, 3)."""
    z = np.zeros(len(w))
    return np.stack(
        [
            np.stack([z, -w[:, 2], w[:, 1]], -1),
            np.stack([w[:, 2], z, -w[:, 0]], -1),
            np.stack([-w[:, 1], w[:, 0], z], -1),
        ],
        axis=1,
    )


def make_fresh_lagged(n: int, seed: int, shift: float = 0.0) -> tuple[PerceptionDataset, Oracle]:
    """``n`` samples of the held-out generator (never used for tuning) and their Gaussian oracle.

    State ``x = [range, azimuth, elevation, v_x, v_y, v_z, w_pitch, w_yaw, altitude]``; the
    truth is the target position in the camera frame. The estimate is
    ``yhat = y + tau (v + w x y) + noise`` with a random lag ``tau`` (mean 0.04 s, sd 0.012 s),
    noise rotated into the line of sight (lateral sd ``0.003 range``, along-sight sd
    ``0.0015 range^2``); the random part of the lag is linearised around the prior mean,
    so ``y | (x, yhat)`` is exactly Gaussian (the Kalman update of the prior).

    Examples
    --------
    >>> ds, orc = make_fresh_lagged(100, seed=0)
    >>> ds.x.shape, orc.law
    ((100, 9), 'gauss')
    """
    rng = np.random.default_rng(seed)
    rho = rng.uniform(1.0, 6.0 + 3.0 * shift, n)
    az = rng.uniform(-0.6, 0.6, n)
    el = rng.uniform(-1.2, -0.3, n)  # looking down
    speed = rng.gamma(2.0, 0.35 * (1.0 + shift), n)
    vdir = rng.standard_normal((n, 3))
    v = vdir / np.linalg.norm(vdir, axis=1, keepdims=True) * speed[:, None]
    w = np.column_stack([rng.normal(0, 0.05, n), rng.normal(0, 0.4, n), rng.normal(0, 0.4, n)])
    alt = -rho * np.sin(el) + rng.normal(0, 0.2, n)
    los = np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    e1 = np.cross(los, np.array([0.0, 0.0, 1.0]))
    e1 /= np.linalg.norm(e1, axis=1, keepdims=True)
    frame = np.stack([los, e1, np.cross(los, e1)], axis=2)  # columns: line of sight, two lateral axes
    prior_sd = np.column_stack([0.15 + 0.05 * np.abs(alt), np.full(n, 0.4), np.full(n, 0.4)])
    P = np.einsum("bij,bj,bkj->bik", frame, prior_sd**2, frame)
    m = rho[:, None] * los
    noise_sd = np.column_stack([0.0015 * rho**2, 0.003 * rho, 0.003 * rho])
    tau0, tau_sd = 0.04, 0.012
    W = _skew(w)
    lag_dir = v + np.einsum("bij,bj->bi", W, m)
    R = np.einsum("bij,bj,bkj->bik", frame, noise_sd**2, frame) + tau_sd**2 * _outer(lag_dir)
    H = np.eye(3)[None] + tau0 * W  # yhat = H y + tau0 v + noise
    y = m + np.einsum("bij,bj->bi", np.linalg.cholesky(P), rng.standard_normal((n, 3)))
    noise = np.einsum("bij,bj->bi", np.linalg.cholesky(R), rng.standard_normal((n, 3)))
    yhat = np.einsum("bij,bj->bi", H, y) + tau0 * v + noise
    Pinv, Rinv = np.linalg.inv(P), np.linalg.inv(R)
    HtRinv = np.einsum("bji,bjk->bik", H, Rinv)
    Sigma = np.linalg.inv(Pinv + np.einsum("bij,bjk->bik", HtRinv, H))
    Sigma = 0.5 * (Sigma + Sigma.transpose(0, 2, 1))
    rhs = np.einsum("bij,bj->bi", Pinv, m) + np.einsum("bij,bj->bi", HtRinv, yhat - tau0 * v)
    mu = np.einsum("bij,bj->bi", Sigma, rhs)
    x = np.column_stack([rho, az, el, v, w[:, 1], w[:, 2], alt])
    ds = PerceptionDataset(x=x, y=y, yhat=yhat, source=f"fresh_lagged(seed={seed}, shift={shift})")
    return ds, Oracle(mean=mu, chol=np.linalg.cholesky(Sigma), law="gauss")
