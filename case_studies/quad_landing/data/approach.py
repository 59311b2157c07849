"""Approach flights: data whose states look like those of a landing run.

The exploration paths of :mod:`.paths` never stop (0.08 % of their samples are slower than
0.1 m/s), but a landing run measures at two kinds of moments: in transit, when the pad
first comes into view, and hovering at a waypoint above the pad. An IPC learned only on
the paths has never seen a hovering camera; it extrapolates there, and its calibration
says nothing about those queries. An approach flight flies what a landing run flies:

1. a transit at constant speed and height toward a prior guess of the pad, from a random
   start (:func:`.scenario.draw_scenario`, wider ranges, pad edges kept off the image
   axes), on past the moment the whole pad comes into view (a geometric test, so that the
   flight does not depend on the camera lag) for a random extra time, then a smooth stop
   (``deceleration``);
2. ``hover_points`` legs to random points above the pad (camera 0.6–1.2 m up, up to
   0.1 m off-centre), each flown until settled and then held for a random dwell.

A measurement is taken every ``sample_every`` camera frames throughout (default 6: 10 Hz),
as in :func:`.collect.fly_path`, and the rows have the same columns (:data:`.columns.DATASET_COLUMNS`).
Flight ``i`` of a collection seeded ``s`` depends only on ``(s, i)``: the same flight,
sampling instants and noise for every buffer size.

Examples
--------
>>> from case_studies.quad_landing import Flight
>>> rec = fly_approach(Flight(buffer_size=1), 0, seed=0, params=ApproachParams.defaults(hover_points=1))
>>> rec.rows.shape[1], bool(len(rec.rows) > 20)
(36, True)
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, fields

import numpy as np
import pandas as pd

from case_studies.quad_landing.data.collect import CollectStats, dataset_from_records
from case_studies.quad_landing.data.recording import (
    FlightRecording,
    PathRecord,
    measure_recording,
    recording_of,
)
from case_studies.quad_landing.landing.scenario import (
    ScenarioParams,
    camera_offset_z,
    draw_scenario,
    scenario_rng,
    stopping_reference,
)
from case_studies.quad_landing.settings import (
    REPRODUCE_PATH,
    ConfigError,
    Range,
    TomlSection,
    check_positive,
    check_range,
)
from case_studies.quad_landing.sim.config import SimConfig, load_config
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.legs import fly_leg
from ipcverify.errors import InvalidInputError

__all__ = ["ApproachParams", "APPROACH_STREAM", "fly_approach", "record_approach", "collect_approach"]


@dataclass(frozen=True, kw_only=True)
class ApproachParams(TomlSection, file=REPRODUCE_PATH, section="approach"):
    """Approach flights: data whose states look like a landing run's (see :mod:`.approach`).

    Parameters
    ----------
    fraction : float
        Share of every dataset flown as approach flights; the rest are exploration paths.
    pad_region, aligned_margin_deg, start_distance, start_height, transit_speed, prior_radius
        As in :class:`~case_studies.quad_landing.landing.scenario.ScenarioParams` (wider ranges).
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
    >>> ApproachParams.defaults().hover_points  # [approach] of reproduce.toml
    2
    """

    fraction: float
    pad_region: float
    aligned_margin_deg: float
    start_distance: Range
    start_height: Range
    transit_speed: Range
    prior_radius: float
    extra_transit: Range
    deceleration: float
    hover_points: int
    hover_offset: float
    hover_height: Range
    dwell: Range
    leg_timeout: float
    sample_every: int

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
            object.__setattr__(self, name, check_range(f"approach.{name}", getattr(self, name), 0.0))
        check_positive("approach.prior_radius", self.prior_radius, allow_zero=True)
        check_positive("approach.hover_offset", self.hover_offset, allow_zero=True)
        check_positive("approach.deceleration", self.deceleration)
        check_positive("approach.hover_points", self.hover_points, integer=True, allow_zero=True)
        check_positive("approach.leg_timeout", self.leg_timeout)
        check_positive("approach.sample_every", self.sample_every, integer=True)
        object.__setattr__(self, "hover_points", int(self.hover_points))
        object.__setattr__(self, "sample_every", int(self.sample_every))
        if self.transit_speed[1] <= 0:
            raise ConfigError("approach.transit_speed must allow a positive speed")

    def scenario(self) -> ScenarioParams:
        """The scenario ranges of an approach flight (pad anywhere, any heading).

        Every field of :class:`ScenarioParams` is taken from the field of the same name here.
        """
        return ScenarioParams(**{f.name: getattr(self, f.name) for f in fields(ScenarioParams)})


#: Random stream of approach flights (scenario draw; ``+ 1`` for the hover points).
APPROACH_STREAM = 71


class _Sampler:
    """Notes the flight time every ``every`` frames (the instants the collector measures at)."""

    def __init__(self, flight: Flight, every: int) -> None:
        self.flight, self.every, self.frame = flight, every, 0
        self.times: list[float] = []

    def __call__(self) -> None:
        self.frame += 1
        if self.frame % self.every == 0:
            self.times.append(self.flight.time)


def record_approach(flight: Flight, index: int, *, seed: int, params: ApproachParams) -> FlightRecording:
    """Fly approach flight ``index`` and keep it with its sampling instants (every ``sample_every`` frames).

    The flight does not depend on the camera: the transit stops a random time after the
    pad is geometrically in view. Measure it with :func:`.recording.measure_recording`.
    """
    cfg = flight.config
    sc = draw_scenario(index, seed=seed, params=params.scenario(), config=cfg, stream=APPROACH_STREAM)
    rng = scenario_rng(seed, index, APPROACH_STREAM + 1)
    flight.reset(sc.start, sc.pad, seed=sc.noise_seed)
    rec = _Sampler(flight, params.sample_every)
    extra = float(rng.uniform(*params.extra_transit))
    stop_at: float | None = None
    while flight.time < sc.transit_time + params.leg_timeout:
        flight.step(sc.reference)
        rec()
        if stop_at is None and flight.pad_in_view():  # geometric, so the path is the same for every camera
            stop_at = flight.time + extra
        if stop_at is not None and flight.time >= stop_at - 1e-9:
            break
    braking = stopping_reference(sc.reference(flight.time), flight.time, params.deceleration)
    t_end = flight.time + np.pi * float(np.linalg.norm(sc.start[3:6])) / (2 * params.deceleration) + 0.5
    while flight.time < t_end:
        flight.step(braking)
        rec()
    pad = sc.pad.position
    for _ in range(params.hover_points):
        angle = rng.uniform(0, 2 * np.pi)
        radius = params.hover_offset * np.sqrt(rng.random())
        height = float(rng.uniform(*params.hover_height))
        target = pad + np.array(
            [radius * np.cos(angle), radius * np.sin(angle), height + camera_offset_z(cfg)]
        )
        fly_leg(
            flight,
            target,
            yaw=sc.yaw,
            timeout=params.leg_timeout,
            dwell=float(rng.uniform(*params.dwell)),
            on_frame=rec,
        )
    return recording_of(flight, index=index, sample_times=rec.times)


def fly_approach(flight: Flight, index: int, *, seed: int, params: ApproachParams) -> PathRecord:
    """Fly approach flight ``index`` and record a measurement every ``params.sample_every`` frames.

    Parameters
    ----------
    flight : Flight
        The simulator (its buffer size is used; its pad is replaced by the flight's).
    index, seed : int
        Which flight; it depends on nothing else.
    params : ApproachParams
        Ranges of the transit and the hover points.

    Returns
    -------
    PathRecord
        Rows in the :data:`.columns.FLOAT_COLUMNS`, their times, the
        outcome code of every measurement (0 detected, 1 marker outside the lagged image,
        2 missed in view) and the time flown.
    """
    return measure_recording(record_approach(flight, index, seed=seed, params=params), flight.camera_stage)


def collect_approach(
    n: int,
    *,
    buffer_size: int,
    seed: int,
    params: ApproachParams,
    config: SimConfig | None = None,
    progress: Callable[[int], None] | None = None,
) -> tuple[pd.DataFrame, CollectStats]:
    """Fly approach flights in index order until ``n`` measurements with a detection are recorded.

    Parameters
    ----------
    n : int
        Samples to collect.
    buffer_size : int
        Camera buffer size ``k``.
    seed : int
        Seeds the flights and their sensor noise.
    params : ApproachParams
        The flights' ranges.
    config : SimConfig, optional
        The simulator (defaults if None).
    progress : callable, optional
        Called with the number of new samples as they are added.

    Returns
    -------
    data : pandas.DataFrame
        ``n`` rows with the columns :data:`.columns.DATASET_COLUMNS` (``path`` is the flight index).
    stats : CollectStats
        Detection counts and timing, as for :func:`.collect.collect`.

    Examples
    --------
    >>> params = ApproachParams.defaults(hover_points=1)
    >>> data, stats = collect_approach(30, buffer_size=2, seed=0, params=params)
    >>> len(data), stats.buffer_size
    (30, 2)
    """
    if isinstance(n, bool) or int(n) != n or n < 1:
        raise InvalidInputError(f"n must be a positive integer, got {n!r}")
    if isinstance(seed, bool) or int(seed) != seed or seed < 0:
        raise InvalidInputError(f"seed must be a non-negative integer, got {seed!r}")
    cfg = load_config() if config is None else config
    flight = Flight(cfg, buffer_size=buffer_size)
    t0 = time.perf_counter()
    parts: list[PathRecord] = []
    done, index = 0, 0
    while done < n:
        rec = fly_approach(flight, index, seed=int(seed), params=params)
        take = min(len(rec.rows), n - done)
        parts.append(rec.head(take))
        done += take
        index += 1
        if progress is not None and take:
            progress(take)
        if index > 50 + 10 * n:
            raise InvalidInputError(
                "approach flights produce no detections; check the camera and pad settings"
            )
    return dataset_from_records(parts, buffer_size=buffer_size, seed=int(seed), started=t0)
