"""Benchmark datasets with fixed seeds: known-oracle synthetic data and the quad-landing data.

Each comes as three independent draws -- train, calibration, test -- so that every
method is fitted on the same training split, calibrated on the same calibration split
and measured on the same test split.

* ``synthetic``: heteroscedastic lagged perception with a known Gaussian conditional law
  (:func:`benchmarks.oracle_data.make_hetlag`), seeds 1000, 1001, 1002; its oracle comes
  with it. (Until the tight recipe this was the demo's
  :func:`ipcverify.data.make_lagged_perception`, whose target height is exactly minus
  an input, ``y_z = -p_z``: an axis with no noise at all, on which a method that learns the
  linear relation gets a set of near-zero volume, so volume ratios measured z-axis
  regression precision more than tightness.)
* ``synthetic_t4``: the same law with heavy-tailed (multivariate t, 4 degrees of freedom)
  conditional errors, seeds 1000-1002.
* ``fresh``: :func:`benchmarks.oracle_data.make_fresh_lagged`, the held-out generator that no
  tuning of the default recipe has seen, seeds 1000-1002.
* ``quad_landing``: :func:`case_studies.quad_landing.data.collect` at buffer size 1 with seeds
  1000, 1001, 1002 (different exploration paths and sensor noise per split). The quad
  data takes about 12 s per 5000 samples to fly, so it is cached as Parquet under
  ``benchmarks/.cache/`` (gitignored), keyed by size, seed and the simulator's settings
  (:func:`simulator_fingerprint`).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.oracle_data import Oracle, make_fresh_lagged, make_hetlag
from ipcverify.data import PerceptionDataset, load_dataset
from ipcverify.data._files import atomic_write
from ipcverify.errors import InvalidInputError

__all__ = [
    "CACHE",
    "DATASETS",
    "ORACLE_DATASETS",
    "SPLIT_SEEDS",
    "Splits",
    "load_splits",
    "quad_flights",
    "quad_split",
    "simulator_fingerprint",
]

#: Cache folder for generated quad-landing data (gitignored).
CACHE = Path(__file__).with_name(".cache")
#: Dataset names, in report order.
DATASETS: tuple[str, ...] = ("synthetic", "synthetic_t4", "fresh", "quad_landing")
#: The known-oracle generators: name -> (n, seed) -> (data, oracle).
ORACLE_DATASETS: dict[str, Callable[[int, int], tuple[PerceptionDataset, Oracle]]] = {
    "synthetic": lambda n, seed: make_hetlag(n, seed, "gauss"),
    "synthetic_t4": lambda n, seed: make_hetlag(n, seed, "t4"),
    "fresh": make_fresh_lagged,
}
#: Seeds of the train, calibration and test draws.
SPLIT_SEEDS: dict[str, int] = {"train": 1000, "calibration": 1001, "test": 1002}


@dataclass(frozen=True)
class Splits:
    """Independent train / calibration / test draws of one dataset.

    Examples
    --------
    >>> s = load_splits("synthetic", n_train=50, n_calibration=60, n_test=70)
    >>> len(s.train), len(s.calibration), len(s.test)
    (50, 60, 70)
    """

    name: str
    train: PerceptionDataset
    calibration: PerceptionDataset
    test: PerceptionDataset
    #: the true conditional law of the calibration and test samples (known-oracle data only)
    calibration_oracle: Oracle | None = None
    test_oracle: Oracle | None = None

    def __post_init__(self) -> None:
        dims = {(d.x_dim, d.y_dim) for d in (self.train, self.calibration, self.test)}
        if len(dims) != 1:
            raise InvalidInputError(f"{self.name}: the splits disagree in dimensions {sorted(dims)}")


def simulator_fingerprint() -> str:
    """Eight hex digits of the simulator's settings (``defaults.toml``): part of the cache key,
    so that data flown with other settings (another detector, another camera) is never reused.

    Examples
    --------
    >>> len(simulator_fingerprint()), simulator_fingerprint() == simulator_fingerprint()
    (8, True)
    """
    from case_studies.quad_landing import load_config

    text = json.dumps(load_config().as_dict(), sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:8]


def quad_split(n: int, seed: int, cache: Path = CACHE) -> PerceptionDataset:
    """One draw of quad-landing data (buffer size 1), flown once and then read from the cache."""
    path = cache / f"quad_k1_n{n}_seed{seed}_{simulator_fingerprint()}.parquet"
    if not path.is_file():
        from case_studies.quad_landing import collect

        frame, _ = collect(n, buffer_size=1, seed=seed)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda f: frame.to_parquet(f, index=False))
    ds = load_dataset(path)
    cols = [c for c in ds.x_columns if c.startswith("x_")]
    if len(cols) != 12:
        raise InvalidInputError(f"{path}: expected 12 x_* columns, found {len(cols)}; delete the cache file")
    return ds


#: Flights of the in-distribution quad workload (``quad_flights``): calibration, then held out.
FLIGHTS = (120, 80)
#: Camera frames between two measurements of that workload (the splits above take every 2nd frame).
SPARSE_EVERY = 20


def quad_flights(
    calibration: int = FLIGHTS[0], held_out: int = FLIGHTS[1], seed: int = 1003, cache: Path = CACHE
) -> tuple[PerceptionDataset, PerceptionDataset]:
    """Many short records of exploration flights: ``calibration`` flights, then ``held_out`` more.

    The quad splits above are 12 flights each, sampled every 2nd frame, so a row-level domain
    test fitted on one split flags most rows of another split's flights (their rows lie close to
    each other and far from other flights). Here every flight is sampled every
    :data:`SPARSE_EVERY` frames (about 43 rows per 15 s flight), so ``calibration`` flights make
    about 5,000 rows and enough flights (``>= 1/alpha - 1``) to fit the domain test by flight;
    the held-out flights are new flights drawn exactly like them (same generator and seed,
    the next path indices). Both keep the flight index as the column ``path``. Flown once
    (about a minute), then read from the cache.
    """
    from case_studies.quad_landing import load_config

    rows = 46 * (calibration + held_out)  # a flight records at most 45 rows at this spacing
    path = cache / f"quad_k1_every{SPARSE_EVERY}_n{rows}_seed{seed}_{simulator_fingerprint()}.parquet"
    if not path.is_file():
        from case_studies.quad_landing import collect

        config = load_config().replace(collect={"sample_every": SPARSE_EVERY})
        frame, _ = collect(rows, buffer_size=1, seed=seed, config=config)
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, lambda f: frame.to_parquet(f, index=False))
    ds = load_dataset(path)
    flight = ds.column("path")
    if flight.max() + 1 < calibration + held_out:
        raise InvalidInputError(f"{path}: fewer than {calibration + held_out} flights; delete the cache file")
    cal = ds.subset(np.flatnonzero(flight < calibration))
    test = ds.subset(np.flatnonzero((flight >= calibration) & (flight < calibration + held_out)))
    return cal, test


def load_splits(name: str, n_train: int, n_calibration: int, n_test: int, cache: Path = CACHE) -> Splits:
    """The three draws of dataset ``name`` (one of :data:`DATASETS`), with the oracles if known."""
    sizes = {"train": n_train, "calibration": n_calibration, "test": n_test}
    if name in ORACLE_DATASETS:
        draws = {k: ORACLE_DATASETS[name](sizes[k], SPLIT_SEEDS[k]) for k in sizes}
        return Splits(
            name,
            draws["train"][0],
            draws["calibration"][0],
            draws["test"][0],
            calibration_oracle=draws["calibration"][1],
            test_oracle=draws["test"][1],
        )
    if name == "quad_landing":
        parts = {k: quad_split(sizes[k], SPLIT_SEEDS[k], cache) for k in sizes}
        return Splits(name, parts["train"], parts["calibration"], parts["test"])
    raise InvalidInputError(f"unknown dataset {name!r}; choose one of {', '.join(DATASETS)}")
