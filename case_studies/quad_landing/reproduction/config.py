"""Settings of the paper reproduction: ``reproduce.toml`` (:mod:`case_studies.quad_landing.settings`).

The simulator's settings stay in ``defaults.toml`` (:mod:`case_studies.quad_landing.sim.config`);
this file holds what the reproduction adds: landing scenarios
(:class:`~case_studies.quad_landing.landing.scenario.ScenarioParams`), approach-flight data
(:class:`~case_studies.quad_landing.data.approach.ApproachParams`), the pilot model of the
test flights (:class:`~case_studies.quad_landing.data.pilot.PilotParams`), the landing state
machine (:class:`~case_studies.quad_landing.landing.state_machine.LandingParams`), the IPC
recipe (:class:`IpcParams`), the sizes of the reproduction (:class:`Sizes`) and of its
per-configuration Table I (:class:`AblationSizes`). Each
section's dataclass lives beside the code that uses it. The ``[quick]`` table is an
overlay with the same layout (``[quick.sizes]``, ``[quick.ipc]``, ``[quick.ablation]``) applied by
``load_reproduce_config(quick=True)``. Unknown sections or keys are errors; nothing is
``eval``-ed.

Examples
--------
>>> cfg = load_reproduce_config()
>>> cfg.landing.max_measurements, cfg.sizes.n_train
(8, 5000)
>>> load_reproduce_config(quick=True).sizes.mc_runs < cfg.sizes.mc_runs
True
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from case_studies.quad_landing.data.approach import ApproachParams
from case_studies.quad_landing.data.pilot import PilotParams
from case_studies.quad_landing.landing.scenario import ScenarioParams
from case_studies.quad_landing.landing.state_machine import LandingParams
from case_studies.quad_landing.settings import (
    REPRODUCE_PATH,
    ConfigError,
    TomlSection,
    build_sections,
    check_positive,
    merge_sections,
    read_toml,
    sections_by_name,
)
from case_studies.quad_landing.sim.camera import BufferSize, check_buffer_size
from ipcverify.errors import InvalidInputError
from ipcverify.network._architecture import RECIPES
from ipcverify.training import TrainConfig
from ipcverify.training._selection import HingeSelection

__all__ = [
    "IpcParams",
    "PaperParams",
    "Sizes",
    "AblationSizes",
    "ReproduceConfig",
    "load_reproduce_config",
    "REPRODUCE_SECTIONS",
]


def _check_recipe(recipe: Any) -> str:
    """``recipe`` if it names a library recipe, else a :class:`ConfigError` listing them."""
    if recipe not in RECIPES:
        raise ConfigError(f"ipc.recipe must be one of {', '.join(RECIPES)}, got {recipe!r}")
    return str(recipe)


def _train_fields() -> dict[str, dataclasses.Field[Any]]:
    return {f.name: f for f in dataclasses.fields(TrainConfig) if f.init}


def _hidden_layers(section: str, hidden: Any) -> tuple[int, ...]:
    """``hidden`` as a tuple of positive integers (layer sizes), else a :class:`ConfigError` naming
    ``<section>.hidden``."""
    h = tuple(hidden)
    if not h or any(isinstance(v, bool) or not isinstance(v, int) or v < 1 for v in h):
        raise ConfigError(f"{section}.hidden must be a list of positive integers, got {hidden!r}")
    return h


def _check_calibration_levels(section: str, params: Any) -> None:
    """Raise a :class:`ConfigError` unless ``epsilon``, ``delta`` and ``coverage_quantile`` of
    ``params`` are numbers strictly between 0 and 1."""
    for name in ("epsilon", "delta", "coverage_quantile"):
        v = getattr(params, name)
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0.0 < v < 1.0:
            raise ConfigError(f"{section}.{name} must lie strictly between 0 and 1, got {v!r}")


@dataclass(frozen=True, kw_only=True)
class IpcParams(TomlSection, file=REPRODUCE_PATH, section="ipc"):
    """The IPC recipe: the network, its training and its calibration (``[ipc]``).

    The ``[ipc]`` table is flat. Its keys that are fields of
    :class:`ipcverify.training.TrainConfig` (``epochs``, ``lr``, ``batch_size``, ``alpha``,
    ``lam``, ``seed``, or any other the library defines) build :attr:`train`; the fields
    the table leaves out keep the values of the library's recipe ``recipe``
    (``TrainConfig.recipe(recipe)``). The other keys are not training:

    Parameters
    ----------
    recipe : str
        The library's recipe (:data:`ipcverify.network.RECIPES`) of the contract
        ``default_calibrated``: ``"tight"``, ipcverify's default, or ``"v1"``, its earlier
        Cholesky head with the hinge loss (``case_studies/quad_landing/v1_head.toml``). The
        paper's own network is :class:`PaperParams` (``[paper]``), always run beside it.
    hidden : tuple of int
        Hidden layer sizes of the network (:class:`ipcverify.network.ModelConfig`).
    train : TrainConfig
        The training settings.
    epsilon, delta : float
        PAC calibration target and confidence parameter.
    coverage_quantile : float
        The domain of validity fitted at calibration (:class:`ipcverify.guard.DomainModel`)
        flags queries beyond this quantile of the calibration inputs' nearest-neighbour
        distances: its false-alarm rate is ``1 - coverage_quantile`` (fitted by flight when
        there are enough flights: :func:`~.learn.domain_groups`). The closed loop's
        shift check (:func:`case_studies.quad_landing.reproduction.coverage.coverage_check`)
        uses the same test.

    Examples
    --------
    >>> ipc = IpcParams.defaults()  # [ipc] of reproduce.toml
    >>> ipc.recipe, ipc.hidden, ipc.train.loss, ipc.epsilon
    ('tight', (64, 128), 'likelihood', 0.002)
    >>> IpcParams.defaults(epochs=2).train.epochs
    2
    """

    recipe: str
    hidden: tuple[int, ...]
    train: TrainConfig
    epsilon: float
    delta: float
    coverage_quantile: float

    def __post_init__(self) -> None:
        _check_recipe(self.recipe)
        object.__setattr__(self, "hidden", _hidden_layers("ipc", self.hidden))
        if not isinstance(self.train, TrainConfig):
            raise ConfigError(f"IpcParams.train must be a TrainConfig, got {type(self.train).__name__}")
        _check_calibration_levels("ipc", self)

    @classmethod
    def toml_keys(cls) -> frozenset[str]:
        """``recipe``, ``hidden``, ``epsilon``, ``delta``, ``coverage_quantile``, TrainConfig's fields."""
        own = {f.name for f in dataclasses.fields(cls) if f.init and f.name != "train"}
        return frozenset(own | set(_train_fields()))

    @classmethod
    def from_table(cls, table: Mapping[str, Any]) -> IpcParams:
        """Split the flat ``[ipc]`` table into the ``TrainConfig`` and the rest."""
        fields = _train_fields()
        train = {k: v for k, v in table.items() if k in fields}
        for key, value in train.items():
            if fields[key].type in ("int", int) and (isinstance(value, bool) or not isinstance(value, int)):
                raise ConfigError(f"ipc.{key} must be an integer, got {value!r}")
        recipe = _check_recipe(table.get("recipe"))
        try:
            config = TrainConfig.recipe(recipe, **train)
        except InvalidInputError as exc:
            raise ConfigError(f"[ipc]: {exc}") from None
        rest: dict[str, Any] = {
            k: tuple(v) if isinstance(v, list) else v for k, v in table.items() if k not in fields
        }
        try:
            return cls(train=config, **rest)
        except TypeError as exc:  # missing required keys
            raise ConfigError(f"[ipc]: {exc}") from None

    def to_table(self) -> dict[str, Any]:
        """The flat ``[ipc]`` layout: ``hidden``, every ``TrainConfig`` field, then the rest."""
        return {
            "recipe": self.recipe,
            "hidden": list(self.hidden),
            **dataclasses.asdict(self.train),
            "epsilon": self.epsilon,
            "delta": self.delta,
            "coverage_quantile": self.coverage_quantile,
        }


