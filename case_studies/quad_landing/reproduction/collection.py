"""Collecting every dataset of a reproduction: grouped by flights, in parallel, cached.

A reproduction needs many datasets: training, calibration and held-out test sets and the
pilot test sets of Table I, for the main camera and for every camera variant of the
ablation. Datasets with the same kind and seed are flown on the same flights (paths,
approach flights, pilot flights), which do not depend on the camera; a group is therefore
flown once per task and measured with every camera in it
(:func:`case_studies.quad_landing.data.datasets.cached_many`). The specs of a group are
split into as many tasks as there are workers, balancing the measurements and the flying
(a task flies as long as its largest dataset needs). Each dataset is cached in
``OUT/data/NAME.parquet`` with its settings; cached ones are not collected again.

Examples
--------
>>> plan = DatasetPlan()
>>> from case_studies.quad_landing.sim.config import load_config
>>> plan.add("mixed", 0, DatasetSpec("train_k1", load_config(), 1, 100))
>>> plan.add("mixed", 0, DatasetSpec("abl_a_train_k1", load_config(), 1, 40))
>>> [[s.name for s in chunk] for chunk in plan.tasks(2)[0][2]]
[['train_k1'], ['abl_a_train_k1']]
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import joblib
import pandas as pd

from case_studies.quad_landing.data.approach import ApproachParams
from case_studies.quad_landing.data.datasets import DatasetSpec, as_dataset, cached_many
from case_studies.quad_landing.data.pilot import PilotParams
from case_studies.quad_landing.sim.config import SimConfig
from ipcverify.data import PerceptionDataset
from ipcverify.errors import InvalidInputError

__all__ = ["KINDS", "DatasetPlan", "collect_plan", "spec_path"]

#: Kinds of dataset: mixed (paths + approach flights) or pilot test flights.
KINDS = ("mixed", "pilot")


@dataclass
class DatasetPlan:
    """Datasets to collect, grouped by ``(kind, seed)`` (see the module docstring)."""

    groups: dict[tuple[str, int], list[DatasetSpec]] = field(default_factory=dict)

    def add(self, kind: str, seed: int, spec: DatasetSpec) -> None:
        """Add a dataset of ``kind`` (``"mixed"`` or ``"pilot"``) flown with flights of ``seed``."""
        if kind not in KINDS:
            raise InvalidInputError(f"dataset kind must be one of {KINDS}, got {kind!r}")
        names = {s.name for specs in self.groups.values() for s in specs}
        if spec.name in names:
            raise InvalidInputError(f"two datasets are called {spec.name!r}")
        self.groups.setdefault((kind, int(seed)), []).append(spec)

    @property
    def specs(self) -> list[DatasetSpec]:
        """Every dataset of the plan."""
        return [s for specs in self.groups.values() for s in specs]

    def tasks(self, workers: int) -> list[tuple[str, int, list[list[DatasetSpec]]]]:
        """Each group's specs in at most ``workers`` chunks of balanced cost.

        A chunk's cost is its measurements plus its flying (its largest dataset); specs are
        placed largest first into the cheapest chunk.
        """
        out = []
        for (kind, seed), specs in self.groups.items():
            chunks: list[list[DatasetSpec]] = [[] for _ in range(max(1, min(workers, len(specs))))]
            for spec in sorted(specs, key=lambda s: -s.n):
                cost = [sum(s.n for s in c) + max((s.n for s in c), default=0) for c in chunks]
                chunks[cost.index(min(cost))].append(spec)
            out.append((kind, seed, [c for c in chunks if c]))
        return out


def _collect_chunk(
    kind: str,
    seed: int,
    specs: list[DatasetSpec],
    params: ApproachParams | PilotParams,
    config: SimConfig,
    margin: float,
) -> int:
    """One task: collect (or find cached) a chunk's datasets; OpenCV single-threaded per process."""
    import cv2

    cv2.setNumThreads(1)
    cached_many(specs, seed=seed, params=params, config=config, margin=margin)
    return sum(s.n for s in specs)


def collect_plan(
    plan: DatasetPlan,
    *,
    approach: ApproachParams,
    pilot: PilotParams,
    config: SimConfig,
    jobs: int,
    progress: Callable[[int], None] | None = None,
) -> tuple[dict[str, PerceptionDataset], dict[str, pd.DataFrame]]:
    """Collect the plan's datasets not yet cached (``jobs`` processes), then load them all.

    Every spec needs a cache ``path``. Pilot sets leave out headings within the approach
    flights' ``aligned_margin_deg`` of the image axes, like the training data.

    Returns
    -------
    datasets : dict of str to PerceptionDataset
        By name.
    frames : dict of str to pandas.DataFrame
        The same data with every column (ages, world-frame states, sources).
    """
    if any(s.path is None for s in plan.specs):
        raise InvalidInputError("every dataset of a reproduction needs a cache path")
    margin = approach.aligned_margin_deg
    params: dict[str, ApproachParams | PilotParams] = {"mixed": approach, "pilot": pilot}
    tasks = [(kind, seed, chunk) for kind, seed, chunks in plan.tasks(max(1, jobs)) for chunk in chunks]
    tasks.sort(key=lambda t: -(sum(s.n for s in t[2]) + max(s.n for s in t[2])))
    calls = (
        joblib.delayed(_collect_chunk)(kind, seed, chunk, params[kind], config, margin)
        for kind, seed, chunk in tasks
    )
    if jobs <= 1:
        for kind, seed, chunk in tasks:
            done = _collect_chunk(kind, seed, chunk, params[kind], config, margin)
            if progress is not None:
                progress(done)
    else:
        for done in joblib.Parallel(n_jobs=min(jobs, len(tasks)) or 1, return_as="generator_unordered")(
            calls
        ):
            if progress is not None:
                progress(done)
    frames: dict[str, pd.DataFrame] = {}
    for (kind, seed), specs in plan.groups.items():
        loaded = cached_many(specs, seed=seed, params=params[kind], config=config, margin=margin)
        frames.update({name: data for name, (data, _) in loaded.items()})
    datasets = {name: as_dataset(df, source=f"{name}.parquet") for name, df in frames.items()}
    return datasets, frames


def spec_path(out_dir: Path, name: str) -> Path:
    """The cache file of dataset ``name`` in a reproduction's output directory."""
    return out_dir / "data" / f"{name}.parquet"
