"""What training optimises, and how: :class:`TrainConfig` and the two objectives.

The paper's loss (``loss="hinge"``) on a batch is
``mean(l(g - 1)) + lam * mean(-log det(C^T C))`` with the hinge
``l(t) = max(0, t / alpha + 1)`` (paper, eq. for L_ERM and L_REG): the hinge pushes every
score ``g = ||C (y - c)||`` below ``1 - alpha``, the log-determinant term shrinks the
ellipsoids. ``loss="likelihood"`` (the default recipe's) is the Gaussian negative
log-likelihood of ``y`` under ``N(c, (C^T C)^{-1})`` up to constants,
``mean(g^2) / 2 - mean(log det C)``.

The defaults of :class:`TrainConfig` are the default recipe ``"tight"``;
:meth:`TrainConfig.recipe` gives the others (``"v1"``, ``"paper"``). Used by
:mod:`ipcverify.training._train` (one network) and :mod:`ipcverify.training._lowrank` (the
ensemble).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any, Literal

import torch
from rich.progress import BarColumn, Progress, TaskID, TextColumn, TimeRemainingColumn

from ipcverify._wording._spelling import option
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import RECIPES

#: Training objectives: the paper's hinge + volume loss, or Gaussian likelihood.
Loss = Literal["hinge", "likelihood"]
_LOSSES: tuple[str, ...] = ("hinge", "likelihood")
#: Step-size schedules: constant, or cosine decay to 0 over all the epochs' steps.
Schedule = Literal["constant", "cosine"]
_SCHEDULES: tuple[str, ...] = ("constant", "cosine")
#: The training part of each recipe (fields not named take the defaults, i.e. "tight").
_V1 = {
    "epochs": 20,
    "lr": 1e-3,
    "batch_size": 64,
    "alpha": 1.0,
    "lam": 0.01,
    "val_fraction": 0.0,
    "patience": None,
    "loss": "hinge",
    "schedule": "constant",
}
_RECIPE_TRAIN: dict[str, dict[str, Any]] = {
    "tight": {},
    "v1": _V1,
    "paper": {**_V1, "alpha": 0.1, "start_at_estimate": True},
}


class NonFiniteLossError(InvalidInputError):
    """Training produced a non-finite loss (possible with the ``full`` parameterisation)."""


@dataclass(frozen=True, kw_only=True)
class TrainConfig:
    """Optimisation settings.

    The defaults are the training part of the default recipe ``"tight"`` (likelihood, 60
    epochs at most with early stopping, cosine step decay); :meth:`recipe` gives the
    others by name (``"v1"``: the hinge with alpha = 1 for 20 epochs; ``"paper"``).

    Parameters
    ----------
    epochs : int
        Passes over the training data (default 60; the paper: 20).
    lr : float
        Adam learning rate (default 2e-3; the paper: 1e-3).
    batch_size : int
        Mini-batch size (default 128; the paper: 64).
    alpha : float
        Hinge margin ``alpha > 0`` (used by ``loss="hinge"``). Default 1.0 (the paper: 0.1):
        with ``alpha >= 1`` the hinge is active for every sample, so the loss is
        ``mean(g) / alpha`` plus the volume term and the shape is learned from all samples,
        not only from those near the
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
        Share of the training data held out for validation (0 disables it; default 0.15).
        Each member of an ensemble holds out its own random share.
    patience : int or None
        With validation, stop after this many epochs without improvement and
        restore the best weights (default 10; per member in an ensemble).
    loss : {"likelihood", "hinge"}
        Training objective. ``"likelihood"`` (default). ``"hinge"`` is the paper's
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
        not smaller (``docs/benchmarks.md``). Only for the paper's heads; the low-rank head
        has the closed-form linear centre stage instead (``ModelConfig.linear_center``).
    schedule : {"cosine", "constant"}
        Step size: decayed along a half cosine from ``lr`` to 0 over all steps of the
        ``epochs`` (default), or constant (the paper).
    linear_ridge : float
        Ridge weight (times ``N``) of the closed-form linear centre stage of the low-rank
        head (default 1e-8: essentially least squares; it only keeps the solve well posed).
    start_at_estimate : bool
        Initialise the network so that its centre output equals ``yhat`` before the first
        step (:meth:`ipcverify.network.IPCNetwork.start_at_estimate`; the paper's heads, ReLU
        only). On by default in the recipe ``"paper"``, whose centre is predicted outright:
        the paper does not state its initialisation, and from PyTorch's default one its
        network learns the centre on the case study's data only to 9-19 cm in 20 epochs
        (``docs/reproduce.md``).

    Raises
    ------
    InvalidInputError
        If a value is out of range or ``loss`` is unknown.

    Examples
    --------
    >>> TrainConfig(epochs=5).lr
    0.002
    >>> TrainConfig.recipe("v1", seed=3).loss, TrainConfig.recipe("paper").alpha
    ('hinge', 0.1)
    """

    epochs: int = 60
    lr: float = 2e-3
    batch_size: int = 128
    alpha: float = 1.0
    lam: float = 0.01
    seed: int = 0
    val_fraction: float = 0.15
    patience: int | None = 10
    loss: Loss = "likelihood"
    warmup_epochs: int = 0
    center_warm_start: bool = False
    schedule: Schedule = "cosine"
    linear_ridge: float = 1e-8
    start_at_estimate: bool = False

    def __post_init__(self) -> None:
        if self.loss not in _LOSSES:
            raise InvalidInputError(f"loss must be 'hinge' or 'likelihood'; got {self.loss!r}")
        if self.schedule not in _SCHEDULES:
            raise InvalidInputError(f"schedule must be 'cosine' or 'constant'; got {self.schedule!r}")
        if not (self.linear_ridge >= 0 and math.isfinite(self.linear_ridge)):
            raise InvalidInputError(f"linear_ridge must be >= 0; got {self.linear_ridge}")
        if not isinstance(self.start_at_estimate, bool):
            raise InvalidInputError(
                f"start_at_estimate must be True or False; got {self.start_at_estimate!r}"
            )
        if not isinstance(self.center_warm_start, bool):
            raise InvalidInputError(
                f"center_warm_start must be True or False; got {self.center_warm_start!r}"
            )
        checks = [
            (self.epochs >= 1, f"{option('epochs')} must be >= 1; got {self.epochs}"),
            (
                isinstance(self.seed, numbers.Integral) and 0 <= self.seed < 2**64,
                f"{option('seed')} must be an integer in [0, 2**64); got {self.seed!r}",
            ),
            (self.lr > 0 and math.isfinite(self.lr), f"{option('lr')} must be > 0; got {self.lr}"),
            (self.batch_size >= 1, f"{option('batch_size')} must be >= 1; got {self.batch_size}"),
            (
                self.alpha > 0 and math.isfinite(self.alpha),
                f"{option('alpha')} must be > 0; got {self.alpha}",
            ),
            (self.lam >= 0 and math.isfinite(self.lam), f"{option('lam')} must be >= 0; got {self.lam}"),
            (
                0 <= self.val_fraction < 1,
                f"{option('val_fraction')} must be in [0, 1); got {self.val_fraction}",
            ),
            (
                self.patience is None or self.patience >= 1,
                f"{option('patience')} must be >= 1; got {self.patience}",
            ),
            (
                self.patience is None or self.val_fraction > 0,
                f"{option('patience')} (early stopping) needs a validation split: set "
                f"{option('val_fraction')} "
                f"above 0, or leave {option('patience')} out",
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

    @classmethod
    def recipe(cls, name: str, **overrides: Any) -> TrainConfig:
        """The training settings of the recipe ``name`` (see ``architecture.RECIPES``), with ``overrides``."""
        if name not in _RECIPE_TRAIN:
            raise InvalidInputError(f"unknown recipe {name!r}; choose one of {', '.join(RECIPES)}")
        return cls(**{**_RECIPE_TRAIN[name], **overrides})

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (stored in model files)."""
        return asdict(self)


