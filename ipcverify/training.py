"""Training an IPC by the paper's objective (or, optionally, by Gaussian likelihood).

The paper's loss (``loss="hinge"``, the default) on a batch is
``mean(l(g - 1)) + lam * mean(-log det(C^T C))`` with the hinge
``l(t) = max(0, t / alpha + 1)`` (paper, eq. for L_ERM and L_REG): the hinge pushes every
score ``g = ||C (y - c)||`` below ``1 - alpha``, the log-determinant term shrinks the
ellipsoids. ``loss="likelihood"`` is the Gaussian negative log-likelihood of ``y`` under
``N(c, (C^T C)^{-1})`` up to constants, ``mean(g^2) / 2 - mean(log det C)``.
"""

from __future__ import annotations

import copy
import math
from dataclasses import asdict, dataclass
from typing import Any, Literal

import torch
from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

from ipcverify.architecture import ModelConfig
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.model import IPCModel, IPCNetwork
from ipcverify.theorem1 import TrainingStatistics

__all__ = [
    "TrainConfig",
    "TrainResult",
    "Loss",
    "hinge",
    "ipc_loss",
    "likelihood_loss",
    "warm_start_center",
    "train",
    "NonFiniteLossError",
]

#: Training objectives: the paper's hinge + volume loss, or Gaussian likelihood.
Loss = Literal["hinge", "likelihood"]
_LOSSES: tuple[str, ...] = ("hinge", "likelihood")


class NonFiniteLossError(InvalidInputError):
    """Training produced a non-finite loss (possible with the ``full`` parameterisation)."""


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """Optimisation settings.

    Parameters
    ----------
    epochs : int
        Passes over the training data (paper: 20).
    lr : float
        Adam learning rate (paper: 1e-3).
    batch_size : int
        Mini-batch size.
    alpha : float
        Hinge margin ``alpha > 0``. Default 1.0 (the paper: 0.1): with ``alpha >= 1`` the
        hinge is active for every sample, so the loss is ``mean(g) / alpha`` plus the volume
        term and the shape is learned from all samples, not only from those near the
        boundary; calibration then sets the size. On held-out data this gave 3x smaller
        calibrated sets on the quad-landing data and 10 % smaller on the synthetic data
        at the same certified coverage (``benchmarks/tuning_results.json``,
        ``docs/benchmarks.md``). The raw, uncalibrated sets are then conservative
        (oversized): calibrate before use.
    lam : float
        Weight ``lambda >= 0`` of the volume penalty.
    seed : int
        Seeds initialisation and shuffling; CPU training is reproducible.
    val_fraction : float
        Share of the training data held out for validation (0 disables it).
    patience : int or None
        With validation, stop after this many epochs without improvement and
        restore the best weights.
    loss : {"hinge", "likelihood"}
        Training objective. ``"hinge"`` (default) is the paper's
        ``mean(l(g - 1)) + lam * mean(-log det(C^T C))``. ``"likelihood"`` is the Gaussian
        negative log-likelihood of ``y`` under ``N(c, (C^T C)^{-1})`` up to constants,
        ``mean(g^2) / 2 - mean(log det C)`` (``log det(C^T C) = 2 log det C``); ``alpha`` and
        ``lam`` are not used by it. The squared score weights large errors more than the
        hinge with ``alpha >= 1`` (which is ``mean(g) / alpha``), and the large errors are
        the ones that set the calibrated radius. Its raw sets (radius 1) are undersized --
        ``g^2`` is about chi-squared with ``n`` degrees of freedom -- so calibrate before use.
    warmup_epochs : int
        With ``loss="hinge"``: train the first ``warmup_epochs`` of the ``epochs`` with the
        likelihood loss, then switch to the hinge (0, the default, disables it; must be
        ``< epochs``). Must be 0 with ``loss="likelihood"``.
    center_warm_start : bool
        Before training, set the centre rows of the network's output layer to the
        least-squares fit of the target centre offset ``(y - base) / sigma`` (``base`` is
        ``yhat`` for ``center="offset"``, the mean of ``y`` for ``"raw"``) on the features
        of the last hidden layer at initialisation, with a small ridge term (closed form,
        see :func:`warm_start_center`). Closed form rather than extra epochs on
        ``||y - c||^2``: it is the exact minimiser of the (ridge-regularised) squared
        centre error over that layer, costs one small linear solve instead of training
        time, has no step size or epoch count to tune, and leaves the shape head at its
        initialisation. It removes e.g. a linear bias of ``yhat`` before the main loss
        starts. Off by default: on the benchmark data it made the calibrated sets larger,
        not smaller (``docs/benchmarks.md``).

    Raises
    ------
    InvalidInputError
        If a value is out of range or ``loss`` is unknown.

    Examples
    --------
    >>> TrainConfig(epochs=5).lr
    0.001
    """

    epochs: int = 20
    lr: float = 1e-3
    batch_size: int = 64
    alpha: float = 1.0
    lam: float = 0.01
    seed: int = 0
    val_fraction: float = 0.0
    patience: int | None = None
    loss: Loss = "hinge"
    warmup_epochs: int = 0
    center_warm_start: bool = False

    def __post_init__(self) -> None:
        if self.loss not in _LOSSES:
            raise InvalidInputError(f"loss must be 'hinge' or 'likelihood'; got {self.loss!r}")
        if not isinstance(self.center_warm_start, bool):
            raise InvalidInputError(
                f"center_warm_start must be True or False; got {self.center_warm_start!r}"
            )
        checks = [
            (self.epochs >= 1, f"epochs must be >= 1; got {self.epochs}"),
            (self.lr > 0 and math.isfinite(self.lr), f"lr must be > 0; got {self.lr}"),
            (self.batch_size >= 1, f"batch size must be >= 1; got {self.batch_size}"),
            (self.alpha > 0 and math.isfinite(self.alpha), f"alpha must be > 0; got {self.alpha}"),
            (self.lam >= 0 and math.isfinite(self.lam), f"lam must be >= 0; got {self.lam}"),
            (0 <= self.val_fraction < 1, f"val_fraction must be in [0, 1); got {self.val_fraction}"),
            (
                self.patience is None or self.patience >= 1,
                f"patience must be >= 1; got {self.patience}",
            ),
            (
                self.patience is None or self.val_fraction > 0,
                "patience (early stopping) needs a validation split: set val_fraction > 0",
            ),
            (
                0 <= self.warmup_epochs < self.epochs,
                f"warmup_epochs must be in [0, epochs={self.epochs}); got {self.warmup_epochs}",
            ),
            (
                self.warmup_epochs == 0 or self.loss == "hinge",
                "warmup_epochs (likelihood pretraining) only applies to loss='hinge'",
            ),
        ]
        for ok, msg in checks:
            if not ok:
                raise InvalidInputError(msg)

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (stored in model files)."""
        return asdict(self)


@dataclass(frozen=True)
class TrainResult:
    """A trained model and the per-epoch history (``loss``, ``hinge``, ``logdet``, ...)."""

    model: IPCModel
    history: list[dict[str, float]]


def hinge(t: torch.Tensor, alpha: float) -> torch.Tensor:
    """The paper's hinge ``l(t) = max(0, t / alpha + 1)``."""
    return torch.clamp(t / alpha + 1.0, min=0.0)


