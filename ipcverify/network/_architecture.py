"""The architecture of an IPC network: :class:`ModelConfig` (plain data, no torch).

Shared by the torch network (:mod:`ipcverify.network._modules`), its float64 evaluation
(:mod:`ipcverify.network._engine`) and the ONNX export, so that none of them imports another
for its description.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass
from typing import Any, Literal

from ipcverify._wording._spelling import option
from ipcverify.errors import InvalidInputError

#: Bound on the log of the Cholesky diagonal (keeps exp finite in float32).
LOGDIAG_CLAMP = 12.0
#: Hidden-layer non-linearities.
ACTIVATIONS = ("relu", "tanh", "elu")
#: Largest ensemble accepted (members are evaluated together; more only costs time).
MAX_MEMBERS = 32
#: Largest network accepted, in weights of its hidden layers over all members (4e8 bytes in float32,
#: several times that while training): a typo such as ``--hidden 6400000`` is refused before torch
#: tries to allocate it.
MAX_HIDDEN_WEIGHTS = 10**8
Param = Literal["cholesky", "full", "lowrank"]
Center = Literal["offset", "raw"]
#: Training recipes by name, with what each one is (the model part is :meth:`ModelConfig.recipe`,
#: the training part :meth:`ipcverify.training._train.TrainConfig.recipe`).
RECIPES: dict[str, str] = {
    "tight": "the default: linear centre stage, low-rank-plus-diagonal covariance head, ensemble of 5, "
    "Gaussian likelihood, cosine step decay, early stopping on 15 % held out (docs/benchmarks.md)",
    "v1": "ipcverify's default before the tight recipe: offset centre, Cholesky head, one network "
    "(64, 128), the paper's hinge loss with alpha = 1, lambda = 0.01, 20 epochs",
    "paper": "the paper's head and loss: centre predicted outright, nine free shape entries, "
    "hinge alpha = 0.1, lambda = 0.01, 20 epochs, Adam 1e-3, batch 64",
}
#: The recipe of ``ModelConfig(...)`` / ``TrainConfig()`` and of ``ipcverify train``.
DEFAULT_RECIPE = "tight"
#: The architecture part of each recipe (fields not named take their defaults).
_RECIPE_MODEL: dict[str, dict[str, Any]] = {
    "tight": {"param": "lowrank"},
    "v1": {"param": "cholesky", "center": "offset"},
    "paper": {"param": "full", "center": "raw"},
}
#: Values of the keys added with the low-rank head, for configurations written before it.
_LEGACY = {"param": "cholesky", "center": "offset", "activation": "relu"}
_LOWRANK_KEYS = ("linear_center", "members")
#: Defaults that depend on the head: (low-rank, paper's heads).
_HIDDEN = {True: (64, 64), False: (64, 128)}
_MEMBERS = {True: 5, False: 1}


@dataclass(frozen=True, kw_only=True)
class ModelConfig:
    """Architecture of an IPC network.

    The defaults are the architecture of the default recipe ``"tight"``; :meth:`recipe`
    gives the others by name (``"v1"``, ``"paper"``).

    Parameters
    ----------
    x_dim, y_dim : int
        State dimension ``d`` and dimension ``n`` of the perceived quantity.
    hidden : tuple of int
        Hidden layer widths of each network; default (64, 64) with ``"lowrank"``, the
        paper's (64, 128) with the other heads.
    param : {"lowrank", "cholesky", "full"}
        Parameterisation of the shape. ``"lowrank"`` (default): the network gives a
        covariance ``diag(exp(2 h)) + V V^T`` (``V`` is ``n x n``, with a linear path from the
        inputs) whose Cholesky factor ``M`` gives ``C = M^-1 diag(1 / sigma)``
        (:mod:`ipcverify.network._lowrank`). ``"cholesky"``: ``C = L diag(1 / sigma)`` with ``L``
        lower-triangular, positive diagonal. ``"full"``: the paper's ``n^2`` free entries.
    center : {"offset", "raw"}
        Centre as ``yhat`` plus a learned offset, or predicted directly (``"raw"``, not with
        ``"lowrank"``).
    activation : {"relu", "tanh", "elu"}
        Hidden-layer non-linearity.
    linear_center : bool, optional
        With ``"lowrank"``: add an affine map of the standardised inputs to the centre,
        fitted in closed form before training (ridge least squares of ``y - yhat``) and then
        trained with the network. Default: True with ``"lowrank"``; must be False otherwise.
    members : int, optional
        With ``"lowrank"``: number of networks in the ensemble, combined by moment matching
        (mean centre; mean covariance plus the spread of the centres). Default: 5 with
        ``"lowrank"``; must be 1 otherwise.

    Raises
    ------
    InvalidInputError
        If a value is out of range or a low-rank option is given with another head.

    Examples
    --------
    >>> ModelConfig(x_dim=6, y_dim=3).n_outputs        # centre 3, log-diagonal 3, factor 9
    15
    >>> ModelConfig.recipe("v1", x_dim=6, y_dim=3).n_outputs
    9
    >>> ModelConfig.recipe("paper", x_dim=6, y_dim=3).param
    'full'
    >>> ModelConfig(x_dim=6, y_dim=3, param="cholesky").hidden   # the other heads keep the paper's net
    (64, 128)
    """

    x_dim: int
    y_dim: int
    hidden: tuple[int, ...] = ()
    param: Param = "lowrank"
    center: Center = "offset"
    activation: str = "relu"
    linear_center: bool | None = None
    members: int = 0

    def __post_init__(self) -> None:
        low = self.param == "lowrank"
        # () / None / 0 mean "the default for this head"
        hidden = tuple(self.hidden) if self.hidden is not None else ()
        object.__setattr__(self, "hidden", tuple(int(h) for h in (hidden or _HIDDEN[low])))
        if self.linear_center is None:
            object.__setattr__(self, "linear_center", low)
        if isinstance(self.members, int) and not isinstance(self.members, bool) and self.members == 0:
            object.__setattr__(self, "members", _MEMBERS[low])
        if self.x_dim < 0 or self.y_dim < 1:
            raise InvalidInputError(
                f"need x_dim >= 0 and y_dim >= 1; got x_dim={self.x_dim}, y_dim={self.y_dim}"
            )
        if not self.hidden or any(h < 1 for h in self.hidden):
            raise InvalidInputError(f"hidden sizes must be positive integers, e.g. 64,128; got {self.hidden}")
        if self.param not in ("lowrank", "cholesky", "full"):
            raise InvalidInputError(f"param must be 'lowrank', 'cholesky' or 'full'; got {self.param!r}")
        if self.center not in ("offset", "raw"):
            raise InvalidInputError(f"center must be 'offset' or 'raw'; got {self.center!r}")
        if self.activation not in ACTIVATIONS:
            raise InvalidInputError(
                f"activation must be one of {', '.join(ACTIVATIONS)}; got {self.activation!r}"
            )
        if not isinstance(self.linear_center, bool):
            raise InvalidInputError(f"linear_center must be True or False; got {self.linear_center!r}")
        if isinstance(self.members, bool) or not isinstance(self.members, int):
            raise InvalidInputError(f"members must be an integer; got {self.members!r}")
        if not 1 <= self.members <= MAX_MEMBERS:
            raise InvalidInputError(f"members must be in [1, {MAX_MEMBERS}]; got {self.members}")
        widths = (self.x_dim + self.y_dim, *self.hidden)
        weights = self.members * sum(a * b for a, b in zip(widths[:-1], widths[1:], strict=True))
        if weights > MAX_HIDDEN_WEIGHTS:
            raise InvalidInputError(
                f"hidden sizes {','.join(map(str, self.hidden))} make a network of more than {weights:.3g} "
                f"weights ({self.members} member(s)), above the {MAX_HIDDEN_WEIGHTS:.0e} ipcverify trains; "
                f"choose narrower layers, e.g. {option('hidden', (64, 64))}"
            )
        if self.param == "lowrank" and self.center != "offset":
            raise InvalidInputError("the low-rank head predicts an offset from yhat: use center='offset'")
        if self.param != "lowrank" and (self.linear_center or self.members != 1):
            raise InvalidInputError(
                f"a linear centre stage and ensembles come with the low-rank head; with param={self.param!r} "
                "set linear_center=False and members=1, or use param='lowrank' (the default recipe)"
            )

    @classmethod
    def recipe(cls, name: str, *, x_dim: int, y_dim: int, **overrides: Any) -> ModelConfig:
        """The architecture of the recipe ``name`` (see :data:`RECIPES`), with ``overrides``.

        Examples
        --------
        >>> ModelConfig.recipe("v1", x_dim=2, y_dim=3, hidden=(8,))
        ModelConfig(x_dim=2, y_dim=3, hidden=(8,), param='cholesky', center='offset', activation='relu', \
linear_center=False, members=1)
        >>> ModelConfig.recipe("v1", x_dim=2, y_dim=3) == ModelConfig(x_dim=2, y_dim=3, param="cholesky")
        True
        """
        if name not in _RECIPE_MODEL:
            raise InvalidInputError(f"unknown recipe {name!r}; choose one of {', '.join(RECIPES)}")
        if overrides.get("members", 1) == 0:  # 0 means "the head's default" to the constructor only
            raise InvalidInputError(
                f"{option('members')} must be in [1, {MAX_MEMBERS}]; got 0 -- leave it out for the recipe's "
                "ensemble size"
            )
        return cls(x_dim=x_dim, y_dim=y_dim, **{**_RECIPE_MODEL[name], **overrides})

    @property
    def kind(self) -> str:
        """The network kind: ``"lowrank"`` (:class:`~ipcverify.network.LowRankEnsemble`, the default) or
        ``"mlp"`` (:class:`~ipcverify.network.IPCNetwork`, the paper's heads). A key for registries
        (the training package's trainers); within ipcverify only the network package branches on it.

        Examples
        --------
        >>> ModelConfig(x_dim=1, y_dim=1).kind, ModelConfig.recipe("paper", x_dim=1, y_dim=1).kind
        ('lowrank', 'mlp')
        """
        return "lowrank" if self.lowrank else "mlp"

    @property
    def lowrank(self) -> bool:
        """True for the low-rank head (single network or ensemble), False for the paper's heads."""
        return self.param == "lowrank"

    @property
    def file_version(self) -> int:
        """The oldest model-file format version that holds this network (:mod:`ipcverify.io._modelio`).

        2 for the low-rank head (its stacked members and config keys came with version 2); 1 for the
        paper's heads, so that older ipcverify versions still read them.

        Examples
        --------
        >>> ModelConfig.recipe("v1", x_dim=1, y_dim=1).file_version
        1
        >>> ModelConfig(x_dim=1, y_dim=1).file_version
        2
        """
        return 2 if self.lowrank else 1

    @property
    def n_shape_outputs(self) -> int:
        """Number of network outputs used for the shape matrix (per member)."""
        n = self.y_dim
        if self.param == "lowrank":
            return n + n * n
        return n * n if self.param == "full" else n * (n + 1) // 2

    @property
    def n_outputs(self) -> int:
        """Total network output size (centre + shape)."""
        return self.y_dim + self.n_shape_outputs

    def to_dict(self) -> dict[str, Any]:
        """Plain-data form (for model files and fingerprints).

        The keys added with the low-rank head (``linear_center``, ``members``) are written
        only for low-rank configurations, so a Cholesky or full network is described (and
        fingerprinted) exactly as before they existed.

        Examples
        --------
        >>> sorted(ModelConfig.recipe("v1", x_dim=1, y_dim=1).to_dict())
        ['activation', 'center', 'hidden', 'param', 'x_dim', 'y_dim']
        """
        d = asdict(self)
        d["hidden"] = list(self.hidden)
        if not self.lowrank:
            for key in _LOWRANK_KEYS:
                del d[key]
        return d

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ModelConfig:
        """Inverse of :meth:`to_dict`; unknown keys are refused.

        A missing optional key takes the value it had before the low-rank head existed
        (a Cholesky network (64, 128), one member): dictionaries without them were written
        then, so they are read as they were meant.

        Examples
        --------
        >>> ModelConfig.from_dict({"x_dim": 2, "y_dim": 3}).param
        'cholesky'
        """
        known = {"x_dim", "y_dim", "hidden", "param", "center", "activation", *_LOWRANK_KEYS}
        unknown = set(data) - known
        if unknown:
            raise InvalidInputError(f"unknown model config key(s): {', '.join(sorted(unknown))}")
        # values are validated by __post_init__; a missing x_dim / y_dim raises TypeError as before
        kwargs: dict[str, Any] = dict(_LEGACY)
        kwargs.update({k: (tuple(v) if k == "hidden" else v) for k, v in data.items()})
        return cls(**kwargs)
