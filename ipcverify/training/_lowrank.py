"""Training a :class:`~ipcverify.network.LowRankEnsemble`: every member at once, in one process.

1. The input standardisation, the closed-form linear centre stage and the output scale
   ``sigma`` are fitted on all training data (float64,
   :meth:`~ipcverify.network.LowRankEnsemble.fit_normalisation`); the targets are
   ``t = (y - yhat - lin(z)) / sigma``.
2. Each member holds out its own random ``val_fraction`` of the rows for validation and
   shuffles its own mini-batches; its weights start from its own seed.
3. One optimiser step updates every member: the loss is the sum of the members' batch
   losses, so each member's weights get exactly its own gradient, and Adam, being
   elementwise, updates each member as if it were trained alone. Members share only the
   step-size schedule.
4. A member whose validation loss has not improved for ``patience`` epochs is frozen at its
   best weights (its loss is masked and its Adam moments are zeroed, so later steps do not
   move it); training ends when every member is frozen or after ``epochs``. Every member
   ends at its best validation epoch.

Batching the members turns five small trainings into one with the same number of
optimiser steps, which costs about as much per step as one member: the whole recipe
trains on N = 5,000 in a few seconds on one core (``benchmarks/bench_training.py``).
"""

from __future__ import annotations

import math

import numpy as np
import torch

from ipcverify._wording._spelling import option
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import ModelConfig
from ipcverify.network._lowrank import LowRankEnsemble, member_covariances
from ipcverify.training._objectives import NonFiniteLossError, TrainConfig, epoch_bar, hinge, step_factor


def member_losses(
    net: LowRankEnsemble, z: torch.Tensor, t: torch.Tensor, loss: str, cfg: TrainConfig
) -> torch.Tensor:
    """Mean batch loss of every member (K,) for standardised inputs ``z`` and targets ``t`` (K, B, ·).

    ``"likelihood"``: ``g^2 / 2 - log det L`` with ``g = ||L (t - o)||`` and ``L = M^-1``,
    ``M = chol(Sigma)`` (the Gaussian negative log-likelihood in standardised units).
    ``"hinge"``: the paper's ``l(g - 1) + lam * (-log det(L^T L))``. The two differ from the
    objectives of :mod:`ipcverify.training._objectives` in original units only by constants.

    Parameters
    ----------
    net : LowRankEnsemble
        The ensemble.
    z, t : Tensor (K, B, ·)
        Standardised inputs and targets, a batch per member.
    loss : {"likelihood", "hinge"}
        The objective.
    cfg : TrainConfig
        Its settings.
    """
    offset, log_diag, factor = net.heads(z)
    chol, info = torch.linalg.cholesky_ex(member_covariances(log_diag, factor))
    resid = torch.linalg.solve_triangular(chol, (t - offset).unsqueeze(-1), upper=False).squeeze(-1)
    g2 = (resid * resid).sum(-1)
    logdet_l = -torch.log(torch.diagonal(chol, dim1=-2, dim2=-1)).sum(-1)
    if bool((info > 0).any()):
        g2 = torch.where(info > 0, torch.full_like(g2, math.nan), g2)
    if loss == "likelihood":
        return (0.5 * g2 - logdet_l).mean(-1)
    g = torch.sqrt(g2 + 1e-12)
    return hinge(g - 1.0, cfg.alpha).mean(-1) + cfg.lam * (-2.0 * logdet_l).mean(-1)


