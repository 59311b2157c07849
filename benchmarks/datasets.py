"""Benchmark datasets with fixed seeds: the bundled synthetic data and the quad-landing data.

Both come as three independent draws -- train, calibration, test -- so that every
method is fitted on the same training split, calibrated on the same calibration split
and measured on the same test split.

* ``synthetic``: :func:`ipcverify.synthetic.make_lagged_perception` with seeds 1000, 1001, 1002.
* ``quad_landing``: :func:`case_studies.quad_landing.data.collect` at buffer size 1 with seeds
  1000, 1001, 1002 (different exploration paths and sensor noise per split). The quad
  data takes about 12 s per 5000 samples to fly, so it is cached as Parquet under
  ``benchmarks/.cache/`` (gitignored), keyed by size and seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ipcverify.data import PerceptionDataset, load_dataset
from ipcverify.errors import InvalidInputError
from ipcverify.files import atomic_write
from ipcverify.synthetic import make_lagged_perception

__all__ = ["CACHE", "DATASETS", "SPLIT_SEEDS", "Splits", "load_splits", "quad_split", "synthetic_split"]

#: Cache folder for generated quad-landing data (gitignored).
CACHE = Path(__file__).with_name(".cache")
#: Dataset names, in report order.
DATASETS: tuple[str, ...] = ("synthetic", "quad_landing")
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

    def __post_init__(self) -> None:
        dims = {(d.x_dim, d.y_dim) for d in (self.train, self.calibration, self.test)}
        if len(dims) != 1:
            raise InvalidInputError(f"{self.name}: the splits disagree in dimensions {sorted(dims)}")


def synthetic_split(n: int, seed: int) -> PerceptionDataset:
    """One draw of the bundled synthetic lagged-perception data."""
    return make_lagged_perception(n, seed=seed)


def quad_split(n: int, seed: int, cache: Path = CACHE) -> PerceptionDataset:
    """One draw of quad-landing data (buffer size 1), flown once and then read from the cache."""
    path = cache / f"quad_k1_n{n}_seed{seed}.parquet"
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


def load_splits(name: str, n_train: int, n_calibration: int, n_test: int, cache: Path = CACHE) -> Splits:
    """The three draws of dataset ``name`` (``"synthetic"`` or ``"quad_landing"``)."""
    sizes = {"train": n_train, "calibration": n_calibration, "test": n_test}
    if name == "synthetic":
        parts = {k: synthetic_split(sizes[k], SPLIT_SEEDS[k]) for k in sizes}
    elif name == "quad_landing":
        parts = {k: quad_split(sizes[k], SPLIT_SEEDS[k], cache) for k in sizes}
    else:
        raise InvalidInputError(f"unknown dataset {name!r}; choose one of {', '.join(DATASETS)}")
    return Splits(name, parts["train"], parts["calibration"], parts["test"])
