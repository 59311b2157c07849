"""The simulator's configuration: ``defaults.toml`` (:mod:`case_studies.quad_landing.settings`).

:func:`load_config` reads the defaults, merges an optional override file and/or a
nested mapping of overrides on top (section by section, key by key), and builds a
frozen :class:`SimConfig` whose parts validate themselves. Unknown sections or keys are
errors, so typos do not pass silently. Nothing is ever ``eval``-ed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from case_studies.quad_landing.perception.aruco import DetectorParams
from case_studies.quad_landing.perception.marker import MarkerParams
from case_studies.quad_landing.settings import (
    DEFAULTS_PATH,
    ConfigError,
    TomlSection,
    build_sections,
    merge_sections,
    read_toml,
    sections_by_name,
)
from case_studies.quad_landing.sim.camera import (
    BufferSize,
    CameraParams,
    CameraTimingParams,
    RenderParams,
    check_buffer_size,
)
from case_studies.quad_landing.sim.dynamics import QuadParams
from case_studies.quad_landing.sim.lqr import LqrParams, SettleParams
from case_studies.quad_landing.sim.marker import Pad
from case_studies.quad_landing.sim.paths import PathParams

__all__ = ["SimParams", "CollectParams", "SimConfig", "load_config", "SIM_SECTIONS"]


@dataclass(frozen=True, kw_only=True)
class SimParams(TomlSection, file=DEFAULTS_PATH, section="sim"):
    """Simulation settings.

    Parameters
    ----------
    physics_rate : float
        Integration rate (Hz), >= 200 and an integer multiple of the camera rate.
    ground_z : float
        Floor height in W (m).
    workspace_min, workspace_max : tuple of 3 floats
        Corners of the box the quadrotor may fly in (m).

    Examples
    --------
    >>> SimParams.defaults().physics_rate  # [sim] of defaults.toml
    240.0
    """

    physics_rate: float
    ground_z: float
    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]

    def __post_init__(self) -> None:
        if not (np.isfinite(self.physics_rate) and self.physics_rate >= 200):
            raise ConfigError(f"sim.physics_rate must be >= 200 Hz, got {self.physics_rate}")
        lo = tuple(float(v) for v in self.workspace_min)
        hi = tuple(float(v) for v in self.workspace_max)
        if len(lo) != 3 or len(hi) != 3 or not all(a < b for a, b in zip(lo, hi, strict=True)):
            raise ConfigError(
                "sim.workspace_min and workspace_max must be 3 numbers each with min < max, "
                f"got {self.workspace_min} and {self.workspace_max}"
            )
        if not lo[2] <= self.ground_z < hi[2]:
            raise ConfigError(f"sim.ground_z ({self.ground_z}) must lie in the workspace's z range")
        object.__setattr__(self, "physics_rate", float(self.physics_rate))
        object.__setattr__(self, "workspace_min", lo)
        object.__setattr__(self, "workspace_max", hi)


@dataclass(frozen=True, kw_only=True)
class CollectParams(TomlSection, file=DEFAULTS_PATH, section="collect"):
    """Data-collection settings.

    Parameters
    ----------
    n : int
        Number of samples with a detection to collect.
    buffer_size : int
        Camera buffer size ``k`` (frames of lag).
    sample_every : int
        Take a measurement every this many camera frames.
    warmup_time : float
        Seconds flown on each path before sampling starts.

    Examples
    --------
    >>> CollectParams.defaults().n
    5000
    """

    n: int
    buffer_size: BufferSize
    sample_every: int
    warmup_time: float

    def __post_init__(self) -> None:
        size = check_buffer_size(self.buffer_size, name="collect.buffer_size", error=ConfigError)
        object.__setattr__(self, "buffer_size", size)
        for name, lo in (("n", 1), ("sample_every", 1)):
            value = getattr(self, name)
            if isinstance(value, bool) or int(value) != value or value < lo:
                raise ConfigError(f"collect.{name} must be an integer >= {lo}, got {value!r}")
            object.__setattr__(self, name, int(value))
        if not (np.isfinite(self.warmup_time) and self.warmup_time >= 0):
            raise ConfigError(f"collect.warmup_time must be >= 0 s, got {self.warmup_time}")


@dataclass(frozen=True, kw_only=True)
class SimConfig:
    """Everything the simulator and data collection need; see ``defaults.toml``.

    Examples
    --------
    >>> cfg = load_config()
    >>> cfg.camera.width, cfg.quad.mass
    (320, 1.5)
    >>> cfg.replace(collect={"buffer_size": 3}).collect.buffer_size
    3
    """

    quad: QuadParams
    sim: SimParams
    lqr: LqrParams
    settle: SettleParams
    camera: CameraParams
    marker: MarkerParams
    pad: Pad
    render: RenderParams
    detector: DetectorParams
    camera_timing: CameraTimingParams
    paths: PathParams
    collect: CollectParams

    def __post_init__(self) -> None:
        ratio = self.sim.physics_rate / self.camera.fps
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise ConfigError(
                f"sim.physics_rate ({self.sim.physics_rate} Hz) must be an integer multiple of "
                f"camera.fps ({self.camera.fps} Hz), e.g. 240 for 60 fps"
            )
        lo, hi = np.asarray(self.sim.workspace_min), np.asarray(self.sim.workspace_max)
        if np.any(self.pad.position < lo) or np.any(self.pad.position > hi):
            raise ConfigError(f"pad.position {self.pad.position.tolist()} is outside the workspace")

    @property
    def sensor_render(self) -> RenderParams:
        """``[render]`` as the camera uses it: no sensor noise when the noise source is off."""
        if self.camera_timing.enabled("noise"):
            return self.render
        return dataclasses.replace(self.render, noise_std=0.0)

    @property
    def substeps(self) -> int:
        """Physics steps per camera frame."""
        return int(round(self.sim.physics_rate / self.camera.fps))

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """The configuration as nested plain data (TOML layout)."""
        return {f.name: getattr(self, f.name).to_table() for f in dataclasses.fields(self)}

    def replace(self, **sections: Mapping[str, Any]) -> SimConfig:
        """A copy with some keys of some sections replaced, e.g. ``replace(camera={"fx": 250})``."""
        return _build(merge_sections(self.as_dict(), sections, "override", SIM_SECTIONS))


#: The sections of ``defaults.toml`` and their dataclasses, in the order of :class:`SimConfig`.
SIM_SECTIONS: dict[str, type[TomlSection]] = sections_by_name(
    QuadParams,
    SimParams,
    LqrParams,
    SettleParams,
    CameraParams,
    MarkerParams,
    Pad,
    RenderParams,
    DetectorParams,
    CameraTimingParams,
    PathParams,
    CollectParams,
)


def load_config(
    path: str | Path | None = None, overrides: Mapping[str, Mapping[str, Any]] | None = None
) -> SimConfig:
    """Read ``defaults.toml``, then merge ``path`` (a TOML file) and ``overrides`` on top.

    Parameters
    ----------
    path : str or Path, optional
        A TOML file with any subset of the sections and keys of ``defaults.toml``.
    overrides : mapping, optional
        ``{section: {key: value}}`` applied last.

    Raises
    ------
    ConfigError
        If a file is missing or malformed, or a section, key or value is invalid.

    Examples
    --------
    >>> load_config(overrides={"collect": {"buffer_size": 5}}).collect.buffer_size
    5
    """
    tree = merge_sections({}, read_toml(DEFAULTS_PATH), str(DEFAULTS_PATH), SIM_SECTIONS)
    if path is not None:
        tree = merge_sections(tree, read_toml(Path(path)), str(path), SIM_SECTIONS)
    if overrides:
        tree = merge_sections(tree, overrides, "override", SIM_SECTIONS)
    return _build(tree)


def _build(tree: Mapping[str, Mapping[str, Any]]) -> SimConfig:
    return SimConfig(**build_sections(tree, SIM_SECTIONS))