def ipc_loss(
    g: torch.Tensor, logdet: torch.Tensor, alpha: float, lam: float
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The paper's objective on a batch.

    Parameters
    ----------
    g : Tensor (B,)
        Scores ``||C (y - c)||``.
    logdet : Tensor (B,)
        ``log det(C^T C)`` per sample.

    Returns
    -------
    loss, hinge_term, reg_term : Tensor
        ``loss = hinge_term + lam * reg_term`` with ``hinge_term = mean l(g - 1)`` and
        ``reg_term = mean(-logdet)``.

    Examples
    --------
    >>> g = torch.tensor([0.5, 1.0]); ld = torch.tensor([2.0, 0.0])
    >>> [round(float(v), 4) for v in ipc_loss(g, ld, alpha=0.5, lam=0.1)]
    [0.4, 0.5, -1.0]
    """
    h = hinge(g - 1.0, alpha).mean()
    reg = (-logdet).mean()
    return h + lam * reg, h, reg


def likelihood_loss(g: torch.Tensor, logdet: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Gaussian negative log-likelihood of ``y`` under ``N(c, (C^T C)^{-1})``, up to constants.

    Parameters
    ----------
    g : Tensor (B,)
        Scores ``||C (y - c)||`` (so ``g^2`` is the Mahalanobis distance in precision ``C^T C``).
    logdet : Tensor (B,)
        ``log det(C^T C)`` per sample.

    Returns
    -------
    loss, sq_term, reg_term : Tensor
        ``loss = sq_term + reg_term / 2`` with ``sq_term = mean(g^2) / 2`` and
        ``reg_term = mean(-logdet)``, i.e. ``mean(g^2) / 2 - mean(log det C)``.

    Examples
    --------
    >>> g = torch.tensor([1.0, 2.0]); ld = torch.tensor([2.0, 0.0])
    >>> [round(float(v), 4) for v in likelihood_loss(g, ld)]
    [0.75, 1.25, -1.0]
    """
    sq = 0.5 * (g * g).mean()
    reg = (-logdet).mean()
    return sq + 0.5 * reg, sq, reg


def _loss(
    g: torch.Tensor, logdet: torch.Tensor, loss: str, cfg: TrainConfig
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    if loss == "likelihood":
        return likelihood_loss(g, logdet)
    return ipc_loss(g, logdet, cfg.alpha, cfg.lam)


def warm_start_center(
    net: IPCNetwork, x: torch.Tensor, y: torch.Tensor, yhat: torch.Tensor, ridge: float = 1e-2
) -> None:
    """Least-squares initialisation of the centre head (in place).

    With ``h`` the last hidden layer's output on the (normalised) inputs and ``[h, 1]`` the
    features, the centre rows ``W`` of the output layer and their biases are set to
    ``argmin ||[h, 1] W^T - t||^2 + ridge * tr(H^T H) / k * ||W||^2`` where
    ``t = (y - base) / sigma`` is the offset that would put the centre on ``y`` (``k``
    features; the bias is not penalised). Solved in float64. The shape rows are untouched.
    The network's normalisation must already be set.

    The default ``ridge = 0.01`` fits the benchmark data's centre almost as well as
    ``1e-6`` on the training split (and better on held-out data) with weights about 10x
    smaller; large output weights amplify every later change of the hidden features.

    Parameters
    ----------
    net : IPCNetwork
    x, y, yhat : Tensor (B, d), (B, n), (B, n)
        Training data (float32).
    ridge : float
        Relative ridge weight (also keeps the solve well posed with dead ReLU features).
    """
    n = net.config.y_dim
    with torch.no_grad():
        z = (torch.cat([x, yhat], dim=1) - net.in_mean) / net.in_std
        h = net.body[:-1](z).double()
        base = yhat if net.config.center == "offset" else net.y_mean.expand_as(yhat)
        target = ((y - base) / net.sigma).double()
        feats = torch.cat([h, torch.ones(len(h), 1, dtype=torch.float64)], dim=1)
        gram = feats.T @ feats
        k = h.shape[1]
        pen = torch.zeros(k + 1, dtype=torch.float64)
        pen[:k] = ridge * max(float(torch.diagonal(gram)[:k].mean()), 1e-12)
        sol = torch.linalg.solve(gram + torch.diag(pen), feats.T @ target)  # (k + 1, n)
        last = net.output_layer
        last.weight[:n] = sol[:k].T.to(last.weight.dtype)
        last.bias[:n] = sol[k].to(last.bias.dtype)


def _tensors(ds: PerceptionDataset) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    return (
        torch.tensor(ds.x, dtype=torch.float32),
        torch.tensor(ds.y, dtype=torch.float32),
        torch.tensor(ds.yhat, dtype=torch.float32),
    )


def _evaluate_loss(net: IPCNetwork, ds: PerceptionDataset, cfg: TrainConfig) -> dict[str, float]:
    x, y, yhat = _tensors(ds)
    with torch.no_grad():
        g, logdet = net.score(x, y, yhat)
        loss, h, reg = _loss(g, logdet, cfg.loss, cfg)
    return {
        "loss": float(loss),
        ("half_sq_score" if cfg.loss == "likelihood" else "hinge"): float(h),
        "neg_logdet": float(reg),
        "violation_rate": float((g > 1).float().mean()),
    }


def train(
    train_data: PerceptionDataset,
    model_config: ModelConfig | None = None,
    train_config: TrainConfig | None = None,
    progress: bool = False,
) -> TrainResult:
    """Learn an IPC from a perception log.

    Parameters
    ----------
    train_data : PerceptionDataset
        Training samples (keep calibration and test data apart).
    model_config : ModelConfig, optional
        Architecture; default: paper's (64, 128) MLP with Cholesky shape.
    train_config : TrainConfig, optional
        Optimisation settings; default: Adam 1e-3 for 20 epochs.
    progress : bool
        Show a rich progress bar.

    Returns
    -------
    TrainResult
        The model (uncalibrated) and the per-epoch history.

    Raises
    ------
    NonFiniteLossError
        If the loss becomes NaN or infinite (possible with ``param="full"``, whose
        ``log det`` is ``-inf`` at a singular ``C``); switch to ``cholesky``.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> ds = make_lagged_perception(200, seed=0)
    >>> res = train(ds, train_config=TrainConfig(epochs=2))
    >>> len(res.history)
    2
    """
    tc = train_config or TrainConfig()
    mc = model_config or ModelConfig(x_dim=train_data.x_dim, y_dim=train_data.y_dim)
    if (mc.x_dim, mc.y_dim) != (train_data.x_dim, train_data.y_dim):
        raise InvalidInputError(
            f"model expects x_dim={mc.x_dim}, y_dim={mc.y_dim} but the data has "
            f"x_dim={train_data.x_dim}, y_dim={train_data.y_dim}"
        )
    torch.manual_seed(tc.seed)
    gen = torch.Generator().manual_seed(tc.seed)

    fit, val = train_data, None
    if tc.val_fraction > 0:
        parts = train_data.split((1 - tc.val_fraction, 0.0, tc.val_fraction), seed=tc.seed)
        if parts.train is None or parts.test is None:
            raise InvalidInputError("too few samples to hold out a validation split")
        fit, val = parts.train, parts.test

    net = IPCNetwork(mc)
    net.set_normalisation(fit.x, fit.y, fit.yhat)
    x, y, yhat = _tensors(fit)
    if tc.center_warm_start:
        warm_start_center(net, x, y, yhat)
    opt = torch.optim.Adam(net.parameters(), lr=tc.lr)
    n = len(fit)
    history: list[dict[str, float]] = []
    best_state: dict[str, Any] | None = None
    best_val = math.inf
    stale = 0

    bar = Progress(
        TextColumn("training"),
        BarColumn(),
        TextColumn("epoch {task.completed}/{task.total} loss {task.fields[loss]:.4f}"),
        TimeRemainingColumn(),
        disable=not progress,
        transient=True,
    )
    with bar:
        task = bar.add_task("train", total=tc.epochs, loss=float("nan"))
        for epoch in range(tc.epochs):
            net.train()
            epoch_loss = "likelihood" if epoch < tc.warmup_epochs else tc.loss
            perm = torch.randperm(n, generator=gen)
            total = 0.0
            for i in range(0, n, tc.batch_size):
                idx = perm[i : i + tc.batch_size]
                g, logdet = net.score(x[idx], y[idx], yhat[idx])
                loss, _, _ = _loss(g, logdet, epoch_loss, tc)
                if not torch.isfinite(loss):
                    raise NonFiniteLossError(
                        f"non-finite training loss at epoch {epoch + 1} "
                        f"(param={mc.param!r}); use --param cholesky, whose log det is always "
                        "finite, or lower the learning rate"
                    )
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                total += float(loss.detach()) * len(idx)
            net.eval()
            rec = {"epoch": float(epoch + 1), "train_loss": total / n}
            rec.update({f"fit_{k}": v for k, v in _evaluate_loss(net, fit, tc).items()})
            if val is not None:
                vrec = _evaluate_loss(net, val, tc)
                rec.update({f"val_{k}": v for k, v in vrec.items()})
                if vrec["loss"] < best_val:
                    best_val, stale = vrec["loss"], 0
                    best_state = copy.deepcopy(net.state_dict())
                else:
                    stale += 1
            history.append(rec)
            bar.update(task, advance=1, loss=rec["train_loss"])
            if tc.patience is not None and stale >= tc.patience:
                break
    if best_state is not None and tc.patience is not None:
        net.load_state_dict(best_state)
    net.eval()
    stats = TrainingStatistics.compute(IPCModel(net), train_data, tc.alpha)
    metadata = {
        "train_config": tc.to_dict(),
        # what Theorem 1 needs, so that `ipcverify certify model.pt` works without the training file
        "training_statistics": stats.to_dict(),
        "train_data_hash": train_data.content_hash(),
        "train_n": len(train_data),
        "x_columns": list(train_data.x_columns),
        "y_columns": list(train_data.y_columns),
        "yhat_columns": list(train_data.yhat_columns),
        "history": history,
    }
    return TrainResult(IPCModel(net, None, metadata), history)
