"""Settings of the paper reproduction: ``reproduce.toml`` (:mod:`case_studies.quad_landing.settings`).

The simulator's settings stay in ``defaults.toml`` (:mod:`case_studies.quad_landing.sim.config`);
this file holds what the reproduction adds: landing scenarios
(:class:`~case_studies.quad_landing.landing.scenario.ScenarioParams`), approach-flight data
(:class:`~case_studies.quad_landing.data.approach.ApproachParams`), the landing state
machine (:class:`~case_studies.quad_landing.landing.state_machine.LandingParams`), the IPC
recipe (:class:`IpcParams`) and the sizes of the reproduction (:class:`Sizes`). Each
section's dataclass lives beside the code that uses it. The ``[quick]`` table is an
overlay with the same layout (``[quick.sizes]``, ``[quick.ipc]``) applied by
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
from case_studies.quad_landing.landing.scenario import ScenarioParams
from case_studies.quad_landing.landing.state_machine import LandingParams
from case_studies.quad_landing.settings import (
    REPRODUCE_PATH,
    ConfigError,
    build_sections,
    check_positive,
    merge_sections,
    read_toml,
)
from case_studies.quad_landing.sim.framebuffer import MAX_BUFFER_SIZE

__all__ = ["IpcParams", "Sizes", "ReproduceConfig", "load_reproduce_config", "REPRODUCE_SECTIONS"]


@dataclass(frozen=True, kw_only=True)
class IpcParams:
    """The IPC recipe: network, training and calibration settings.

    Examples
    --------
    >>> IpcParams().hidden
    (64, 128)
    """

    hidden: tuple[int, ...] = (64, 128)
    epochs: int = 40
    lr: float = 1e-3
    batch_size: int = 64
    alpha: float = 0.1
    lam: float = 0.01
    seed: int = 0
    epsilon: float = 0.002
    delta: float = 0.001
    coverage_quantile: float = 0.995

    def __post_init__(self) -> None:
        object.__setattr__(self, "hidden", tuple(int(h) for h in self.hidden))
        for name in ("epochs", "batch_size"):
            check_positive(f"ipc.{name}", getattr(self, name), integer=True)
        check_positive("ipc.seed", self.seed, integer=True, allow_zero=True)
        for name in ("lr", "alpha"):
            check_positive(f"ipc.{name}", getattr(self, name))
        check_positive("ipc.lam", self.lam, allow_zero=True)
        for name in ("epsilon", "delta", "coverage_quantile"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 < v < 1.0):
                raise ConfigError(f"ipc.{name} must lie strictly between 0 and 1, got {v!r}")


@dataclass(frozen=True, kw_only=True)
class Sizes:
    """Sizes of the reproduction.

    Parameters
    ----------
    n_train, n_calibration, n_test : int
        Samples of the training and calibration sets (per IPC) and of each test set.
    buffers : tuple of int
        Buffer sizes of Table I.
    paper_runs, mc_runs : int
        Landing runs: the paper-style experiment and the Monte Carlo campaign.
    buffer1_runs : int
        Runs of the buffer-1 landing (the lag control experiment); 0 skips it.

    Examples
    --------
    >>> Sizes().buffers
    (1, 2, 3, 4, 5)
    """

    n_train: int = 5000
    n_calibration: int = 10000
    n_test: int = 2000
    buffers: tuple[int, ...] = (1, 2, 3, 4, 5)
    paper_runs: int = 10
    mc_runs: int = 300
    buffer1_runs: int = 100

    def __post_init__(self) -> None:
        for name in ("n_train", "n_calibration", "n_test", "paper_runs", "mc_runs"):
            check_positive(f"sizes.{name}", getattr(self, name), integer=True)
        check_positive("sizes.buffer1_runs", self.buffer1_runs, integer=True, allow_zero=True)
        b = tuple(self.buffers)
        if (
            not b
            or any(isinstance(k, bool) or not isinstance(k, int) or not 0 <= k <= MAX_BUFFER_SIZE for k in b)
            or len(set(b)) != len(b)
        ):
            raise ConfigError(f"sizes.buffers must be distinct integers in [0, {MAX_BUFFER_SIZE}], got {b!r}")
        if 1 not in b:
            raise ConfigError("sizes.buffers must include 1, the buffer size the Table I IPC is learned at")
        object.__setattr__(self, "buffers", tuple(sorted(b)))


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
    landing: LandingParams
    ipc: IpcParams
    sizes: Sizes
    quick: bool = False

    def as_dict(self) -> dict[str, Any]:
        """Plain data in the TOML layout (for the summary)."""
        out: dict[str, Any] = {}
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            out[f.name] = dataclasses.asdict(v) if dataclasses.is_dataclass(v) else v
        return out


#: The sections of ``reproduce.toml`` and their dataclasses.
REPRODUCE_SECTIONS: dict[str, type] = {
    "scenario": ScenarioParams,
    "approach": ApproachParams,
    "landing": LandingParams,
    "ipc": IpcParams,
    "sizes": Sizes,
}


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
