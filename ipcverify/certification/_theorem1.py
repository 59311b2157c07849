"""The paper's Theorem 1, computed honestly.

For a training set of ``N`` i.i.d. samples, with probability at least
``1 - delta``::

    P(g_theta_hat(X) > 1) <= (1/N) sum_i min(1, l(g(X_i) - 1))      (empirical truncated hinge)
                             + (12 / alpha) * L_g * sqrt(p / N)      (complexity)
                             + sqrt(ln(2 / delta) / (2 N))           (confidence)

with ``l(t) = max(0, t / alpha + 1)``, ``p`` the number of parameters and ``L_g``
the Lipschitz constant of ``g`` in ``theta`` (paper, Section "Probabilistic
correctness"; the paper's ``epsilon`` is solved from ``2 exp(-2 N epsilon^2) = delta``).

The hinge margin ``alpha`` is the one recorded at training (``TrainConfig.alpha``). The
theorem holds for any ``alpha > 0`` fixed before the data are seen, whatever objective
chose ``theta_hat``: ``1{g > 1} <= min(1, l(g - 1))`` for every ``alpha > 0``, and the
bound is uniform over the parameter set. The default recipe trains by likelihood and does
not use ``alpha``; its recorded value is the fixed default 1.0.

It is evaluated with both Lipschitz values of :mod:`ipcverify.certification._lipschitz` (for either network
kind: the paper's heads or the default low-rank ensemble). Only the
sound (upper) ``L_g`` can give a valid bound; the empirical one gives an optimistic
number that proves nothing. A bound above 1 says nothing about a probability and is
flagged vacuous, with the training-set size ``N`` that would bring it below 1 (the
empirical term held fixed), or ``None`` if the empirical term alone is at least 1.
Details and caveats: ``proofs/theorem1.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ipcverify._wording._spelling import option
from ipcverify.contract._model import IPCModel
from ipcverify.data._dataset import PerceptionDataset
from ipcverify.errors import InvalidInputError
from ipcverify.network._lipschitz_ball import DEFAULT_RADIUS, DataBox


@dataclass(frozen=True, kw_only=True)
class TrainingStatistics:
    """What Theorem 1 needs from the training data, stored in the model file at training time.

    With them ``ipcverify certify model.pt`` evaluates Theorem 1 without the training file.

    Attributes
    ----------
    n : int
        Training samples ``N``.
    alpha : float
        Hinge margin of the empirical term.
    truncated_hinge_mean : float
        The empirical term at the trained weights.
    empirical_lipschitz : float
        Largest per-sample gradient norm at the trained weights (a lower estimate of ``L_g``).
    box : DataBox
        Bounding box of the training ``(x, y, yhat)`` (for the sound ``L_g``).
    data_sha256 : str
        Content hash of the training data.
    """

    n: int
    alpha: float
    truncated_hinge_mean: float
    empirical_lipschitz: float
    box: DataBox
    data_sha256: str

    def __post_init__(self) -> None:
        if self.n < 1 or not (0.0 <= self.truncated_hinge_mean <= 1.0) or not self.empirical_lipschitz >= 0:
            raise InvalidInputError("training statistics: need n >= 1, a hinge mean in [0, 1], L_g >= 0")

    @classmethod
    def compute(cls, model: IPCModel, train_data: PerceptionDataset, alpha: float) -> TrainingStatistics:
        """Evaluate the statistics on the training data at the trained weights.

        Examples
        --------
        >>> from ipcverify import example
        >>> from ipcverify.training import train, TrainConfig
        >>> ds = example(200, seed=0).data
        >>> model = train(ds, train_config=TrainConfig.recipe("v1", epochs=1), recipe="v1").model
        >>> stats = TrainingStatistics.compute(model, ds, 1.0)
        >>> stats.n, TrainingStatistics.from_dict(stats.to_dict()).to_dict() == stats.to_dict()
        (200, True)
        """
        from ipcverify.certification._lipschitz import (
            empirical_lipschitz,  # torch: the records above need none of it
        )

        scores = model.raw_scores(train_data.x, train_data.y, train_data.yhat)
        return cls(
            n=len(train_data),
            alpha=float(alpha),
            truncated_hinge_mean=truncated_hinge_mean(scores, alpha),
            empirical_lipschitz=empirical_lipschitz(model, train_data).value,
            box=DataBox.from_dataset(train_data),
            data_sha256=train_data.content_hash(),
        )

    def to_dict(self) -> dict[str, Any]:
        """Plain data (stored in the model file's metadata)."""
        return {
            "n": self.n,
            "alpha": self.alpha,
            "truncated_hinge_mean": self.truncated_hinge_mean,
            "empirical_lipschitz": self.empirical_lipschitz,
            "box": self.box.to_dict(),
            "data_sha256": self.data_sha256,
        }

    @classmethod
    def from_dict(cls, data: Any) -> TrainingStatistics:
        """Inverse of :meth:`to_dict`."""
        b = data["box"]
        return cls(
            n=int(data["n"]),
            alpha=float(data["alpha"]),
            truncated_hinge_mean=float(data["truncated_hinge_mean"]),
            empirical_lipschitz=float(data["empirical_lipschitz"]),
            box=DataBox(b["x_lo"], b["x_hi"], b["y_lo"], b["y_hi"], b["yhat_lo"], b["yhat_hi"]),
            data_sha256=str(data["data_sha256"]),
        )


def truncated_hinge_mean(scores: ArrayLike, alpha: float) -> float:
    """``(1/N) sum min(1, max(0, (g_i - 1) / alpha + 1))``, the empirical term of Theorem 1.

    Parameters
    ----------
    scores : array_like, shape (N,)
        The scores ``g_i``.
    alpha : float
        The hinge width.

    Examples
    --------
    >>> round(truncated_hinge_mean([0.5, 0.95, 2.0], alpha=0.1), 12)  # (0 + 0.5 + 1) / 3
    0.5
    """
    if not (math.isfinite(alpha) and alpha > 0):
        raise InvalidInputError(f"alpha must be > 0; got {alpha!r}")
    g = np.asarray(scores, dtype=np.float64)
    if g.size == 0:
        raise InvalidInputError("no training scores: Theorem 1 needs N >= 1 samples")
    return float(np.mean(np.clip((g - 1.0) / alpha + 1.0, 0.0, 1.0)))


def n_needed(empirical: float, complexity_coefficient: float, confidence_coefficient: float) -> int | None:
    """Smallest ``N`` with ``empirical + (a + b) / sqrt(N) < 1``, or ``None`` if there is none.

    ``a`` is the complexity coefficient ``(12 / alpha) L_g sqrt(p)``, ``b`` the
    confidence coefficient ``sqrt(ln(2 / delta) / 2)``.

    Parameters
    ----------
    empirical : float
        The empirical term.
    complexity_coefficient, confidence_coefficient : float
        ``a`` and ``b``.

    Examples
    --------
    >>> n_needed(0.0, 1.0, 1.0)  # 2 / sqrt(N) < 1  <=>  N > 4
    5
    >>> n_needed(1.0, 1.0, 1.0) is None
    True
    """
    if empirical >= 1.0:
        return None
    c = (complexity_coefficient + confidence_coefficient) / (1.0 - empirical)
    if not math.isfinite(c * c):
        return None
    if c * c > 2.0**50:  # beyond float resolution of N: round up generously (informational number)
        return int(math.ceil(c * c * (1.0 + 1e-9))) + 1
    n = int(math.floor(c * c)) + 1
    while n > 1 and empirical + c * (1.0 - empirical) / math.sqrt(n - 1) < 1.0:
        n -= 1  # guard against float rounding in floor(c^2)
    while empirical + c * (1.0 - empirical) / math.sqrt(n) >= 1.0:
        n += 1
    return n


@dataclass(frozen=True, kw_only=True)
class Theorem1Bound:
    """Theorem 1 evaluated with one value of ``L_g``.

    Attributes
    ----------
    lipschitz : float
        The Lipschitz constant ``L_g`` of the score in ``theta`` that the bound was evaluated
        with: the sound upper bound (``valid``) or the empirical lower estimate.
    complexity : float
        ``(12 / alpha) L_g sqrt(p / N)``.
    bound : float
        Empirical + complexity + confidence term.
    vacuous : bool
        ``bound >= 1`` (no information about a probability).
    n_needed : int or None
        Training-set size that would make the bound < 1 with the same empirical
        term; ``None`` if no ``N`` does.
    valid : bool
        Whether this ``L_g`` is an upper bound (only then is the theorem applicable).
    """

    lipschitz: float
    complexity: float
    bound: float
    vacuous: bool
    n_needed: int | None
    valid: bool

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form."""
        return {
            "lipschitz": self.lipschitz,
            "complexity_term": self.complexity,
            "bound": self.bound,
            "vacuous": self.vacuous,
            "n_needed": self.n_needed,
            "valid": self.valid,
        }


def theorem1_terms(
    empirical: float,
    lipschitz: float,
    n_parameters: int,
    n_train: int,
    alpha: float,
    delta: float,
    valid: bool,
) -> Theorem1Bound:
    """Evaluate the right-hand side of Theorem 1 for given ingredients.

    Parameters
    ----------
    empirical : float
        The empirical truncated hinge mean.
    lipschitz : float
        The Lipschitz constant ``L_g``.
    n_parameters, n_train : int
        ``p`` and ``N``.
    alpha, delta : float
        The hinge width and the confidence parameter.
    valid : bool
        Whether ``lipschitz`` is a sound upper bound (else the bound proves nothing).

    Examples
    --------
    >>> t = theorem1_terms(0.01, 16.0, 10_900, 5000, alpha=0.1, delta=0.05, valid=False)
    >>> round(t.complexity, 1), t.vacuous
    (2834.8, True)
    """
    if n_train < 1 or n_parameters < 1:
        raise InvalidInputError("Theorem 1 needs N >= 1 samples and p >= 1 parameters")
    if not (0 < delta < 1):
        raise InvalidInputError(f"delta must lie strictly between 0 and 1; got {delta!r}")
    if not (math.isfinite(lipschitz) and lipschitz >= 0):
        raise InvalidInputError(f"L_g must be finite and >= 0; got {lipschitz!r}")
    a = 12.0 / alpha * lipschitz * math.sqrt(n_parameters)
    b = math.sqrt(math.log(2.0 / delta) / 2.0)
    complexity = a / math.sqrt(n_train)
    bound = empirical + complexity + b / math.sqrt(n_train)
    return Theorem1Bound(
        lipschitz=float(lipschitz),
        complexity=complexity,
        bound=bound,
        vacuous=bound >= 1.0,
        n_needed=n_needed(empirical, a, b),
        valid=valid,
    )


@dataclass(frozen=True, kw_only=True)
class Theorem1Result:
    """Theorem 1 for a trained model on its training data, with both ``L_g``.

    Attributes
    ----------
    n_train, n_parameters : int
        ``N`` and ``p``.
    alpha, delta : float
        Hinge margin (from training) and confidence parameter.
    empirical_term, confidence_term : float
        Truncated hinge mean and ``sqrt(ln(2/delta) / (2N))``.
    sound : Theorem1Bound
        With the sound (upper-bound) ``L_g`` over ``B(theta_hat, radius)`` and the
        training data's box: the only applicable version.
    optimistic : Theorem1Bound
        With the empirical (lower-estimate) ``L_g``: not a guarantee.
    radius : float
        Parameter-ball radius of the sound ``L_g``.
    """

    n_train: int
    n_parameters: int
    alpha: float
    delta: float
    empirical_term: float
    confidence_term: float
    sound: Theorem1Bound
    optimistic: Theorem1Bound
    radius: float

    @property
    def usable(self) -> bool:
        """True only if the sound bound is below 1."""
        return not self.sound.vacuous

    def explanation(self) -> str:
        """Plain-language verdict on the bound."""
        if self.usable:
            return (
                f"Theorem 1 with the sound L_g gives {self.sound.bound:.4g} < 1 (confidence "
                f"{1 - self.delta:.6g}), valid only under the assumptions of proofs/theorem1.md: the data's "
                f"support lies in the training data's box, and the parameter ball of radius {self.radius:g} "
                "around the trained weights is taken as the hypothesis class. It is not a certificate."
            )
        why = (
            f"the complexity term (12/alpha) L_g sqrt(p/N) alone is {self.sound.complexity:.3g} with the "
            f"sound L_g = {self.sound.lipschitz:.3g} and {self.optimistic.complexity:.3g} even with the "
            f"empirical L_g = {self.optimistic.lipschitz:.3g} (p = {self.n_parameters}, N = {self.n_train})"
        )
        need = self.sound.n_needed
        more = (
            "no training-set size would fix it (the empirical term alone is >= 1)"
            if need is None
            else f"it would need N >= {need:.3g} training samples to drop below 1"
        )
        return (
            f"Theorem 1 is vacuous (bound {self.sound.bound:.3g} >= 1, so it says nothing): {why}; "
            f"{more}. Use the calibration certificate instead."
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form; ``bound``/``vacuous``/``n_needed`` refer to the sound ``L_g``."""
        return {
            "computed": True,
            "bound": self.sound.bound,
            "vacuous": self.sound.vacuous,
            "n_needed": self.sound.n_needed,
            "lipschitz_empirical": self.optimistic.lipschitz,
            "lipschitz_sound": self.sound.lipschitz,
            "lipschitz_radius": self.radius,
            "n_train": self.n_train,
            "n_parameters": self.n_parameters,
            "alpha": self.alpha,
            "delta": self.delta,
            "empirical_term": self.empirical_term,
            "confidence_term": self.confidence_term,
            "complexity_term_sound": self.sound.complexity,
            "complexity_term_empirical": self.optimistic.complexity,
            "bound_with_empirical_lipschitz": self.optimistic.bound,
            "vacuous_with_empirical_lipschitz": self.optimistic.vacuous,
            "n_needed_with_empirical_lipschitz": self.optimistic.n_needed,
            "guarantee": self.usable,  # non-vacuous with the sound L_g (see "note" for its assumptions)
            "note": (
                "Only the sound L_g (an upper bound over the parameter ball and the training data's "
                "box) can make Theorem 1 valid; the empirical L_g is a lower estimate and its bound is "
                "optimistic, not a guarantee. A bound >= 1 is vacuous. Even a sound bound < 1 rests on the "
                "assumptions listed in proofs/theorem1.md (support inside the box, the parameter ball as "
                "the hypothesis class)."
            ),
            "explanation": self.explanation(),
        }


def theorem1(
    model: IPCModel,
    train_data: PerceptionDataset | TrainingStatistics,
    delta: float,
    *,
    alpha: float | None = None,
    radius: float = DEFAULT_RADIUS,
) -> Theorem1Result:
    """Evaluate Theorem 1 for ``model`` on its training data (or its stored statistics).

    Parameters
    ----------
    model : IPCModel
        The trained model (``g`` is the raw score; calibration plays no role).
    train_data : PerceptionDataset or TrainingStatistics
        The training set ``S`` (``N = len(train_data)``), or the statistics of it that
        :func:`ipcverify.training.train` stored in the model file.
    delta : float
        Confidence parameter, ``0 < delta < 1``.
    alpha : float, optional
        Hinge margin; default: the ``alpha`` recorded at training (for the default recipe,
        which trains by likelihood, its fixed default 1.0; any ``alpha > 0`` fixed before
        seeing the data is valid, see ``proofs/theorem1.md``).
    radius : float
        Parameter-ball radius of the sound Lipschitz bound.

    Examples
    --------
    >>> from ipcverify import example
    >>> from ipcverify.training import train, TrainConfig
    >>> ds = example(300, seed=0).data
    >>> model = train(ds, train_config=TrainConfig.recipe("v1", epochs=1), recipe="v1").model
    >>> res = theorem1(model, ds, delta=0.01)
    >>> res.sound.vacuous, res.sound.lipschitz >= res.optimistic.lipschitz
    (True, True)
    >>> default = train(ds, train_config=TrainConfig(epochs=1)).model  # the low-rank ensemble
    >>> res = theorem1(default, ds, delta=0.01)
    >>> res.alpha, res.n_parameters, res.sound.vacuous, res.sound.lipschitz >= res.optimistic.lipschitz
    (1.0, 29475, True, True)
    """
    if alpha is None:
        alpha = (model.metadata.get("train_config") or {}).get("alpha")
        if alpha is None:
            raise InvalidInputError("the model file records no training alpha; pass alpha explicitly")
    from ipcverify.certification._lipschitz import (
        sound_lipschitz,  # torch (the sound bound differentiates the network)
    )

    alpha = float(alpha)
    if isinstance(train_data, PerceptionDataset):
        if (train_data.x_dim, train_data.y_dim) != (model.config.x_dim, model.config.y_dim):
            raise InvalidInputError(
                f"{train_data.source}: training data has x_dim={train_data.x_dim}, y_dim={train_data.y_dim} "
                f"but the model expects x_dim={model.config.x_dim}, y_dim={model.config.y_dim}"
            )
        stats = TrainingStatistics.compute(model, train_data, alpha)
    else:
        stats = train_data
        if stats.alpha != alpha:
            raise InvalidInputError(
                f"the stored training statistics use alpha={stats.alpha:g}, not {alpha:g}; pass the training "
                f"data ({option('train_data')}) to evaluate Theorem 1 at another alpha"
            )
    emp, n, p = stats.truncated_hinge_mean, stats.n, model.n_parameters
    high = sound_lipschitz(model, stats.box, radius=radius)
    return Theorem1Result(
        n_train=n,
        n_parameters=p,
        alpha=alpha,
        delta=float(delta),
        empirical_term=emp,
        confidence_term=math.sqrt(math.log(2.0 / delta) / (2.0 * n)),
        sound=theorem1_terms(emp, high.value, p, n, alpha, delta, valid=True),
        optimistic=theorem1_terms(emp, stats.empirical_lipschitz, p, n, alpha, delta, valid=False),
        radius=float(radius),
    )
