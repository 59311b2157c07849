"""Settings of the paper reproduction: ``reproduce.toml`` beside this module, read with :mod:`tomllib`.

The simulator's settings stay in ``defaults.toml`` (:mod:`.config`); this file holds what
issue 6 adds: landing scenarios (:class:`ScenarioParams`), approach-flight data
(:class:`ApproachParams`), the landing state machine (:class:`LandingParams`), the IPC
recipe (:class:`IpcParams`) and the sizes of the reproduction (:class:`Sizes`). The
``[quick]`` table is an overlay with the same layout (``[quick.sizes]``, ``[quick.ipc]``)
applied by ``load_reproduce_config(quick=True)``. Unknown sections or keys are errors;
nothing is ``eval``-ed.

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
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from case_studies.quad_landing.config import ConfigError, merge_sections, read_toml
from case_studies.quad_landing.framebuffer import MAX_BUFFER_SIZE

__all__ = [
    "REPRODUCE_PATH",
    "Range",
    "ScenarioParams",
    "ApproachParams",
    "LandingParams",
    "IpcParams",
    "Sizes",
    "ReproduceConfig",
    "load_reproduce_config",
]

#: The settings file shipped beside the code.
REPRODUCE_PATH = Path(__file__).with_name("reproduce.toml")

Range = tuple[float, float]


def _range(where: str, value: Any, lo: float = -math.inf) -> Range:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(f"{where} must be two numbers [low, high], got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b) and lo <= a <= b):
        raise ConfigError(f"{where} must be finite with {lo:g} <= low <= high, got {value!r}")
    return (a, b)


def _positive(where: str, value: Any, *, integer: bool = False, allow_zero: bool = False) -> None:
    bad = isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value)
    if not bad:
        bad = value < 0 or (value == 0 and not allow_zero) or (integer and int(value) != value)
    if bad:
        kind = "an integer" if integer else "a number"
        raise ConfigError(f"{where} must be {kind} {'>= 0' if allow_zero else '> 0'}, got {value!r}")


@dataclass(frozen=True, kw_only=True)
class ScenarioParams:
    """How a landing run starts: a random pad, the vehicle arriving toward a prior guess of it.

    Parameters
    ----------
    pad_region : float
        Pad centre ``x, y`` uniform in ``[-r, r]`` (m).
    start_distance, start_height : (low, high)
        Horizontal distance from the pad and camera height above it at the start (m).
    transit_speed : (low, high)
        Speed of the transit toward the prior guess (m/s).
    prior_radius : float
        The prior guess of the pad lies uniformly within this radius of it (m).
    aligned_margin_deg : float
        The pad's edges are kept at least this many degrees from the image axes (0 turns
        it off): OpenCV's AprilTag refinement reads the range ~1 % short within ~2 degrees.
    deceleration : float
        Past the prior guess the transit brakes smoothly at up to this (m/s^2).

    Examples
    --------
    >>> ScenarioParams().transit_speed
    (1.2, 1.8)
    """

    pad_region: float = 2.0
    start_distance: Range = (1.6, 2.2)
    start_height: Range = (1.5, 2.1)
    transit_speed: Range = (1.2, 1.8)
    prior_radius: float = 0.3
    aligned_margin_deg: float = 3.0
    deceleration: float = 1.5

    def __post_init__(self) -> None:
        _positive("scenario.pad_region", self.pad_region)
        _positive("scenario.deceleration", self.deceleration)
        _positive("scenario.prior_radius", self.prior_radius, allow_zero=True)
        for name in ("start_distance", "start_height", "transit_speed"):
            object.__setattr__(self, name, _range(f"scenario.{name}", getattr(self, name), 0.0))
        if self.start_height[0] < 0.8:
            raise ConfigError("scenario.start_height must start at >= 0.8 m (the IPC's height range)")
        if not 0.0 <= self.aligned_margin_deg < 45.0:
            raise ConfigError(
                f"scenario.aligned_margin_deg must lie in [0, 45), got {self.aligned_margin_deg}"
            )


@dataclass(frozen=True, kw_only=True)
class ApproachParams:
    """Approach flights: data whose states look like a landing run's (see :mod:`.approach`).

    Parameters
    ----------
    fraction : float
        Share of every dataset flown as approach flights; the rest are exploration paths.
    start_distance, start_height, transit_speed, prior_radius
        As in :class:`ScenarioParams` (wider ranges).
    extra_transit : (low, high)
        Seconds flown on along the transit after the first detection.
    deceleration : float
        Braking at the end of the transit (m/s^2), smooth instead of a step in the reference
        (also past the prior guess, as in :class:`ScenarioParams`).
    hover_points : int
        Waypoints above the pad flown to after the transit.
    hover_offset : float
        Horizontal offset of a hover point from the pad (uniform in a disc, m).
    hover_height : (low, high)
        Camera height above the pad at a hover point (m).
    dwell : (low, high)
        Seconds spent at a hover point after settling.
    leg_timeout : float
        Seconds per leg.
    sample_every : int
        Camera frames between measurements, in approach flights and exploration paths alike.

    Examples
    --------
    >>> ApproachParams().hover_points
    2
    """

    fraction: float = 0.5
    aligned_margin_deg: float = 3.0
    start_distance: Range = (1.2, 2.2)
    start_height: Range = (1.2, 2.3)
    transit_speed: Range = (0.2, 2.0)
    prior_radius: float = 0.3
    extra_transit: Range = (0.0, 0.6)
    deceleration: float = 1.5
    hover_points: int = 2
    hover_offset: float = 0.1
    hover_height: Range = (0.6, 1.2)
    dwell: Range = (0.2, 0.8)
    leg_timeout: float = 8.0
    sample_every: int = 6

    def __post_init__(self) -> None:
        if not 0.0 <= self.fraction <= 1.0:
            raise ConfigError(f"approach.fraction must lie in [0, 1], got {self.fraction!r}")
        if not 0.0 <= self.aligned_margin_deg < 45.0:
            raise ConfigError(
                f"approach.aligned_margin_deg must lie in [0, 45), got {self.aligned_margin_deg!r}"
            )
        for name in (
            "start_distance",
            "start_height",
            "transit_speed",
            "extra_transit",
            "hover_height",
            "dwell",
        ):
            object.__setattr__(self, name, _range(f"approach.{name}", getattr(self, name), 0.0))
        _positive("approach.prior_radius", self.prior_radius, allow_zero=True)
        _positive("approach.hover_offset", self.hover_offset, allow_zero=True)
        _positive("approach.deceleration", self.deceleration)
        _positive("approach.hover_points", self.hover_points, integer=True, allow_zero=True)
        _positive("approach.leg_timeout", self.leg_timeout)
        _positive("approach.sample_every", self.sample_every, integer=True)
        object.__setattr__(self, "hover_points", int(self.hover_points))
        object.__setattr__(self, "sample_every", int(self.sample_every))
        if self.transit_speed[1] <= 0:
            raise ConfigError("approach.transit_speed must allow a positive speed")

    def scenario(self) -> ScenarioParams:
        """The scenario ranges of an approach flight (pad anywhere, any heading)."""
        return ScenarioParams(
            start_distance=self.start_distance,
            start_height=self.start_height,
            transit_speed=self.transit_speed,
            prior_radius=self.prior_radius,
            aligned_margin_deg=self.aligned_margin_deg,
            deceleration=self.deceleration,
        )


@dataclass(frozen=True, kw_only=True)
class LandingParams:
    """The landing state machine (see :mod:`.state_machine`).

    Parameters
    ----------
    buffer_size : int
        Camera buffer size of the landing runs (frames of lag).
    tracking_tolerance : float
        ``tau`` (m): a measurement is accepted only if the ellipsoid fits ``G`` shrunk by
        ``tau`` on every side, and the motors are cut only within ``tau`` (inf-norm) of the
        turn-off point (``proofs/landing_safety.md``).
    max_measurements : int
        Cap ``M`` on IPC queries per run; a run that reaches it without accepting aborts.
    measure_height, max_height : float
        A New Waypoint keeps the camera between these heights above the pad estimate (m).
    climb : float
        With no detection at a waypoint, climb this much and look again (m).
    search_timeout, leg_timeout, settle_timeout : float
        Seconds allowed for the transit to produce a detection, for a waypoint, and for
        settling within ``tau`` of the turn-off point; running out aborts the run.
    trajectory_every : int
        Keep every n-th frame of the trajectory (figures).

    Examples
    --------
    >>> LandingParams().tracking_tolerance
    0.005
    """

    buffer_size: int = 3
    tracking_tolerance: float = 0.005
    max_measurements: int = 8
    measure_height: float = 0.7
    max_height: float = 2.3
    climb: float = 0.3
    search_timeout: float = 8.0
    leg_timeout: float = 10.0
    settle_timeout: float = 6.0
    trajectory_every: int = 6

    def __post_init__(self) -> None:
        b = self.buffer_size
        if isinstance(b, bool) or not isinstance(b, int) or not 0 <= b <= MAX_BUFFER_SIZE:
            raise ConfigError(f"landing.buffer_size must be an integer in [0, {MAX_BUFFER_SIZE}], got {b!r}")
        if not 0.0 < self.tracking_tolerance < 0.025:
            raise ConfigError(
                "landing.tracking_tolerance must lie in (0, 0.025) m: G is 0.05 m tall and is shrunk "
                f"by tau on each side; got {self.tracking_tolerance!r}"
            )
        _positive("landing.max_measurements", self.max_measurements, integer=True)
        object.__setattr__(self, "max_measurements", int(self.max_measurements))
        for name in (
            "measure_height",
            "max_height",
            "climb",
            "search_timeout",
            "leg_timeout",
            "settle_timeout",
        ):
            _positive(f"landing.{name}", getattr(self, name))
        _positive("landing.trajectory_every", self.trajectory_every, integer=True)
        if self.measure_height >= self.max_height:
            raise ConfigError(
                f"landing.measure_height ({self.measure_height}) must be below landing.max_height "
                f"({self.max_height})"
            )


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
            _positive(f"ipc.{name}", getattr(self, name), integer=True)
        _positive("ipc.seed", self.seed, integer=True, allow_zero=True)
        for name in ("lr", "alpha"):
            _positive(f"ipc.{name}", getattr(self, name))
        _positive("ipc.lam", self.lam, allow_zero=True)
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
            _positive(f"sizes.{name}", getattr(self, name), integer=True)
        _positive("sizes.buffer1_runs", self.buffer1_runs, integer=True, allow_zero=True)
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
    """Everything :mod:`.reproduce` needs besides the simulator's :class:`.config.SimConfig`.

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


_SECTIONS: dict[str, type] = {
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
        tree = merge_sections(tree, data, str(src), _SECTIONS)
        if quick:
            if not isinstance(overlay, Mapping):
                raise ConfigError(f"{src}: [quick] must be a table of sections")
            tree = merge_sections(tree, overlay, f"{src} [quick]", _SECTIONS)
    if overrides:
        tree = merge_sections(tree, overrides, "override", _SECTIONS)
    parts: dict[str, Any] = {}
    for name, cls in _SECTIONS.items():
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in tree.get(name, {}).items()}
        parts[name] = cls(**values)
    return ReproduceConfig(**parts, quick=quick)