def step_factor(step: int, total_steps: int, schedule: str) -> float:
    """Multiplier of the learning rate at optimiser step ``step`` of ``total_steps``.

    Parameters
    ----------
    step, total_steps : int
        The optimiser step and the number of steps.
    schedule : {"constant", "cosine"}
        The schedule.

    Examples
    --------
    >>> [round(step_factor(k, 4, "cosine"), 3) for k in range(5)]
    [1.0, 0.854, 0.5, 0.146, 0.0]
    >>> step_factor(3, 4, "constant")
    1.0
    """
    if schedule == "constant" or total_steps <= 0:
        return 1.0
    return 0.5 * (1.0 + math.cos(math.pi * min(step, total_steps) / total_steps))


def hinge(t: torch.Tensor, alpha: float) -> torch.Tensor:
    """The paper's hinge ``l(t) = max(0, t / alpha + 1)``.

    Parameters
    ----------
    t : Tensor
        The argument.
    alpha : float
        The hinge width.
    """
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
    alpha : float
        The hinge width.
    lam : float
        The weight of the volume term.

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


def objective(
    g: torch.Tensor, logdet: torch.Tensor, loss: str, cfg: TrainConfig
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """The objective ``loss`` (``"hinge"`` or ``"likelihood"``) with the settings of ``cfg``.

    Parameters
    ----------
    g, logdet
        As for :func:`ipc_loss`.
    loss : {"hinge", "likelihood"}
        The objective.
    cfg : TrainConfig
        Its settings (``alpha``, ``lam``).
    """
    if loss == "likelihood":
        return likelihood_loss(g, logdet)
    return ipc_loss(g, logdet, cfg.alpha, cfg.lam)


@contextmanager
def epoch_bar(epochs: int, enabled: bool) -> Iterator[tuple[Progress, TaskID]]:
    """A rich progress bar over the epochs (``bar.update(task, advance=1, loss=...)``), silent if disabled.

    Parameters
    ----------
    epochs : int
        Number of epochs.
    enabled : bool
        Show the bar.
    """
    bar = Progress(
        TextColumn("training"),
        BarColumn(),
        TextColumn("epoch {task.completed}/{task.total} loss {task.fields[loss]:.4f}"),
        TimeRemainingColumn(),
        disable=not enabled,
        transient=True,
    )
    with bar:
        yield bar, bar.add_task("train", total=epochs, loss=float("nan"))