def _splits(n: int, members: int, val_fraction: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Per member: fit rows (K, n - v) and validation rows (K, v)."""
    n_val = int(round(val_fraction * n)) if val_fraction > 0 else 0
    if val_fraction > 0 and not 1 <= n_val < n:
        raise InvalidInputError(
            f"too few samples ({n}) to hold out a validation split of {val_fraction:g}: pass "
            f"{option('val_fraction', 0)} (and no {option('patience')}) or give more data"
        )
    rng = np.random.default_rng(seed)
    perms = np.stack([rng.permutation(n) for _ in range(members)])
    return perms[:, n_val:], perms[:, :n_val]


def train_lowrank(
    train_data: PerceptionDataset, mc: ModelConfig, tc: TrainConfig, progress: bool = False
) -> tuple[LowRankEnsemble, list[dict[str, float]]]:
    """Train the ensemble of ``mc`` on ``train_data`` with the settings ``tc`` (see the module).

    Returns the trained network (eval mode) and one record per epoch: ``epoch``,
    ``train_loss`` and ``val_loss`` (means over the members still training),
    ``active_members``.

    Parameters
    ----------
    train_data : PerceptionDataset
        The training data.
    mc : ModelConfig
        The ensemble's configuration.
    tc : TrainConfig
        The training settings.
    progress : bool
        Show a progress bar.

    Examples
    --------
    >>> from ipcverify import example
    >>> net, hist = train_lowrank(example(300, seed=0).data, ModelConfig(x_dim=6, y_dim=3),
    ...                           TrainConfig(epochs=2))
    >>> net.members, len(hist)
    (5, 2)
    """
    if tc.center_warm_start or tc.start_at_estimate:
        raise InvalidInputError(
            "center_warm_start and start_at_estimate are for the paper's heads; the low-rank head has the "
            "closed-form linear centre stage (ModelConfig.linear_center) instead"
        )
    net = LowRankEnsemble(mc)
    z64, t64 = net.fit_normalisation(train_data.x, train_data.y, train_data.yhat, tc.linear_ridge)
    net.initialise(tc.seed)
    k = mc.members
    fit_rows, val_rows = _splits(len(z64), k, tc.val_fraction, tc.seed)
    z = torch.as_tensor(z64, dtype=torch.float32)
    t = torch.as_tensor(t64, dtype=torch.float32)
    zf, tf = z[torch.as_tensor(fit_rows)], t[torch.as_tensor(fit_rows)]  # (K, n_fit, ·)
    zv, tv = z[torch.as_tensor(val_rows)], t[torch.as_tensor(val_rows)]
    n_fit = fit_rows.shape[1]
    member = torch.arange(k)[:, None]

    params = dict(net.named_parameters())
    opt = torch.optim.Adam(params.values(), lr=tc.lr)
    total_steps = tc.epochs * math.ceil(n_fit / tc.batch_size)
    sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda s: step_factor(s, total_steps, tc.schedule))
    gens = [torch.Generator().manual_seed(1000 * tc.seed + j + 500) for j in range(k)]
    validate = val_rows.shape[1] > 0
    active = torch.ones(k, dtype=torch.bool)
    best_val = torch.full((k,), math.inf, dtype=torch.float64)
    best_epoch = torch.zeros(k, dtype=torch.long)
    best = {name: p.detach().clone() for name, p in params.items()}
    history: list[dict[str, float]] = []

    def freeze(j: int) -> None:
        """Member j back to its best weights, with Adam moments zeroed: later steps leave it there."""
        with torch.no_grad():
            for name, p in params.items():
                p[j] = best[name][j]
                state = opt.state.get(p, {})
                for key in ("exp_avg", "exp_avg_sq"):
                    if key in state:
                        state[key][j] = 0.0
        active[j] = False

    with epoch_bar(tc.epochs, progress) as (bar, task):
        for epoch in range(tc.epochs):
            loss_name = "likelihood" if epoch < tc.warmup_epochs else tc.loss
            if epoch == tc.warmup_epochs and epoch > 0:
                best_val[:] = math.inf  # a new objective: its losses are not comparable with the old one's
            net.train()
            perms = torch.stack([torch.randperm(n_fit, generator=g) for g in gens])
            total = torch.zeros(k, dtype=torch.float64)
            mask = active.to(torch.float32)
            for i in range(0, n_fit, tc.batch_size):
                idx = perms[:, i : i + tc.batch_size]
                losses = member_losses(net, zf[member, idx], tf[member, idx], loss_name, tc)
                if not bool(torch.isfinite(losses[active]).all()):
                    raise NonFiniteLossError(
                        f"non-finite training loss at epoch {epoch + 1} (low-rank head); lower the learning "
                        f"rate ({option('lr')}) or check the data for extreme values"
                    )
                loss = (torch.nan_to_num(losses) * mask).sum()
                opt.zero_grad(set_to_none=True)
                loss.backward()
                opt.step()
                sched.step()
                total += losses.detach().double() * idx.shape[1]
            net.eval()
            rec = {"epoch": float(epoch + 1), "train_loss": float((total / n_fit)[active].mean())}
            if validate:
                with torch.no_grad():
                    vloss = member_losses(net, zv, tv, loss_name, tc).double()
                rec["val_loss"] = float(vloss[active].mean())
                for j in range(k):
                    if not active[j]:
                        continue
                    if vloss[j] < best_val[j]:
                        best_val[j], best_epoch[j] = vloss[j], epoch
                        with torch.no_grad():
                            for name, p in params.items():
                                best[name][j] = p[j]
                    elif tc.patience is not None and epoch - int(best_epoch[j]) >= tc.patience:
                        freeze(j)
            rec["active_members"] = float(active.sum())
            history.append(rec)
            bar.update(task, advance=1, loss=rec["train_loss"])
            if not bool(active.any()):
                break
    if validate:  # every member at its best epoch (a frozen one may have drifted on NaN gradients)
        with torch.no_grad():
            for name, p in params.items():
                p.copy_(best[name])
    net.eval()
    return net, history
