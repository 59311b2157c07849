"""Recorded flights: fly an open-loop flight once, measure it with any camera afterwards.

Data-collection flights (exploration paths, approach flights, pilot test flights) follow
references that do not depend on what the camera sees, so their trajectories are the same
for every camera: every buffer size, every timing model, every error source switched on or
off. A :class:`FlightRecording` keeps such a flight (its state history, pad, sensor seed and
the instants at which the collector measures); :func:`measure_recording` replays a camera
stage over it. A dataset for several camera variants then costs one flight and one
measurement per variant, instead of one flight per variant.

Measuring a recording gives exactly what measuring during the flight gives: the camera
stage reads only the state history up to each instant and its own seeded draws.

Examples
--------
>>> from case_studies.quad_landing import Flight, hover_state
>>> from case_studies.quad_landing.sim.camera import build_camera_stage
>>> flight = Flight(buffer_size=1, seed=0)
>>> flight.reset(hover_state((0.0, 0.0, 1.3)))
>>> times = [flight.time for _ in range(12) if flight.step() is None]
>>> rec = recording_of(flight, index=0, sample_times=times[5::6])
>>> part = measure_recording(rec, build_camera_stage(flight.config, 3))
>>> part.rows.shape, int(part.outcomes.sum())
((2, 36), 0)
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from case_studies.quad_landing.data.columns import FLOAT_COLUMNS, measurement_row
from case_studies.quad_landing.sim.camera import CameraStage, Measurement
from case_studies.quad_landing.sim.flight import Flight
from case_studies.quad_landing.sim.history import StateHistory
from case_studies.quad_landing.sim.marker import Pad

__all__ = ["FlightRecording", "PathRecord", "recording_of", "measure_recording"]


@dataclass(frozen=True, eq=False)
class PathRecord:
    """What measuring one flight produced (:func:`measure_recording`).

    Attributes
    ----------
    index : int
        Path index (seeds the path and its sensor noise).
    rows : ndarray, shape (m, 36)
        One row per detection, the :data:`.columns.FLOAT_COLUMNS`.
    times : ndarray, shape (m,)
        Time of each detection's paired state (s).
    outcomes : ndarray of int8
        One code per measurement, in order: 0 detected, 1 missed with the marker (partly)
        outside the lagged image, 2 missed although it was inside.
    flight_time : float
        Time flown, warm-up included (s).
    ages : ndarray, shape (m,)
        Each detection's age: how much older its image is than its paired state (s).
    """

    index: int
    rows: np.ndarray
    times: np.ndarray
    outcomes: np.ndarray
    flight_time: float
    ages: np.ndarray

    def head(self, samples: int) -> PathRecord:
        """The first ``samples`` rows, with the measurements up to the last of them."""
        if samples >= len(self.rows):
            return self
        last = int(np.flatnonzero(self.outcomes == 0)[samples - 1]) if samples else -1
        return PathRecord(self.index, self.rows[:samples], self.times[:samples],
                          self.outcomes[: last + 1], self.flight_time, self.ages[:samples])  # fmt: skip


@dataclass(frozen=True, eq=False)
class FlightRecording:
    """One flight, flown once (see the module docstring).

    Attributes
    ----------
    index : int
        The flight's index in its collection (path, approach flight or pilot flight).
    history : StateHistory
        The state at every simulated frame from ``t = 0``.
    pad : Pad
        Where the pad lay.
    sensor_seed : int
        The flight's sensor seed (noise, camera timing draws).
    sample_times : ndarray
        The instants at which the collector measures (s).
    flight_time : float
        Time flown (s).
    """

    index: int
    history: StateHistory
    pad: Pad
    sensor_seed: int
    sample_times: NDArray[np.float64]
    flight_time: float


def recording_of(flight: Flight, *, index: int, sample_times: Sequence[float]) -> FlightRecording:
    """The flight just flown by ``flight``, with the instants to measure it at."""
    return FlightRecording(
        index=int(index),
        history=flight.history.copy(),
        pad=flight.pad,
        sensor_seed=flight.sensor_seed,
        sample_times=np.asarray(sample_times, dtype=np.float64),
        flight_time=flight.time,
    )


def measure_recording(
    recording: FlightRecording,
    stage: CameraStage,
    *,
    limit: int | None = None,
    keep: Callable[[Measurement], bool] | None = None,
) -> PathRecord:
    """Measure ``recording`` with ``stage`` at its sample instants.

    Parameters
    ----------
    recording : FlightRecording
        The flight.
    stage : CameraStage
        The camera to measure with (:func:`~case_studies.quad_landing.sim.camera.build_camera_stage`).
    limit : int, optional
        Stop after this many detections.
    keep : callable, optional
        Measurements for which it returns False are skipped (neither rows nor misses).

    Returns
    -------
    PathRecord
        One row per detection, with its time and age, and the outcome of every measurement
        (0 detected, 1 marker outside the image, 2 missed in view).
    """
    stage.begin(recording.history, recording.pad, recording.sensor_seed)
    rows: list[NDArray[np.float64]] = []
    times: list[float] = []
    ages: list[float] = []
    outcomes: list[int] = []
    for t in recording.sample_times:
        m = stage.measure(float(t))
        if keep is not None and not keep(m):
            continue
        if m.yhat_c is None:
            outcomes.append(2 if m.pad_in_view else 1)
            continue
        outcomes.append(0)
        rows.append(measurement_row(m))
        times.append(m.time)
        ages.append(m.age)
        if limit is not None and len(rows) >= limit:
            break
    return PathRecord(
        index=recording.index,
        rows=np.array(rows).reshape(-1, len(FLOAT_COLUMNS)),
        times=np.array(times),
        outcomes=np.array(outcomes, dtype=np.int8),
        flight_time=recording.flight_time,
        ages=np.array(ages),
    )
