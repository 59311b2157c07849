"""Training an IPC: :func:`train`, by a recipe (default ``"tight"``) or explicit configurations.

The objectives and :class:`TrainConfig` live in :mod:`ipcverify.objectives` (re-exported
here). A low-rank network (the default) is trained by :mod:`ipcverify.lowrank_training`,
all ensemble members at once; the paper's heads (recipes ``"v1"``, ``"paper"``) by the loop
below, one network.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

import torch

from ipcverify.architecture import DEFAULT_RECIPE, ModelConfig
from ipcverify.data import PerceptionDataset
from ipcverify.data_checks import check_informative, input_ranges
from ipcverify.errors import InvalidInputError
from ipcverify.lowrank_training import train_lowrank
from ipcverify.model import IPCModel, IPCNetwork, Network
from ipcverify.objectives import (
    Loss,
    NonFiniteLossError,
    TrainConfig,
    epoch_bar,
    hinge,
    ipc_loss,
    likelihood_loss,
    objective,
    step_factor,
)
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


@dataclass(frozen=True)
class TrainResult:
    """A trained model and the per-epoch history (``loss``, ``hinge``, ``logdet``, ...)."""

    model: IPCModel
    history: list[dict[str, float]]


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
        loss, h, reg = objective(g, logdet, cfg.loss, cfg)
    return {
        "loss": float(loss),
        ("half_sq_score" if cfg.loss == "likelihood" else "hinge"): float(h),
        "neg_logdet": float(reg),
        "violation_rate": float((g > 1).float().mean()),
    }


def _train_network(
    train_data: PerceptionDataset, mc: ModelConfig, tc: TrainConfig, progress: bool
) -> tuple[IPCNetwork, list[dict[str, float]]]:
    """The training loop of one network with the paper's heads (recipes ``"v1"``, ``"paper"``)."""
    if tc.center_warm_start and mc.lowrank:
        raise InvalidInputError("center_warm_start is for the paper's heads")
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
    total_steps = tc.epochs * math.ceil(n / tc.batch_size)
    sched = None
    if tc.schedule != "constant":
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda k: step_factor(k, total_steps, tc.schedule))
    history: list[dict[str, float]] = []
    best_state: dict[str, Any] | None = None
    best_val = math.inf
    stale = 0

    with epoch_bar(tc.epochs, progress) as (bar, task):
        for epoch in range(tc.epochs):
            net.train()
            epoch_loss = "likelihood" if epoch < tc.warmup_epochs else tc.loss
            perm = torch.randperm(n, generator=gen)
            total = 0.0
            for i in range(0, n, tc.batch_size):
                idx = perm[i : i + tc.batch_size]
                g, logdet = net.score(x[idx], y[idx], yhat[idx])
                loss, _, _ = objective(g, logdet, epoch_loss, tc)
                if not torch.isfinite(loss):
                    raise NonFiniteLossError(
                        f"non-finite training loss at epoch {epoch + 1} "
                        f"(param={mc.param!r}); use --param cholesky, whose log det is always "
                        "finite, or lower the learning rate"
                    )
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                if sched is not None:
                    sched.step()
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
    return net, history


def train(
    train_data: PerceptionDataset,
    model_config: ModelConfig | None = None,
    train_config: TrainConfig | None = None,
    progress: bool = False,
    *,
    recipe: str = DEFAULT_RECIPE,
) -> TrainResult:
    """Learn an IPC from a perception log.

    Parameters
    ----------
    train_data : PerceptionDataset
        Training samples (keep calibration and test data apart).
    model_config : ModelConfig, optional
        Architecture; default: the recipe's (for ``"tight"``: an ensemble of 5 low-rank-head
        MLPs (64, 64) with a linear centre stage).
    train_config : TrainConfig, optional
        Optimisation settings; default: the recipe's (for ``"tight"``: Gaussian likelihood,
        Adam 2e-3 with cosine decay, at most 60 epochs, early stopping on 15 % held out).
    progress : bool
        Show a rich progress bar.
    recipe : {"tight", "v1", "paper"}
        Where the configurations not given come from (``ipcverify.architecture.RECIPES``).
        A configuration that is given is used as it is.

    Returns
    -------
    TrainResult
        The model (uncalibrated) and the per-epoch history. The model's metadata holds the
        :class:`~ipcverify.theorem1.TrainingStatistics` of ``train_data`` (for every recipe),
        so that Theorem 1 can be evaluated from the model file alone.

    Raises
    ------
    NonFiniteLossError
        If the loss becomes NaN or infinite (possible with ``param="full"``, whose
        ``log det`` is ``-inf`` at a singular ``C``); switch to ``cholesky``.
    InvalidInputError
        For an unknown recipe or a configuration that does not fit the data.

    Examples
    --------
    >>> from ipcverify.synthetic import make_lagged_perception
    >>> ds = make_lagged_perception(200, seed=0)
    >>> res = train(ds, train_config=TrainConfig(epochs=2))
    >>> len(res.history), res.model.config.members
    (2, 5)
    >>> train(ds, recipe="paper").model.config.param
    'full'
    """
    check_informative(train_data, "training")
    tc = train_config or TrainConfig.recipe(recipe)
    mc = model_config or ModelConfig.recipe(recipe, x_dim=train_data.x_dim, y_dim=train_data.y_dim)
    if (mc.x_dim, mc.y_dim) != (train_data.x_dim, train_data.y_dim):
        raise InvalidInputError(
            f"model expects x_dim={mc.x_dim}, y_dim={mc.y_dim} but the data has "
            f"x_dim={train_data.x_dim}, y_dim={train_data.y_dim}"
        )
    net: Network
    if mc.lowrank:
        net, history = train_lowrank(train_data, mc, tc, progress)
    else:
        net, history = _train_network(train_data, mc, tc, progress)
    model = IPCModel(net)
    metadata: dict[str, Any] = {
        "train_config": tc.to_dict(),
        # what Theorem 1 needs, so that `ipcverify certify model.pt` works without the training file
        "training_statistics": TrainingStatistics.compute(model, train_data, tc.alpha).to_dict(),
        "train_data_hash": train_data.content_hash(),
        "train_n": len(train_data),
        "x_columns": list(train_data.x_columns),
        "y_columns": list(train_data.y_columns),
        "yhat_columns": list(train_data.yhat_columns),
        "training_inputs": input_ranges(train_data),  # calibration data far outside them: a warning
        "history": history,
    }
    return TrainResult(IPCModel(net, None, metadata), history)
