"""Training an IPC: :func:`train`, by a recipe (default ``"tight"``) or explicit configurations.

The objectives and :class:`TrainConfig` live in :mod:`ipcverify.training._objectives` (re-exported
here). A low-rank network (the default) is trained by :mod:`ipcverify.training._lowrank`,
all ensemble members at once; the paper's heads (recipes ``"v1"``, ``"paper"``) by the loop
below, one network.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from rich.progress import Progress

from ipcverify._wording._spelling import option, options
from ipcverify.certification._theorem1 import TrainingStatistics
from ipcverify.contract._model import IPCModel
from ipcverify.data._checks import check_informative, input_ranges
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.data._fingerprints import row_fingerprints, with_recorded_rows
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import DEFAULT_RECIPE, ModelConfig
from ipcverify.network._modules import IPCNetwork, Network
from ipcverify.training._lowrank import train_lowrank
from ipcverify.training._objectives import (
    NonFiniteLossError,
    TrainConfig,
    epoch_bar,
    objective,
    step_factor,
)
from ipcverify.training._selection import Candidate, HingeSelection, SelectionRecord
from ipcverify.training._threads import torch_threads

#: Recipes whose unstated hinge settings are chosen by :class:`HingeSelection` when no
#: training configuration is given.
_SELECTED_RECIPES = ("paper",)


@dataclass(frozen=True)
class TrainResult:
    """A trained model and the per-epoch history (``loss``, ``hinge``, ``logdet``, ...).

    Attributes
    ----------
    model : IPCModel
        The trained (uncalibrated) model.
    history : list of dict
        One record per epoch.
    """

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
    if (tc.center_warm_start or tc.start_at_estimate) and not trainer_for(mc).warm_start:
        raise InvalidInputError("center_warm_start and start_at_estimate are for the paper's heads")
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
    if tc.start_at_estimate:
        net.start_at_estimate()
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
                        f"(param={mc.param!r}); use {option('param', 'cholesky')}, whose log det is always "
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


def _candidate(fit: PerceptionDataset, val: PerceptionDataset, mc: ModelConfig, tc: TrainConfig) -> Candidate:
    """Train one candidate on ``fit`` and measure it on ``val`` (raw miss rate, mean log-volume)."""
    try:
        model = IPCModel(_train_network(fit, mc, tc, False)[0])
        centers, shapes = model.raw_arrays(val.x, val.yhat)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            logdet = np.linalg.slogdet(shapes)[1]
            g = np.linalg.norm(np.einsum("bij,bj->bi", shapes, val.y - centers), axis=1)
        misses = int(np.sum(~(g <= 1.0)))  # a non-finite score is a miss
        volume = float(np.mean(-logdet)) if np.isfinite(logdet).all() else math.inf
    except NonFiniteLossError:
        misses, volume = len(val), math.inf
    return Candidate(alpha=tc.alpha, lam=tc.lam, batch_size=tc.batch_size, val_n=len(val),
                     val_misses=misses, val_log_volume=volume)  # fmt: skip


def select_hinge(
    train_data: PerceptionDataset,
    model_config: ModelConfig,
    train_config: TrainConfig,
    rule: HingeSelection,
    progress: bool = False,
    *,
    threads: int | None = None,
) -> tuple[TrainConfig, SelectionRecord]:
    """Choose ``alpha``, ``lam`` and the batch size by ``rule`` on held-out training rows.

    See :mod:`ipcverify.training._selection`. Only ``train_data`` is used: a share of it is held out
    (seeded by ``train_config.seed``; whole groups with ``rule.group_column``), each candidate
    of the grid is trained on the rest
    with ``train_config``'s other settings, and the rule picks one.

    Parameters
    ----------
    train_data : PerceptionDataset
        The training data.
    model_config : ModelConfig
        The network to train.
    train_config : TrainConfig
        The training settings the candidates vary.
    rule : HingeSelection
        The grid and the rule.
    progress : bool
        Show a progress bar.
    threads : int, optional
        torch threads for the candidates' training, as in :func:`train`.

    Returns
    -------
    TrainConfig
        ``train_config`` with the chosen ``alpha``, ``lam`` and ``batch_size``.
    SelectionRecord
        Every candidate's held-out miss rate and log-volume, and the choice.

    Examples
    --------
    >>> from ipcverify import example
    >>> ds = example(300, seed=0).data
    >>> mc = ModelConfig.recipe("paper", x_dim=6, y_dim=3, hidden=(8, 8))
    >>> tc, rec = select_hinge(ds, mc, TrainConfig.recipe("paper", epochs=1),
    ...                        HingeSelection(alphas=(0.1, 1.0), lams=(0.01,)))
    >>> len(rec.candidates), tc.alpha == rec.chosen.alpha
    (2, True)
    """
    with torch_threads(threads):
        return _select_hinge(train_data, model_config, train_config, rule, progress)


def _select_hinge(
    train_data: PerceptionDataset,
    model_config: ModelConfig,
    train_config: TrainConfig,
    rule: HingeSelection,
    progress: bool,
) -> tuple[TrainConfig, SelectionRecord]:
    """:func:`select_hinge` on the torch threads the caller set."""
    if not trainer_for(model_config).hinge_selection:
        raise InvalidInputError("the hinge selection is for the paper's heads (recipes 'paper', 'v1')")
    parts = train_data.split(
        (1 - rule.val_fraction, 0.0, rule.val_fraction),
        seed=train_config.seed,
        group_column=rule.group_column,
    )
    if parts.train is None or parts.test is None:
        raise InvalidInputError(
            f"too few training rows ({len(train_data)}) to hold out {rule.val_fraction:g} of them for the "
            f"hinge selection; give more data, or set {options('alpha', 'lam', 'batch_size')} yourself"
        )
    started = time.perf_counter()
    candidates = []
    grid = rule.grid()
    with Progress(disable=not progress, transient=True) as bar:
        task = bar.add_task("choosing alpha, lambda, batch size", total=len(grid))
        for alpha, lam, batch in grid:
            cfg = dataclasses.replace(train_config, alpha=alpha, lam=lam, batch_size=batch)
            candidates.append(_candidate(parts.train, parts.test, model_config, cfg))
            bar.advance(task)
    record = dataclasses.replace(rule.choose(candidates), seconds=time.perf_counter() - started)
    best = record.chosen
    return dataclasses.replace(
        train_config, alpha=best.alpha, lam=best.lam, batch_size=best.batch_size
    ), record


@dataclass(frozen=True)
class Trainer:
    """How one network kind is trained (an entry of the registry :func:`trainer_for` reads).

    Attributes
    ----------
    fit : callable
        ``fit(train_data, model_config, train_config, progress) -> (network, history)``.
    hinge_selection : bool
        Whether :class:`HingeSelection` applies (the hinge objective's settings).
    warm_start : bool
        Whether ``center_warm_start`` and ``start_at_estimate`` apply.
    """

    fit: Callable[[PerceptionDataset, ModelConfig, TrainConfig, bool], tuple[Network, list[dict[str, float]]]]
    hinge_selection: bool
    warm_start: bool


def trainer_for(config: ModelConfig) -> Trainer:
    """The trainer of ``config``'s network kind (:attr:`ModelConfig.kind`): the training package's one choice.

    Examples
    --------
    >>> trainer_for(ModelConfig(x_dim=1, y_dim=1)).hinge_selection
    False
    """
    return _TRAINERS[config.kind]


def train(
    train_data: PerceptionDataset,
    model_config: ModelConfig | None = None,
    train_config: TrainConfig | None = None,
    progress: bool = False,
    *,
    recipe: str = DEFAULT_RECIPE,
    select: HingeSelection | None = None,
    threads: int | None = None,
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
        Where the configurations not given come from (``ipcverify.network.RECIPES``).
        A configuration that is given is used as it is.
    select : HingeSelection, optional
        Choose ``alpha``, ``lam`` and the batch size by this rule on held-out training rows
        (:func:`select_hinge`), then train on all of ``train_data`` with them; the record is
        stored as ``metadata["selection"]``. Default: :class:`HingeSelection()` for the recipe
        ``"paper"`` when no ``train_config`` is given (the paper states none of the three),
        none otherwise.
    threads : int, optional
        torch threads to train on (the previous setting is restored afterwards). Default: the
        user's ``OMP_NUM_THREADS`` if set, else 1 -- these networks are too small to gain
        from more, and beside other busy processes more threads are several times slower
        (:mod:`ipcverify.training._threads`). The model does not depend on it.

    Returns
    -------
    TrainResult
        The model (uncalibrated) and the per-epoch history. The model's metadata holds the
        :class:`~ipcverify.certification.TrainingStatistics` of ``train_data`` (for every recipe),
        so that Theorem 1 can be evaluated from the model file alone.

    Raises
    ------
    NonFiniteLossError
        If the loss becomes NaN or infinite (possible with ``param="full"``, whose
        ``log det`` is ``-inf`` at a singular ``C``); switch to ``cholesky``.
    InvalidInputError
        For an unknown recipe, a configuration that does not fit the data, or ``threads``
        not an integer >= 1.

    Examples
    --------
    >>> from ipcverify import example
    >>> ds = example(200, seed=0).data
    >>> res = train(ds, train_config=TrainConfig(epochs=2))
    >>> len(res.history), res.model.config.members
    (2, 5)
    >>> train(ds, recipe="paper").model.config.param
    'full'
    """
    check_informative(train_data, "training")
    with torch_threads(threads):
        return _train(train_data, model_config, train_config, progress, recipe, select)


def _train(
    train_data: PerceptionDataset,
    model_config: ModelConfig | None,
    train_config: TrainConfig | None,
    progress: bool,
    recipe: str,
    select: HingeSelection | None,
) -> TrainResult:
    """:func:`train` on the torch threads the caller set."""
    tc = train_config or TrainConfig.recipe(recipe)
    mc = model_config or ModelConfig.recipe(recipe, x_dim=train_data.x_dim, y_dim=train_data.y_dim)
    if (mc.x_dim, mc.y_dim) != (train_data.x_dim, train_data.y_dim):
        raise InvalidInputError(
            f"model expects x_dim={mc.x_dim}, y_dim={mc.y_dim} but the data has "
            f"x_dim={train_data.x_dim}, y_dim={train_data.y_dim}"
        )
    if select is None and train_config is None and recipe in _SELECTED_RECIPES:
        select = HingeSelection()
    record = None
    if select is not None:
        tc, record = _select_hinge(train_data, mc, tc, select, progress)
    net, history = trainer_for(mc).fit(train_data, mc, tc, progress)
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
    if record is not None:
        metadata["selection"] = record.to_dict()
    # every training row's fingerprint: calibrate and certify refuse rows that are training rows
    metadata = with_recorded_rows(metadata, "training", row_fingerprints(train_data))
    return TrainResult(IPCModel(net, None, metadata), history)


#: One trainer per network kind (:attr:`ModelConfig.kind`): the paper's heads by the loop above,
#: the low-rank ensemble by :mod:`ipcverify.training._lowrank` (all members at once).
_TRAINERS: dict[str, Trainer] = {
    "mlp": Trainer(_train_network, hinge_selection=True, warm_start=True),
    "lowrank": Trainer(train_lowrank, hinge_selection=False, warm_start=False),
}