@dataclass(frozen=True, kw_only=True)
class PaperParams(TomlSection, file=REPRODUCE_PATH, section="paper"):
    """The paper's IPC in the reproduction (``[paper]`` of ``reproduce.toml``; :mod:`.paper_ipc`).

    Parameters
    ----------
    hidden : tuple of int
        The paper's hidden layers (64, 128).
    epochs, lr : int, float
        The paper's 20 epochs of Adam at 1e-3.
    seed : int
        Seeds the initialisation, the shuffling and the held-out share of the selection.
    alphas, lams, batch_sizes : tuple
        The candidates of the selection rule (the paper states none of the three).
    target_miss, val_fraction : float
        The selection rule: the smallest held-out log-volume with a raw held-out miss rate at
        most ``target_miss``, on ``val_fraction`` of the training rows
        (:class:`ipcverify.training.HingeSelection`).
    selection_groups : str
        Hold out whole groups of this column (``"flight"``: rows of one flight are correlated);
        ``""`` holds out rows.
    epsilon, delta : float
        The PAC calibration of ``paper_calibrated``.
    coverage_quantile : float
        Its domain of validity (as ``[ipc] coverage_quantile``).
    fly_uncalibrated : bool
        Fly ``paper_raw``, the uncalibrated network, in the landing runs (``reproduce
        --fly-uncalibrated``; off by default). Its sets carry no guarantee, so this is an
        explicit choice; Table I is measured either way.

    Examples
    --------
    >>> PaperParams.defaults().hidden, PaperParams.defaults().fly_uncalibrated
    ((64, 128), False)
    >>> PaperParams.defaults().selection().target_miss
    0.002
    """

    hidden: tuple[int, ...]
    epochs: int
    lr: float
    seed: int
    alphas: tuple[float, ...]
    lams: tuple[float, ...]
    batch_sizes: tuple[int, ...]
    target_miss: float
    val_fraction: float
    selection_groups: str
    epsilon: float
    delta: float
    coverage_quantile: float
    fly_uncalibrated: bool

    def __post_init__(self) -> None:
        object.__setattr__(self, "hidden", _hidden_layers("paper", self.hidden))
        if not isinstance(self.fly_uncalibrated, bool):
            raise ConfigError(f"paper.fly_uncalibrated must be true or false, got {self.fly_uncalibrated!r}")
        _check_calibration_levels("paper", self)
        try:
            self.selection()
            self.train_config()
        except InvalidInputError as exc:
            raise ConfigError(f"[paper]: {exc}") from None

    def selection(self) -> HingeSelection:
        """The rule that chooses ``alpha``, ``lambda`` and the batch size."""
        return HingeSelection(
            alphas=tuple(float(a) for a in self.alphas),
            lams=tuple(float(v) for v in self.lams),
            batch_sizes=tuple(self.batch_sizes),
            target_miss=float(self.target_miss),
            val_fraction=float(self.val_fraction),
            group_column=self.selection_groups or None,
        )

    def train_config(self) -> TrainConfig:
        """The recipe ``"paper"``'s training with this section's epochs, step size and seed."""
        return TrainConfig.recipe("paper", epochs=self.epochs, lr=float(self.lr), seed=self.seed)


@dataclass(frozen=True, kw_only=True)
class Sizes(TomlSection, file=REPRODUCE_PATH, section="sizes"):
    """Sizes of the reproduction.

    Parameters
    ----------
    n_train, n_calibration, n_test : int
        Samples of the training and calibration sets and of the held-out test set (per IPC).
    n_pilot : int
        Table I: pilot test measurements per buffer size.
    buffers : tuple of int
        Buffer sizes of Table I.
    paper_runs, mc_runs : int
        Landing runs: the paper-style experiment and the Monte Carlo campaign.
    extra_landing_buffer : int
        A second landing experiment at this buffer size, with an IPC learned there.
    extra_landing_runs : int
        Its Monte Carlo runs per contract; 0 skips it.

    Examples
    --------
    >>> Sizes.defaults().buffers  # [sizes] of reproduce.toml
    (1, 2, 3, 4, 5)
    """

    n_train: int
    n_calibration: int
    n_test: int
    n_pilot: int
    buffers: tuple[BufferSize, ...]
    paper_runs: int
    mc_runs: int
    extra_landing_buffer: BufferSize
    extra_landing_runs: int

    def __post_init__(self) -> None:
        for name in ("n_train", "n_calibration", "n_test", "n_pilot", "paper_runs", "mc_runs"):
            check_positive(f"sizes.{name}", getattr(self, name), integer=True)
        check_positive("sizes.extra_landing_runs", self.extra_landing_runs, integer=True, allow_zero=True)
        extra = check_buffer_size(
            self.extra_landing_buffer, name="sizes.extra_landing_buffer", lowest=1, error=ConfigError
        )
        object.__setattr__(self, "extra_landing_buffer", extra)
        b = tuple(check_buffer_size(k, name="each of sizes.buffers", error=ConfigError) for k in self.buffers)
        if not b or len(set(b)) != len(b):
            raise ConfigError(
                f"sizes.buffers must be distinct buffer sizes (one or more); got {self.buffers!r}"
            )
        if 1 not in b:
            raise ConfigError("sizes.buffers must include 1, the buffer size the Table I IPC is learned at")
        object.__setattr__(self, "buffers", tuple(sorted(b)))


@dataclass(frozen=True, kw_only=True)
class AblationSizes(TomlSection, file=REPRODUCE_PATH, section="ablation"):
    """Sizes of the per-configuration Table I (ablation of the error sources, sensitivity).

    Every configuration learns its own buffer-1 IPC with the ``[ipc]`` recipe, PAC-calibrated at
    ``epsilon`` and ``delta`` (smaller calibration sets cannot certify the main ``[ipc] epsilon``).

    Parameters
    ----------
    n_train, n_calibration, n_pilot : int
        Training and calibration samples, and pilot test measurements per buffer size.
    epsilon, delta : float
        PAC calibration target and confidence parameter of these IPCs.
    variants : tuple of str
        The configurations to run (names of :func:`.variants.ablation_variants`); empty: all.

    Examples
    --------
    >>> AblationSizes.defaults().epsilon  # [ablation] of reproduce.toml
    0.01
    """

    n_train: int
    n_calibration: int
    n_pilot: int
    epsilon: float
    delta: float
    variants: tuple[str, ...]

    def __post_init__(self) -> None:
        v = tuple(self.variants)
        if any(not isinstance(name, str) or not name for name in v) or len(set(v)) != len(v):
            raise ConfigError(f"ablation.variants must be distinct variant names, got {self.variants!r}")
        object.__setattr__(self, "variants", v)
        for name in ("n_train", "n_calibration", "n_pilot"):
            check_positive(f"ablation.{name}", getattr(self, name), integer=True)
        for name in ("epsilon", "delta"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 < v < 1.0):
                raise ConfigError(f"ablation.{name} must lie strictly between 0 and 1, got {v!r}")


@dataclass(frozen=True, kw_only=True)
class ReproduceConfig:
    """Everything :mod:`.pipeline` needs besides the simulator's :class:`.sim.config.SimConfig`.

    Examples
    --------
    >>> cfg = load_reproduce_config(overrides={"landing": {"max_measurements": 5}})
    >>> cfg.landing.max_measurements
    5
    """

    scenario: ScenarioParams
    approach: ApproachParams
    pilot: PilotParams
    landing: LandingParams
    ipc: IpcParams
    paper: PaperParams
    sizes: Sizes
    ablation: AblationSizes
    quick: bool = False

    def as_dict(self) -> dict[str, Any]:
        """Plain data in the TOML layout (for the summary), and ``quick``."""
        sections: dict[str, Any] = {name: getattr(self, name).to_table() for name in REPRODUCE_SECTIONS}
        return {**sections, "quick": self.quick}


#: The sections of ``reproduce.toml`` and their dataclasses.
REPRODUCE_SECTIONS: dict[str, type[TomlSection]] = sections_by_name(
    ScenarioParams,
    ApproachParams,
    PilotParams,
    LandingParams,
    IpcParams,
    PaperParams,
    Sizes,
    AblationSizes,
)


def load_reproduce_config(
    path: str | Path | None = None,
    overrides: Mapping[str, Mapping[str, Any]] | None = None,
    *,
    quick: bool = False,
) -> ReproduceConfig:
    """Read ``reproduce.toml``, then the ``[quick]`` overlay (if ``quick``), ``path`` and ``overrides``.

    Parameters
    ----------
    path : str or Path, optional
        A TOML file with any subset of the sections and keys of ``reproduce.toml``
        (its own ``[quick]`` table, if any, is applied with ``quick=True``).
    overrides : mapping, optional
        ``{section: {key: value}}`` applied last.
    quick : bool
        Apply the ``[quick]`` overlay (smaller sizes, same pipeline).

    Raises
    ------
    ConfigError
        If a file is missing or malformed, or a section, key or value is invalid.
    """
    tree: dict[str, dict[str, Any]] = {}
    sources = [(REPRODUCE_PATH, read_toml(REPRODUCE_PATH))]
    if path is not None:
        sources.append((Path(path), read_toml(Path(path))))
    for src, data in sources:
        data = dict(data)
        overlay = data.pop("quick", {})
        tree = merge_sections(tree, data, str(src), REPRODUCE_SECTIONS)
        if quick:
            if not isinstance(overlay, Mapping):
                raise ConfigError(f"{src}: [quick] must be a table of sections")
            tree = merge_sections(tree, overlay, f"{src} [quick]", REPRODUCE_SECTIONS)
    if overrides:
        tree = merge_sections(tree, overrides, "override", REPRODUCE_SECTIONS)
    return ReproduceConfig(**build_sections(tree, REPRODUCE_SECTIONS), quick=quick)
